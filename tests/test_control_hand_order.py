"""The song's hand crossings given to the hand on that side (pure arrays, no simulation)."""

import numpy as np

from pianist.control.planner.hand_order import uncross_hands

KEY_Y = np.arange(88) * 0.0235 - 1.0  # ascending with pitch, as the piano's key sites


def _song(notes, T=40):
    """notes: (midi key, first frame, end frame (excl.), finger 0-9)."""
    keys = np.zeros((T, 88), dtype=bool)
    fingers = np.full((T, 88), -1, dtype=np.int8)
    for key, first, end, finger in notes:
        keys[first:end, key - 21] = True
        fingers[first:end, key - 21] = finger
    return keys, fingers


def _crossed_frames(keys, fingers):
    right = keys & (fingers >= 0) & (fingers < 5)
    left = keys & (fingers >= 5)
    low_right = np.where(right, KEY_Y, np.inf).min(axis=1)
    high_left = np.where(left, KEY_Y, -np.inf).max(axis=1)
    return np.flatnonzero(low_right < high_left)


def test_a_bass_note_the_right_hand_reaches_down_for_goes_to_the_left_hand():
    # The left hand holds B3 D4 G4 (frames 0-30) while the right plays F5, then reaches down
    # for G3 (frames 10-18) under the chord: Clara Schumann's fourth polonaise.
    chord = [(59, 0, 30, 9), (62, 0, 30, 7), (67, 0, 30, 5)]
    keys, fingers = _song([*chord, (77, 0, 10, 4), (55, 10, 18, 4)])
    assert _crossed_frames(keys, fingers).tolist() == list(range(10, 18))
    out = uncross_hands(keys, fingers, KEY_Y)
    assert out.dtype == fingers.dtype
    assert (out[10:18, 55 - 21] == 9).all()  # the right little finger -> the left one
    changed = np.argwhere(out != fingers)
    assert {int(k) for _, k in changed} == {55 - 21}  # the chord and F5 keep their hands
    assert _crossed_frames(keys, out).size == 0


def test_a_note_changes_hand_for_its_whole_length():
    # G3 in the right hand (frames 5-20), crossing the left hand's longer E4 only from frame
    # 12: the whole note moves (a key handed over mid-note would be let up and struck again).
    keys, fingers = _song([(55, 5, 20, 0), (64, 12, 40, 5), (72, 0, 40, 3)])
    out = uncross_hands(keys, fingers, KEY_Y)
    assert (out[5:20, 55 - 21] == 5).all()
    assert _crossed_frames(keys, out).size == 0


def test_the_short_crossing_note_moves_not_the_long_one():
    # Frame 20: the right hand's G2 (a note of 4 frames) below the left hand's D4 (held for
    # 30): either alone would uncross the frame; the shorter note moves.
    keys, fingers = _song([(62, 0, 30, 6), (43, 20, 24, 0), (72, 0, 30, 2)])
    out = uncross_hands(keys, fingers, KEY_Y)
    assert (out[20:24, 43 - 21] == 5).all()
    assert (out[:30, 62 - 21] == 6).all()


def test_hands_in_order_are_left_as_they_are():
    keys, fingers = _song([(48, 0, 10, 9), (52, 0, 10, 7), (60, 0, 10, 0), (64, 5, 15, 2)])
    out = uncross_hands(keys, fingers, KEY_Y)
    assert np.array_equal(out, fingers)
    assert out is not fingers
