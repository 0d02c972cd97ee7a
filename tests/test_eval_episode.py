"""Episode records, rollouts and the baseline controllers."""

import numpy as np
import pytest

from pianist.control import RandomController, ReplayController, ZeroController, make_controller
from pianist.env import PianoEnv
from pianist.eval import Episode, run_episode
from pianist.music import Note, Song

TINY = Song(notes=(Note(60, 0.0, 0.15, finger=1), Note(60, 0.2, 0.3, finger=1)), name="tiny")


def _episode(events, end_time_s=1.0):
    T = 4
    return Episode(
        actions=np.zeros((T, 3)),
        active_keys=np.zeros((T, 88), bool),
        sustain=np.zeros(T, bool),
        goal_keys=np.zeros((T, 88), bool),
        goal_sustain=np.zeros(T, bool),
        rewards=np.ones(T),
        reward_terms={},
        note_events=np.array(events, dtype=float).reshape(-1, 3),
        control_timestep_s=0.05,
        end_time_s=end_time_s,
    )


def test_performance_pairs_on_and_off_events_into_notes():
    song = _episode(
        [(0.1, 39, 1), (0.2, 40, 1), (0.3, 39, 0), (0.35, -1, 1), (0.5, -1, 0)]
    ).performance()
    pitches = sorted((n.pitch, round(n.onset_s, 6), round(n.offset_s, 6)) for n in song.notes)
    # Key 39 = C4 (MIDI 60); key 40 still sounds at the end and closes at end_time_s.
    assert pitches == [(60, 0.1, 0.3), (61, 0.2, 1.0)]
    assert song.sustain == ((0.35, 0.5),)


def test_metrics_nothing_due_nothing_pressed_is_perfect():
    metrics = _episode([]).metrics()
    assert metrics["precision"] == metrics["recall"] == metrics["f1"] == 1.0
    assert metrics["steps"] == 4 and metrics["seconds"] == pytest.approx(0.2)
    assert metrics["return"] == 4.0


def test_run_episode_records_every_step_and_replay_reproduces_it():
    env = PianoEnv(TINY, physics="fast")
    first = run_episode(env, RandomController(), seed=5)
    assert first.actions.shape == (env.num_steps, env.action_space.shape[0])
    assert first.active_keys.shape == (env.num_steps, 88)
    np.testing.assert_array_equal(first.goal_keys, env.goal.keys)
    assert set(first.reward_terms) == {"key_press", "fingering", "energy", "sustain", "forearm"}
    replay = run_episode(env, ReplayController(first.actions), seed=5)
    np.testing.assert_array_equal(replay.active_keys, first.active_keys)
    np.testing.assert_array_equal(replay.rewards, first.rewards)


def test_zero_controller_keeps_the_pedal_up():
    env = PianoEnv(TINY, physics="fast")
    episode = run_episode(env, ZeroController(), seed=0)
    assert not episode.sustain.any()
    assert np.all(episode.actions[:, :-1] == 0)


def test_replay_rejects_wrong_width_and_running_out():
    env = PianoEnv(TINY, physics="fast")
    with pytest.raises(ValueError, match="dimensions"):
        run_episode(env, ReplayController(np.zeros((env.num_steps, 5))))
    with pytest.raises(ValueError, match="ran out"):
        run_episode(env, ReplayController(np.zeros((2, env.action_space.shape[0]))))


def test_make_controller_specs():
    assert isinstance(make_controller("random"), RandomController)
    assert isinstance(make_controller("zero"), ZeroController)
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("planner9000")
    with pytest.raises(FileNotFoundError):
        make_controller("replay:/nonexistent/actions.npy")
