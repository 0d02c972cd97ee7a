"""What the fingertip policy reads and writes, one hand at a time, in the hand's own frame.

The policy sees each hand alone, mirrored for the left hand (``sign`` -1 flips every
distance along the keyboard), so one network plays both hands and what it learns at one
place on the keyboard holds at every other: every position is relative to the hand.

Inputs (:func:`hand_features`, (D,) float32, D = :data:`FEATURE_DIM`):

- the hand: its side, its slide's position in its range and its velocity (m/s), the other
  forearm's distance (m);
- its notes over the next :data:`WINDOW` frames: per frame, how many of its keys are due and
  how far (m) the slide would have to move for the middle finger to be over the lowest and
  the highest of them;
- each finger: its next key by the song's fingering within the window (whether it has one,
  frames until it is due, whether that note is already sounding, how long it lasts, how far
  the slide would move to put this finger over it), the fingertip's offset from that key's
  press point and from its own lifted place (m), whether the key is black and whether it is
  down, and the mode the finger was in last step.

Outputs (:data:`OUTPUT_DIM` in [-1, 1], the network's tanh): the slide's target for the end
of the next step, its position relative to now and its velocity (:func:`encode_move`); then
per finger a score per :class:`Mode` (the largest is played).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from pianist.control.planner.forearm import _note_onsets
from pianist.sim import constants as C

FINGERS = 5
WINDOW = 20
"""Frames of the song the policy reads ahead (1 s at the 20 Hz control rate)."""
MOVE_UNIT_M = 0.01
"""The slide's position target relative to now is written ``asinh(move / unit) / asinh(30)``:
a millimetre counts as much in the loss as a jump's last centimetres, and a jump of up to
0.3 m (the furthest a step's target goes) still fits in [-1, 1]."""
SPEED_UNIT = 0.1
"""m/s: the same for the slide's velocity target (up to 3 m/s)."""
_SQUASH = float(np.arcsinh(30.0))


def encode_move(value: np.ndarray | float, unit: float) -> np.ndarray:
    """A move (m) or speed (m/s) -> the policy's output scale in [-1, 1] (clipped)."""
    return np.clip(np.arcsinh(np.asarray(value) / unit) / _SQUASH, -1.0, 1.0)


def decode_move(value: np.ndarray | float, unit: float) -> np.ndarray:
    """The inverse of :func:`encode_move`."""
    return unit * np.sinh(np.asarray(value) * _SQUASH)


class Mode(IntEnum):
    """What a finger does in a step (the planner's finger states, merged by target)."""

    LIFT = 0
    """Its lifted posture, clear of the keys."""
    HOVER = 1
    """Above its next key (the planner's hovering and travelling)."""
    PRESS = 2
    """Below its key's top, so its servo holds the key down (pressing and pushing)."""
    RESTRIKE = 3
    """Just above its key, which is down and must sound again."""


NUM_MODES = len(Mode)
HAND_DIM = 4 + 3 * WINDOW
FINGER_DIM = 13 + NUM_MODES
FEATURE_DIM = HAND_DIM + FINGERS * FINGER_DIM
OUTPUT_DIM = 2 + FINGERS * NUM_MODES


@dataclass
class NextKeys:
    """Each finger's next key by the song's fingering, for every frame (10 fingers, T frames):
    ``frame`` (10, T) the frame it is due (-1: none left), ``key`` (10, T) which key,
    ``ongoing`` (10, T) bool the note started before the frame, ``end`` (10, T) the frame
    after the note's last."""

    frame: np.ndarray
    key: np.ndarray
    ongoing: np.ndarray
    end: np.ndarray

    @classmethod
    def of(cls, keys: np.ndarray, fingers: np.ndarray) -> NextKeys:
        """From the goal's ``keys`` (T, 88) bool and ``fingers`` (T, 88) int (-1: none)."""
        T = keys.shape[0]
        onset = _note_onsets(keys)
        # run_end[t, k]: the first frame >= t at which key k is not due.
        run_end = np.full((T + 1, keys.shape[1]), T)
        for t in range(T - 1, -1, -1):
            run_end[t] = np.where(keys[t], run_end[t + 1], t)
        frame = np.full((10, T), -1)
        key = np.full((10, T), -1)
        for g in range(10):
            mine = keys & (fingers == g)
            has = mine.any(axis=1)
            lowest = np.argmax(mine, axis=1)
            nxt, k = -1, -1
            for t in range(T - 1, -1, -1):
                if has[t]:
                    nxt, k = t, int(lowest[t])
                frame[g, t], key[g, t] = nxt, k
        valid = frame >= 0
        f, k = np.maximum(frame, 0), np.maximum(key, 0)
        ongoing = valid & (onset[f, k] < np.arange(T)[None, :])
        end = np.where(valid, run_end[f, k], -1)
        return cls(frame, key, ongoing, end)


@dataclass
class HandView:
    """What :func:`hand_features` reads of one hand and the scene (planner set-up values)."""

    sign: float
    """+1 for the right hand, -1 for the left (mirrors distances along the keyboard)."""
    finger_offset: int
    tx: float
    """The slide's position (m) and velocity (m/s) now."""
    tx_vel: float
    tx_mid: float
    tx_half: float
    other_y: float | None
    """The other forearm's root y minus this one's (m), None without another hand."""
    tip_offset_y: np.ndarray
    """(5,) m: slide position that puts each finger over a key at y is y - this."""
    tips: np.ndarray
    """(5, 3) m: the fingertips, world frame."""
    lift_tips: np.ndarray
    """(5, 3) m: the lifted fingertips, world frame (for the forearm where it is now)."""


def hand_features(
    view: HandView,
    t: int,
    goal_keys: np.ndarray,
    goal_fingers: np.ndarray,
    nxt: NextKeys,
    key_point: np.ndarray,
    key_top_z: np.ndarray,
    key_down: np.ndarray,
    last_mode: np.ndarray,
) -> np.ndarray:
    """One hand's features at step ``t``, shape (:data:`FEATURE_DIM`,) float32.

    Args:
        goal_keys, goal_fingers: the song's (T, 88) due keys and fingers (0-4 right, 5-9 left).
        key_point: (88, 3) m, where a finger presses each key; ``key_top_z`` (88,) m.
        key_down: (88,) bool, the keys down now.
        last_mode: (5,) int, each finger's :class:`Mode` last step.
    """
    s = view.sign
    T = goal_keys.shape[0]
    out = np.zeros(FEATURE_DIM, dtype=np.float32)
    out[0] = s
    out[1] = s * (view.tx - view.tx_mid) / view.tx_half
    out[2] = s * view.tx_vel
    out[3] = 1.0 if view.other_y is None else s * view.other_y
    # The hand's notes ahead: count and the slide's moves to the lowest and highest (all the
    # window's frames at once: (W, 88) masks over every key's move).
    lo, hi = view.finger_offset, view.finger_offset + FINGERS
    window = slice(t, min(t + WINDOW, T))
    fingers = goal_fingers[window]
    mine = goal_keys[window] & (fingers >= lo) & (fingers < hi)
    busy = np.flatnonzero(mine.any(axis=1))
    if busy.size:
        mine = mine[busy]
        moves = s * (key_point[:, 1] - view.tip_offset_y[2] - view.tx)  # (88,)
        ahead = out[4:HAND_DIM].reshape(WINDOW, 3)
        ahead[busy, 0] = mine.sum(axis=1) / FINGERS
        ahead[busy, 1] = np.where(mine, moves, np.inf).min(axis=1)
        ahead[busy, 2] = np.where(mine, moves, -np.inf).max(axis=1)
    radius = C.FINGERTIP_CAPSULE_RADIUS_M
    for f in range(FINGERS):
        base = HAND_DIM + f * FINGER_DIM
        g = view.finger_offset + f
        row = out[base : base + FINGER_DIM]
        tip = view.tips[f]
        off = tip - view.lift_tips[f]
        row[10:13] = (off[0], s * off[1], off[2])
        row[13 + int(last_mode[f])] = 1.0
        frame = nxt.frame[g, t]
        if frame < 0 or frame >= t + WINDOW:
            continue
        key = int(nxt.key[g, t])
        point = key_point[key]
        row[0] = 1.0
        row[1] = (frame - t) / WINDOW
        row[2] = float(nxt.ongoing[g, t])
        row[3] = min(nxt.end[g, t] - frame, WINDOW) / WINDOW
        row[4] = s * (point[1] - view.tip_offset_y[f] - view.tx)
        row[5:8] = (tip[0] - point[0], s * (tip[1] - point[1]), tip[2] - key_top_z[key] - radius)
        row[8] = 1.0 if C.BLACK_KEY_MASK[key] else -1.0
        row[9] = float(key_down[key])
    return out


def mode_of(state: int, active: bool) -> Mode:
    """The :class:`Mode` of a planner finger state (:class:`FingerState`) and target flag."""
    from pianist.control.planner.targets import FingerState

    if not active:
        return Mode.LIFT
    if state in (FingerState.PRESSING, FingerState.PUSHING):
        return Mode.PRESS
    if state == FingerState.RESTRIKING:
        return Mode.RESTRIKE
    return Mode.HOVER
