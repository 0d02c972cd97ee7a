"""Choosing the planner's plan by rehearsal, and replaying the rehearsal as the performance."""

import numpy as np
import pytest

from pianist.control.base import BaseController
from pianist.control.lookahead import LookAhead
from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner.config import PLAN_CANDIDATES
from pianist.control.planner.rehearsal import rehearse
from pianist.env.handle import control_handle
from pianist.eval import run_episode
from pianist.eval.session import make_env

SONG = "c-major-scale-right"  # the frame-by-frame plan plays it best, the step-F1 plan worst


class _Nudged(BaseController):
    """A controller's actions, one joint nudged at one step (the performance leaves the
    rehearsed path there)."""

    def __init__(self, inner, step: int) -> None:
        self.inner, self.step, self.actions = inner, step, []

    def reset(self, env, seed=None):
        self.env = env
        self.inner.reset(env, seed=seed)

    def act(self, observation):
        action = np.array(self.inner.act(observation))
        if len(self.actions) == self.step:
            action[-2] = np.clip(action[-2] + 0.5, -1.0, 1.0)
        self.actions.append(action)
        return action


def _episode(controller, song=SONG):
    env = make_env(song, IKPlanner(), physics="fast")
    return run_episode(env, controller, seed=0)


def test_the_plan_that_rehearses_best_is_played_and_scores_as_rehearsed():
    planner = IKPlanner()
    f1 = _episode(planner).metrics()["f1"]
    rehearsed = planner.rehearsed
    assert set(rehearsed) <= set(PlannerConfig().best_candidates) and len(rehearsed) >= 2
    winner = max(rehearsed, key=rehearsed.get)
    # Deterministic physics: the performance scores exactly what its rehearsal scored.
    assert f1 == pytest.approx(rehearsed[winner], abs=1e-12)
    assert planner.plan_kind == PLAN_CANDIDATES[winner]
    assert winner == "frame" and rehearsed["piece-f1"] < f1 - 0.05


def test_choosing_by_playable_key_frames_needs_no_rehearsal():
    planner = IKPlanner(PlannerConfig(choose_plan="playable"))
    _episode(planner)
    assert planner.rehearsed == {}


@pytest.mark.parametrize("nudge_at", [None, 30])
def test_the_replayed_performance_is_the_live_one_on_and_off_the_rehearsed_path(nudge_at):
    # The planner with its rehearsal replayed, and the same planner acting live every step
    # (the rehearsal dropped after reset): the same actions, also after a nudge takes the
    # performance off the rehearsed path (the planner's memory is kept as acting leaves it).
    replayed = _Nudged(IKPlanner(), -1 if nudge_at is None else nudge_at)
    _episode(replayed)

    class Live(IKPlanner):
        def reset(self, env, seed=None):
            super().reset(env, seed)
            self._replay = None

    live = _Nudged(Live(), -1 if nudge_at is None else nudge_at)
    _episode(live)
    np.testing.assert_array_equal(np.array(replayed.actions), np.array(live.actions))


def test_a_rehearsal_that_cannot_win_is_given_up_with_a_bound():
    planner = IKPlanner(PlannerConfig(hand_planning="piece"))
    env = make_env(SONG, planner, physics="fast")
    env.reset(seed=0)
    planner.reset(env, seed=0)
    start = planner.memory()
    look = LookAhead(control_handle(env))
    state = look.snapshot()
    look.start(planner, state, start, record=True)
    full, replay = rehearse(planner, look)
    assert replay is not None and len(replay.actions) == env.unwrapped.goal.num_frames
    assert replay.tape.start is state and len(replay.tape) == len(replay.actions)
    look.start(planner, state, start, record=True)
    bound, none = rehearse(planner, look, give_up_at=1.0)
    assert none is None and full <= bound < 1.0
    look.start(planner, state, start)
    with pytest.raises(ValueError, match="record=True"):
        rehearse(planner, look)


def test_unknown_plan_candidates_are_refused():
    with pytest.raises(ValueError, match="best_candidates"):
        PlannerConfig(best_candidates=("frame", "nope"))
    with pytest.raises(ValueError, match="best_candidates"):
        PlannerConfig(best_candidates=())
