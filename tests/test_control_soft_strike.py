"""The planner's pushed strikes (pianist.control.planner.strikes): a soft note's key brought
down along a planned descent at the speed its velocity maps to, the finger's depth fed back
from the key's angle."""

import dataclasses

import numpy as np
import pytest

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner.strikes import (
    SOUND_ANGLE_RAD,
    plan_strikes,
    planned_angle,
    push_depth,
)
from pianist.env.loudness import KEY_LEVER_M, speed_to_velocity, velocity_to_speed
from pianist.eval.session import play
from pianist.media.results import played_dynamics
from pianist.music import GoalFrames, load_song
from pianist.music.pitch import NUM_KEYS

PUSHED = PlannerConfig().with_fields(push_below_velocity=90)
C4, E4 = 39, 43  # key indices (white keys)


def _goal(velocities: dict[int, list[tuple[int, int, int]]], frames: int = 20) -> GoalFrames:
    """Goal frames from {key: [(first frame, last frame, velocity)]}, fingered by finger 1."""
    keys = np.zeros((frames, NUM_KEYS), dtype=bool)
    vel = np.zeros((frames, NUM_KEYS), dtype=np.uint8)
    for key, notes in velocities.items():
        for first, last, v in notes:
            keys[first : last + 1, key] = True
            vel[first : last + 1, key] = v
    fingers = np.where(keys, 1, -1).astype(np.int8)
    sustain = np.zeros(frames, dtype=bool)
    return GoalFrames(keys=keys, sustain=sustain, fingers=fingers, dt=0.05, velocities=vel)


def test_velocity_to_speed_inverts_the_loudness_curve():
    velocities = np.arange(1, 128)
    np.testing.assert_array_equal(speed_to_velocity(velocity_to_speed(velocities)), velocities)
    assert np.all(np.diff(velocity_to_speed(velocities)) > 0)


def test_a_soft_note_is_planned_at_its_velocitys_speed_to_sound_at_its_frame():
    goal = _goal({C4: [(10, 14, 40)], E4: [(10, 14, 100)]})
    plan = plan_strikes(goal, push_below=90, lag_frames=0)
    # The soft note's key rises at the angular rate its velocity's speed gives; the loud
    # one is struck at full speed (rate 0).
    rate = velocity_to_speed(40) * 0.05 / KEY_LEVER_M[C4]
    np.testing.assert_allclose(plan.rate[10:15, C4], rate)
    assert not plan.rate[:, E4].any() and not plan.rate[:10, C4].any()
    # Planned to reach the angle where it sounds at the end of its onset's step, from rest
    # at the step before its push starts.
    assert plan.sound[12, C4] == 10
    assert planned_angle(plan, 12, C4, 10) == pytest.approx(SOUND_ANGLE_RAD[C4])
    start = int(plan.start[12, C4])
    assert planned_angle(plan, 12, C4, start - 1) == 0.0 < planned_angle(plan, 12, C4, start)
    # A slower (softer) note starts its push earlier.
    softer = plan_strikes(_goal({C4: [(10, 14, 20)], E4: [(10, 14, 100)]}), 90, 0)
    assert softer.start[12, C4] < start


def test_a_song_of_one_velocity_or_no_threshold_pushes_nothing():
    same = _goal({C4: [(10, 14, 40)], E4: [(10, 14, 40)]})
    assert not plan_strikes(same, push_below=90, lag_frames=0).pushed
    mixed = _goal({C4: [(10, 14, 40)], E4: [(10, 14, 100)]})
    assert not plan_strikes(mixed, push_below=0, lag_frames=0).pushed


def test_the_push_goes_deeper_when_the_key_lags_its_plan_and_shallower_when_ahead():
    plan = plan_strikes(_goal({C4: [(10, 14, 40)], E4: [(10, 14, 100)]}), 90, 0)
    full, share, lever = 0.025, 0.68, 0.12
    first = push_depth(plan, 12, C4, int(plan.start[12, C4]), 0.0, np.nan, full, share, lever, 1.0)
    assert first > share * full  # from the breakaway depth, by the first step's descent
    wanted = planned_angle(plan, 12, C4, 9)
    on_plan = push_depth(plan, 12, C4, 9, wanted, 0.02, full, share, lever, 1.0)
    behind = push_depth(plan, 12, C4, 9, wanted - 0.01, 0.02, full, share, lever, 1.0)
    ahead = push_depth(plan, 12, C4, 9, wanted + 0.01, 0.02, full, share, lever, 1.0)
    assert on_plan == pytest.approx(0.02)
    assert ahead < on_plan < behind
    # Never past the full depth, nor shallower than the breakaway depth.
    assert push_depth(plan, 12, C4, 9, 0.0, full, full, share, lever, 5.0) == full
    assert push_depth(plan, 12, C4, 9, 1.0, 0.0, full, share, lever, 1.0) == share * full


@pytest.mark.parametrize("physics", ["fast", "faithful"])
def test_pushed_notes_sound_near_the_velocity_asked_for(physics):
    """The crescendo (30 up to 110 and back): the notes pushed sound within 20 of their
    velocity in the median and follow it (rank correlation), where the plain planner strikes
    them all at ~90."""
    result = play("crescendo-scale", IKPlanner(PUSHED), physics=physics, seed=0)
    pairs = played_dynamics(result)[2]
    score = np.array([s.velocity for _, s in pairs])
    performed = np.array([p.velocity for p, _ in pairs])
    pushed = score < PUSHED.strikes.push_below_velocity
    assert pushed.sum() >= 10
    assert np.median(np.abs(performed[pushed] - score[pushed])) <= 20
    plain = play("crescendo-scale", IKPlanner(), physics=physics, seed=0)
    plain_pairs = played_dynamics(plain)[2]
    plain_error = np.median(
        [abs(p.velocity - s.velocity) for p, s in plain_pairs if s.velocity < 90]
    )
    assert np.median(np.abs(performed[pushed] - score[pushed])) < plain_error - 10
    rho = played_dynamics(result)[3]["velocity_rank_correlation"]
    assert rho >= 0.4


def test_a_song_of_one_velocity_plays_as_without_pushes():
    song = load_song("c-major-chords")
    assert len({note.velocity for note in song.notes}) == 1
    with_pushes = play(song, IKPlanner(PUSHED), physics="fast", seed=0)
    without = play(song, IKPlanner(), physics="fast", seed=0)
    np.testing.assert_array_equal(with_pushes.episode.actions, without.episode.actions)
    # The same song with one note softer is pushed, and plays otherwise.
    notes = list(song.notes)
    notes[3] = dataclasses.replace(notes[3], velocity=40)
    softer = play(dataclasses.replace(song, notes=tuple(notes)), IKPlanner(PUSHED), physics="fast")
    assert not np.array_equal(softer.episode.actions, without.episode.actions)
