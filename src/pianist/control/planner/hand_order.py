"""The song's hands put in order across the keyboard: crossings given to the hand on that side.

A score may cross the hands: Clara Schumann's third and fourth polonaises (op. 1) have the
right hand reach over the left for bass notes, 35 and 43 frames of them. Two forearms on
slides cannot cross, so a plan that follows such a fingering sends the right forearm through
the left one, and keeping the forearms apart afterwards (``_keep_forearms_apart``) pushes
both away from every key they were due to play. :func:`uncross_hands` gives crossing notes
to the other hand instead, as few of their key-frames as put every frame's hands in order
(the left hand's keys all below the right hand's); the plan then fingers them as its own.

Arrays in, arrays out: (T, 88) frames by keys; fingers 0-4 the right hand (thumb to little
finger), 5-9 the left.
"""

from __future__ import annotations

import numpy as np

#: Fingers per hand: finger f of the right hand is finger f + 5 of the left.
_PER_HAND = 5


def uncross_hands(
    keys: np.ndarray, fingers: np.ndarray, key_y: np.ndarray, max_rounds: int = 4
) -> np.ndarray:
    """``fingers`` with every note that crosses the other hand moved to that hand.

    At each frame whose hands cross (a right-hand key below a left-hand key, by ``key_y``)
    the frame's keys are split in order across the keyboard, the left hand taking the lowest,
    at the split that moves the fewest key-frames to the other hand (each key weighs its
    note's length: a bass note the right hand reaches down for moves, not the chord the left
    hand holds under it; of equals, the split at the widest gap between two neighbouring
    keys). A note (a run of frames of one key with one finger) that changes hand at any of
    its frames changes hand at all of them, keeping its finger's number (the right little
    finger becomes the left little finger). Moving a held note can cross another frame, so
    this repeats, at most ``max_rounds`` times.

    Args:
        keys: (T, 88) bool, keys due.
        fingers: (T, 88) int, the finger 0-9 of each due key (-1 elsewhere).
        key_y: (88,) each key's position across the keyboard (m), ascending with pitch.
        max_rounds: passes over the piece at most.
    Returns:
        (T, 88) the fingers, same dtype; unchanged where no frame crosses.
    """
    out = np.array(fingers, copy=True)
    for _ in range(max_rounds):
        flip = _crossed_key_frames(keys, out, key_y)
        if not flip.any():
            break
        out = _flip_notes(keys, out, flip)
    return out


def _crossed_key_frames(keys: np.ndarray, fingers: np.ndarray, key_y: np.ndarray) -> np.ndarray:
    """(T, 88) bool: the key-frames whose hand the cheapest ordered split changes."""
    flip = np.zeros(keys.shape, dtype=bool)
    right = keys & (fingers >= 0) & (fingers < _PER_HAND)
    left = keys & (fingers >= _PER_HAND)
    y = np.asarray(key_y, dtype=float)
    low_right = np.where(right, y, np.inf).min(axis=1)
    high_left = np.where(left, y, -np.inf).max(axis=1)
    crossed = np.flatnonzero(low_right < high_left)
    if crossed.size == 0:
        return flip
    length = _note_lengths(keys, fingers)
    for t in crossed.tolist():
        ids = np.flatnonzero(keys[t])
        ids = ids[np.argsort(y[ids], kind="stable")]
        is_left = left[t, ids]
        weight = length[t, ids].astype(float)
        # cost[s]: the key-frames whose notes change hand if the left hand takes the lowest s.
        right_below = np.r_[0.0, np.cumsum(np.where(is_left, 0.0, weight))]
        left_above = np.r_[np.cumsum(np.where(is_left, weight, 0.0)[::-1])[::-1], 0.0]
        cost = right_below + left_above
        gaps = np.r_[0.0, np.diff(y[ids]), 0.0]  # the gap at each split (none at the ends)
        best = np.flatnonzero(cost == cost.min())
        s = int(best[np.argmax(gaps[best])])
        new_left = np.arange(ids.size) < s
        flip[t, ids[new_left != is_left]] = True
    return flip


def _notes(keys: np.ndarray, fingers: np.ndarray, k: int) -> list[tuple[int, int]]:
    """Key ``k``'s notes, (first frame, end frame): runs of due frames with one finger."""
    due, finger = keys[:, k], fingers[:, k]
    T = due.shape[0]
    # A note starts where the key becomes due or its finger changes.
    starts = np.flatnonzero(due & ~np.r_[False, due[:-1] & (finger[1:] == finger[:-1])])
    notes = []
    for a in starts.tolist():
        b = a + 1
        while b < T and due[b] and finger[b] == finger[a]:
            b += 1
        notes.append((a, b))
    return notes


def _note_lengths(keys: np.ndarray, fingers: np.ndarray) -> np.ndarray:
    """(T, 88) int: at each due key-frame, the length (frames) of the note it belongs to."""
    length = np.zeros(keys.shape, dtype=int)
    for k in np.flatnonzero(keys.any(axis=0)).tolist():
        for a, b in _notes(keys, fingers, k):
            length[a:b, k] = b - a
    return length


def _flip_notes(keys: np.ndarray, fingers: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """``fingers`` with every note holding a ``flip`` key-frame given to the other hand."""
    out = fingers.copy()
    for k in np.flatnonzero(flip.any(axis=0)).tolist():
        for a, b in _notes(keys, fingers, k):
            if flip[a:b, k].any():
                out[a:b, k] = (fingers[a, k] + _PER_HAND) % (2 * _PER_HAND)
    return out
