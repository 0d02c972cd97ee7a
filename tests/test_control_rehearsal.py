"""Choosing the planner's plan by rehearsal, and replaying the rehearsal as the performance."""

import numpy as np
import pytest

from pianist.control.base import BaseController
from pianist.control.lookahead import LookAhead
from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner import controller as planner_controller
from pianist.control.planner.config import PLAN_CANDIDATES
from pianist.control.planner.rehearsal import rehearse
from pianist.env.handle import control_handle
from pianist.eval import run_episode
from pianist.eval.session import make_env
from pianist.music import Note, Song

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
    assert set(rehearsed) <= set(PlannerConfig().plan.best_candidates) and len(rehearsed) >= 2
    winner = max(rehearsed, key=rehearsed.get)
    # Deterministic physics: the performance scores exactly what its rehearsal scored.
    assert f1 == pytest.approx(rehearsed[winner], abs=1e-12)
    assert planner.plan_kind == PLAN_CANDIDATES[winner]
    assert winner == "frame" and rehearsed["piece-f1"] < f1 - 0.05


def test_a_plan_that_differs_late_is_rehearsed_from_there_and_scores_as_played_alone(
    monkeypatch,
):
    # A five-finger melody, then broken octaves, over a bass: the plan that may turn the
    # wrist anywhere is the step-F1 plan until the octaves (frame 97), and is rehearsed from
    # shortly before them, on from the state the first rehearsal kept there. Each
    # candidate's rehearsed F1 is the F1 of its plan played alone, from the start, and the
    # performance that replays the spliced winner scores it too.
    notes = [
        Note(p, 0.2 * i, 0.2 * i + 0.18, finger=i % 5)
        for i, p in enumerate((60, 62, 64, 65, 67, 65, 64, 62) * 3)
    ]
    start = 0.2 * len(notes)
    for i in range(10):
        pitch, finger = (60, 0) if i % 2 == 0 else (72, 4)
        notes.append(Note(pitch, start + 0.25 * i, start + 0.25 * i + 0.23, finger=finger))
    notes += [Note((43, 48)[i % 2], 0.5 * i, 0.5 * i + 0.48, finger=7) for i in range(15)]
    song = Song(tuple(notes), name="melody-then-octaves")
    names = ("piece-f1", "piece-f1-turn")
    # No rehearsal given up: each rehearsed F1 is then the plan's, not a bound on it.
    monkeypatch.setattr(planner_controller, "f1_lost", lambda f1, steps: np.inf)
    planner = IKPlanner(PlannerConfig().with_fields(best_candidates=names))
    f1 = _episode(planner, song).metrics()["f1"]
    assert set(planner.rehearsed) == set(names)
    later = max(names, key=planner.rehearsed_from.get)
    assert planner.rehearsed_from[later] > 50  # the melody's 96 frames, less a margin
    for name in names:
        alone = _episode(IKPlanner(PlannerConfig().with_fields(best_candidates=(name,))), song)
        assert planner.rehearsed[name] == pytest.approx(alone.metrics()["f1"], abs=1e-12)
    assert f1 == pytest.approx(max(planner.rehearsed.values()), abs=1e-12)


def test_choosing_by_playable_key_frames_needs_no_rehearsal():
    planner = IKPlanner(PlannerConfig().with_fields(choose_plan="playable"))
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
    planner = IKPlanner(PlannerConfig().with_fields(hand_planning="piece"))
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
        PlannerConfig().with_fields(best_candidates=("frame", "nope"))
    with pytest.raises(ValueError, match="best_candidates"):
        PlannerConfig().with_fields(best_candidates=())
