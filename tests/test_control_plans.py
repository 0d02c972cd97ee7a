"""The planner's plans as data, and the cache that keeps them between episodes."""

import dataclasses

import numpy as np
import pytest

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner.plans import PlanCache, goal_digest
from pianist.eval.session import make_env

SONG = "c-major-scale-right"


def _reset(planner: IKPlanner, song: str = SONG) -> IKPlanner:
    env = make_env(song, planner, physics="fast")
    env.reset(seed=0)
    planner.reset(env, seed=0)
    return planner


def _counting(monkeypatch) -> list[int]:
    calls: list[int] = []
    plan = IKPlanner._plan
    monkeypatch.setattr(IKPlanner, "_plan", lambda self, *a: calls.append(1) or plan(self, *a))
    return calls


def test_a_new_environment_of_the_same_song_reuses_the_plan(monkeypatch):
    cache = PlanCache()
    calls = _counting(monkeypatch)
    first = _reset(IKPlanner(cache=cache))
    made = len(calls)
    assert made >= 2 and len(cache) == 1  # every candidate planned once, then rehearsed
    again = _reset(IKPlanner(cache=cache))  # another environment: another goal object
    assert len(calls) == made and len(cache) == 1
    assert again.goal is not first.goal and goal_digest(again.goal) == goal_digest(first.goal)
    assert again.rehearsed == first.rehearsed and again.plan_kind == first.plan_kind
    for a, b in zip(first.plan.hands, again.plan.hands, strict=True):
        np.testing.assert_array_equal(a.tx_plan, b.tx_plan)
    # Another configuration, another song: planned anew, each kept apart.
    _reset(IKPlanner(PlannerConfig().with_fields(lazy_m=0.01), cache=cache))
    _reset(IKPlanner(cache=cache), "twinkle-twinkle")
    assert len(calls) > made and len(cache) == 3


def test_the_cache_keeps_the_latest_plans():
    cache = PlanCache(kept=2)
    for song in ("twinkle-twinkle", SONG, "c-major-chords"):
        _reset(IKPlanner(PlannerConfig().with_fields(hand_planning="frame"), cache=cache), song)
    assert len(cache) == 2
    planner = _reset(
        IKPlanner(PlannerConfig().with_fields(hand_planning="frame"), cache=cache), SONG
    )
    assert cache.get(planner.goal, planner.handle.scene.options, planner.config) is not None
    with pytest.raises(ValueError, match="at least 1"):
        PlanCache(kept=0)


def test_plans_made_twice_are_the_same_plan():
    a = _reset(IKPlanner(PlannerConfig().with_fields(hand_planning="piece"), cache=PlanCache()))
    b = _reset(IKPlanner(PlannerConfig().with_fields(hand_planning="piece"), cache=PlanCache()))
    plan_a, plan_b = a.plan, b.plan
    assert plan_a.hands[0].tx_path is not plan_b.hands[0].tx_path  # made anew each time
    assert plan_a.same_as(plan_b)
    other_fingers = plan_b.fingers.copy()
    other_fingers[0, 0] += 1  # one finger changed
    assert not plan_a.same_as(dataclasses.replace(plan_b, fingers=other_fingers))
    moved = dataclasses.replace(plan_b.hands[0], tx_plan=plan_b.hands[0].tx_plan + 0.001)
    assert not plan_a.same_as(dataclasses.replace(plan_b, hands=(moved, *plan_b.hands[1:])))
