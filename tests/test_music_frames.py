"""goal_frames: exact frame counts, coverage, the re-struck key release frame, GoalFrames."""

from __future__ import annotations

import numpy as np
import pytest

from pianist.music import GoalFrames, Note, Song, goal_frames, num_goal_frames

C4 = 60
KEY = C4 - 21  # 39


def _due(frames: GoalFrames, key: int = KEY) -> list[int]:
    return np.flatnonzero(frames.keys[:, key]).tolist()


def test_single_note_exact_count() -> None:
    frames = goal_frames(Song((Note(C4, 0.0, 0.1, finger=1),)), dt=0.05)
    assert frames.num_frames == 3  # int(0.1 * 20 + 1)
    assert frames.keys.shape == (3, 88) and frames.fingers.shape == (3, 88)
    assert frames.sustain.shape == (3,)
    assert _due(frames) == [0, 1, 2]
    assert frames.keys.sum() == 3
    assert frames.fingers[:, KEY].tolist() == [1, 1, 1]
    assert (frames.fingers[:, :KEY] == -1).all()
    assert frames.duration_s == pytest.approx(0.15)


def test_floor_ceil_both_ends_included() -> None:
    song = Song((Note(C4, 0.52, 0.73), Note(72, 0.0, 1.0)))
    frames = goal_frames(song)
    assert frames.num_frames == 21
    assert _due(frames) == list(range(10, 16))  # floor(10.4) .. ceil(14.6)
    assert frames.fingers[10, KEY] == -1  # unfingered note


def test_float_tolerance() -> None:
    # 0.15 * 20 = 3.0000000000000004 and 0.35 * 20 = 7.000000000000001 in binary floats.
    frames = goal_frames(Song((Note(C4, 0.15, 0.35), Note(72, 0.0, 0.7))))
    assert _due(frames) == [3, 4, 5, 6, 7]
    assert frames.num_frames == 15
    assert num_goal_frames(0.7, 0.05) == 15 and num_goal_frames(0.3, 0.1) == 4


def test_different_dt() -> None:
    frames = goal_frames(Song((Note(C4, 0.25, 0.5),)), dt=0.1)
    assert frames.num_frames == 6  # int(0.5 * 10 + 1)
    assert _due(frames) == [2, 3, 4, 5]


def test_restruck_key_gets_one_release_frame() -> None:
    song = Song((Note(C4, 0.0, 0.5, finger=0), Note(C4, 0.5, 1.0, finger=1)))
    frames = goal_frames(song)
    assert frames.num_frames == 21
    # Without the rule: 0..10 and 10..20. The first is cut to 0..8; frame 9 is free.
    assert _due(frames) == [*range(0, 9), *range(10, 21)]
    assert frames.fingers[8, KEY] == 0 and frames.fingers[9, KEY] == -1
    assert frames.fingers[10, KEY] == 1


def test_restruck_key_adjacent_frames() -> None:
    # 0..0.45 covers 0..9, next starts at frame 10: adjacent, so still cut to leave frame 9.
    frames = goal_frames(Song((Note(C4, 0.0, 0.45), Note(C4, 0.5, 1.0))))
    assert 9 not in _due(frames) and 8 in _due(frames) and 10 in _due(frames)


def test_gap_already_present_is_kept() -> None:
    frames = goal_frames(Song((Note(C4, 0.0, 0.4), Note(C4, 0.5, 1.0))))
    assert _due(frames) == [*range(0, 9), *range(10, 21)]


def test_restruck_very_short_note_pushes_next_start() -> None:
    # First covers 0..1 and cannot shrink below its first frame; the second moves to frame 2.
    frames = goal_frames(Song((Note(C4, 0.0, 0.05), Note(C4, 0.05, 0.5))))
    assert _due(frames) == [0, *range(2, 11)]


def test_other_keys_may_overlap() -> None:
    frames = goal_frames(Song((Note(C4, 0.0, 0.5), Note(62, 0.5, 1.0))))
    assert _due(frames) == list(range(0, 11))
    assert _due(frames, 62 - 21) == list(range(10, 21))
    assert frames.keys[10].sum() == 2


def test_sustain_frames() -> None:
    song = Song((Note(C4, 0.0, 1.0),), sustain=[(0.1, 0.3), (0.52, 2.0)])
    frames = goal_frames(song)
    assert frames.num_frames == 41  # the pedal outlasts the note: duration 2.0 s
    assert np.flatnonzero(frames.sustain).tolist() == [*range(2, 7), *range(10, 41)]


def test_empty_song_has_one_empty_frame() -> None:
    frames = goal_frames(Song(()))
    assert frames.num_frames == 1 and not frames.keys.any() and not frames.sustain.any()


def test_finger_mask_and_fingers_due() -> None:
    song = Song((Note(C4, 0.0, 0.1, finger=0), Note(48, 0.1, 0.2, finger=9)))
    frames = goal_frames(song)
    assert frames.finger_mask.shape == (5, 10) and frames.finger_mask.dtype == bool
    assert np.flatnonzero(frames.finger_mask[:, 0]).tolist() == [0, 1, 2]
    assert np.flatnonzero(frames.finger_mask[:, 9]).tolist() == [2, 3, 4]
    assert frames.finger_mask[:, 1:9].sum() == 0
    assert frames.fingers_due(2).tolist() == [True] + [False] * 8 + [True]
    assert not frames.fingers_due(99).any() and frames.fingers_due(99).shape == (10,)
    with pytest.raises(IndexError):
        frames.fingers_due(-1)


def test_goal_window_zero_padded() -> None:
    frames = goal_frames(Song((Note(C4, 0.0, 0.1),), sustain=[(0.0, 0.05)]))
    window = frames.goal_window(1, 3)
    assert window.shape == (4, 89) and window.dtype == bool
    assert window[:, KEY].tolist() == [True, True, False, False]
    assert window[:, 88].tolist() == [True, False, False, False]
    assert not frames.goal_window(10, 2).any()


def test_arrays_are_read_only() -> None:
    frames = goal_frames(Song((Note(C4, 0.0, 0.1),)))
    for array in (frames.keys, frames.sustain, frames.fingers, frames.finger_mask):
        with pytest.raises(ValueError):
            array[0] = 0


def test_constructor_copies_input() -> None:
    keys = np.zeros((2, 88), dtype=bool)
    frames = GoalFrames(keys, np.zeros(2, bool), np.full((2, 88), -1, np.int8), 0.05)
    keys[0, 0] = True
    assert not frames.keys.any()


@pytest.mark.parametrize(
    ("keys", "sustain", "fingers", "dt"),
    [
        (np.zeros((2, 87), bool), np.zeros(2, bool), np.full((2, 87), -1, np.int8), 0.05),
        (np.zeros((2, 88), int), np.zeros(2, bool), np.full((2, 88), -1, np.int8), 0.05),
        (np.zeros((0, 88), bool), np.zeros(0, bool), np.full((0, 88), -1, np.int8), 0.05),
        (np.zeros((2, 88), bool), np.zeros(3, bool), np.full((2, 88), -1, np.int8), 0.05),
        (np.zeros((2, 88), bool), np.zeros(2, bool), np.full((2, 88), -1, np.int32), 0.05),
        (np.zeros((2, 88), bool), np.zeros(2, bool), np.full((2, 88), 0, np.int8), 0.05),
        (np.ones((2, 88), bool), np.zeros(2, bool), np.full((2, 88), 10, np.int8), 0.05),
        (np.zeros((2, 88), bool), np.zeros(2, bool), np.full((2, 88), -1, np.int8), 0.0),
        (np.zeros((2, 88), bool), np.zeros(2, bool), np.full((2, 88), -1, np.int8), float("nan")),
    ],
)
def test_goal_frames_validation(keys, sustain, fingers, dt) -> None:
    with pytest.raises(ValueError):
        GoalFrames(keys, sustain, fingers, dt)


def test_bad_dt() -> None:
    with pytest.raises(ValueError):
        goal_frames(Song(()), dt=0)


def test_a_lead_in_prepends_silent_frames() -> None:
    song = Song((Note(60, 0.0, 0.1, finger=0),), sustain=((0.0, 0.1),))
    goal = goal_frames(song)
    led = goal.with_lead_in(10)
    assert led.num_frames == goal.num_frames + 10
    assert not led.keys[:10].any() and not led.sustain[:10].any()
    assert (led.fingers[:10] == -1).all() and not led.finger_mask[:10].any()
    np.testing.assert_array_equal(led.keys[10:], goal.keys)
    np.testing.assert_array_equal(led.fingers[10:], goal.fingers)
    np.testing.assert_array_equal(led.sustain[10:], goal.sustain)
    assert goal.with_lead_in(0) is goal


@pytest.mark.parametrize("frames", [-1, 1.5, True, "3"])
def test_a_lead_in_needs_a_whole_number_of_frames(frames) -> None:
    with pytest.raises(ValueError, match="whole number of frames"):
        goal_frames(Song((Note(60, 0.0, 0.1),))).with_lead_in(frames)


def test_goal_frames_keep_each_notes_velocity_and_where_it_starts():
    from pianist.music.frames import DEFAULT_VELOCITY

    notes = (
        Note(60, 0.0, 0.2, velocity=30),
        Note(60, 0.2, 0.4, velocity=90),  # re-struck: a free frame between the two
        Note(64, 0.1, 0.4, velocity=127),
    )
    goal = goal_frames(Song(notes=notes, name="dynamics"), dt=0.05)
    c4, e4 = 60 - 21, 64 - 21
    due_c4 = np.flatnonzero(goal.keys[:, c4])
    assert set(goal.velocities[due_c4, c4]) == {30, 90}
    assert np.all(goal.velocities[~goal.keys] == 0)
    assert np.flatnonzero(goal.onsets[:, c4]).tolist() == [0, 4]
    assert np.flatnonzero(goal.onsets[:, e4]).tolist() == [2]
    assert goal.velocities[2, e4] == 127 and goal.velocities[4, c4] == 90
    lead = goal.with_lead_in(3)
    assert np.array_equal(lead.velocities[3:], goal.velocities) and not lead.velocities[:3].any()
    # Goal frames made without velocities: mezzo-forte wherever a key is due.
    plain = GoalFrames(goal.keys, goal.sustain, goal.fingers, goal.dt)
    assert np.all(plain.velocities[goal.keys] == DEFAULT_VELOCITY)
    with pytest.raises(ValueError, match="1..127 where keys are due"):
        GoalFrames(goal.keys, goal.sustain, goal.fingers, goal.dt, np.zeros_like(goal.velocities))
