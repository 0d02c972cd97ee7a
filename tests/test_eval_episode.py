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
    terms = {"key_press", "fingering", "energy", "sustain", "forearm", "velocity"}
    assert set(first.reward_terms) == terms
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
    width = env.action_space.shape[0]
    for steps in (2, env.num_steps + 1):  # another song's (or lead-in's) actions
        with pytest.raises(ValueError, match=f"are {steps} steps, this episode has"):
            run_episode(env, ReplayController(np.zeros((steps, width))))


def test_make_controller_specs():
    assert isinstance(make_controller("random"), RandomController)
    assert isinstance(make_controller("zero"), ZeroController)
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("planner9000")
    with pytest.raises(FileNotFoundError):
        make_controller("replay:/nonexistent/actions.npy")


def test_after_a_lead_in_the_song_steps_are_also_scored_alone():
    # Two silent lead-in steps with a wrong press in the first, then two song steps: one
    # played right, one missed.
    episode = _episode([])
    episode.lead_in_steps = 2
    episode.active_keys[0, 5] = True
    episode.goal_keys[2:, 39] = True
    episode.active_keys[2, 39] = True
    metrics = episode.metrics()
    assert metrics["f1"] == pytest.approx((0 + 1 + 1 + 0) / 4)
    assert metrics["song_f1"] == pytest.approx((1 + 0) / 2)
    assert metrics["song_precision"] == 1.0 and metrics["song_recall"] == 0.5
    assert metrics["lead_in_steps"] == 2
    # A song that itself begins with a rest is scored from its first note the same way.
    episode.lead_in_steps = 0
    metrics = episode.metrics()
    assert metrics["song_f1"] == pytest.approx((1 + 0) / 2) and "lead_in_steps" not in metrics
    assert metrics["silent_start_steps"] == 2
    # A song with a key due in its first step has no song-only metrics.
    episode.goal_keys[0, 5] = True
    assert "song_f1" not in episode.metrics()


def test_an_environment_with_a_lead_in_starts_the_song_later():
    plain = PianoEnv(TINY, physics="fast")
    env = PianoEnv(TINY, physics="fast", initial_buffer_s=0.26)  # rounds to 5 steps
    assert env.config.lead_in_steps == 5
    assert env.goal.num_frames == plain.goal.num_frames + 5
    assert not env.goal.keys[:5].any()
    np.testing.assert_array_equal(env.goal.keys[5:], plain.goal.keys)
    episode = run_episode(env, ZeroController(), seed=0)
    assert episode.num_steps == env.goal.num_frames and episode.lead_in_steps == 5
    # Nothing is pressed: only the steps with nothing due score (F1 1), the lead-in's among them.
    silent = ~env.goal.keys.any(axis=1)
    metrics = episode.metrics()
    assert metrics["song_f1"] == pytest.approx(silent[5:].mean()) and metrics["song_f1"] < 0.5
    assert metrics["f1"] == pytest.approx(silent.mean())


@pytest.mark.parametrize("bad", [-0.5, float("nan"), float("inf"), True])
def test_a_bad_lead_in_is_refused(bad):
    with pytest.raises(ValueError, match="initial_buffer_s"):
        PianoEnv(TINY, physics="fast", initial_buffer_s=bad)
