"""The ``velocity`` reward term: how loud the due keys struck in a step sounded against the
score, measured as the metrics measure a performance's velocities."""

import numpy as np
import pytest

from pianist.control.planner import ENV_OPTIONS, IKPlanner, PlannerConfig
from pianist.env import PianoEnv
from pianist.env.rewards import velocity_reward
from pianist.eval import run_episode
from pianist.media.dynamics import episode_velocities
from pianist.music import Note, Song


def _crescendo() -> Song:
    # C major up and down, each note louder than the last, then softer, right hand.
    pitches = (60, 62, 64, 65, 67, 65, 64, 62, 60)
    velocities = (20, 40, 60, 80, 110, 80, 60, 40, 20)
    fingers = (0, 1, 2, 3, 4, 3, 2, 1, 0)
    notes = [
        Note(p, 0.3 + 0.3 * i, 0.55 + 0.3 * i, velocity=v, finger=f)
        for i, (p, v, f) in enumerate(zip(pitches, velocities, fingers, strict=True))
    ]
    return Song(tuple(notes), name="crescendo")


def _episode(velocity_goal: bool, push_below_velocity: int = 0):
    """The planner's episode on the crescendo; by default every note struck at full speed."""
    env = PianoEnv(_crescendo(), physics="fast", velocity_goal=velocity_goal, **ENV_OPTIONS)
    config = PlannerConfig().with_fields(push_below_velocity=push_below_velocity)
    return env, run_episode(env, IKPlanner(config), seed=0)


def test_the_term_is_what_the_metrics_measure_step_by_step():
    env, episode = _episode(velocity_goal=True)
    played = episode_velocities(episode, env.scene)  # aligned with episode.note_events
    events = np.asarray(episode.note_events, dtype=np.float64)
    dt = episode.control_timestep_s
    expected = np.zeros(len(episode.rewards))
    step = np.ceil(events[:, 0] / dt - 1e-9).astype(int) - 1
    struck = (events[:, 1] >= 0) & (events[:, 2] != 0)
    goal = env.goal
    for t in range(len(expected)):
        rows = np.flatnonzero(struck & (step == t))
        keys = events[rows, 1].astype(int)
        due = goal.keys[t, keys]
        expected[t] = velocity_reward(played[rows[due]], goal.velocities[t, keys[due]])
    term = np.asarray(episode.reward_terms["velocity"])
    np.testing.assert_allclose(term, expected, atol=1e-12)
    # Every note struck gives a step with a (negative) term; the planner striking every note
    # plays them all at about one loudness, so the crescendo's ends are far off.
    assert (term < 0).sum() >= 8 and term.min() < -0.1
    # Pushing the soft ones (the default) brings the term closer to 0 over the piece.
    _, pushed = _episode(velocity_goal=True, push_below_velocity=80)
    assert np.sum(pushed.reward_terms["velocity"]) > term.sum() + 0.1


def test_without_the_score_s_loudness_the_term_is_zero_and_the_reward_the_paper_s():
    _, plain = _episode(velocity_goal=False)
    _, loud = _episode(velocity_goal=True)
    assert not np.any(plain.reward_terms["velocity"])
    np.testing.assert_array_equal(plain.actions, loud.actions)
    # The same steps, the total less the velocity term (weight 1) the same.
    velocity = np.asarray(loud.reward_terms["velocity"])
    assert velocity.any()
    np.testing.assert_allclose(loud.rewards - velocity, plain.rewards, atol=1e-12)


def test_the_reward_function():
    assert velocity_reward(np.array([]), np.array([])) == 0.0
    assert velocity_reward(np.array([80, 80]), np.array([80, 80])) == 0.0
    assert velocity_reward(np.array([1, 127]), np.array([127, 1])) == pytest.approx(-126 / 127)
