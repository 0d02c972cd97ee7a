"""Note velocities of a performance, from how fast each key went down when it sounded.

The simulation has no hammer, so a played note's loudness is estimated from its key's motion
as a real piano's action turns key speed into hammer speed. The episode records every key's
angle once per control step (``Episode.qpos``) and the substep at which each key started
sounding (``Episode.note_events``). A key sounds once its angle reaches its activation
threshold (:data:`pianist.sim.constants.KEY_ACTIVATION_THRESHOLD_RAD` above the bottom of its
travel), so the strike speed of a note that sounded at time t_on, in the control step that
started at t_s with the key at angle q_s, is the finite difference

    speed = lever * (threshold - q_s) / (t_on - t_s)      [m/s]

the mean downward speed of the key's front edge (``lever``: hinge-to-front length, 0.15 m for
a white key, 0.09 m for a black one, so both kinds compare in m/s) over the part of the step
before it sounded; the same over the window from the previous step's start is taken when it is
larger (a key that went most of the way down in the previous step). A key that rested for part
of the window reads slower than it struck: the estimate is a lower bound, with the event times
resolved to a physics substep (5 ms).

:func:`speed_to_velocity` maps the speed to MIDI velocity with a logarithmic curve (loudness in
dB grows about linearly with log hammer speed): 1 at :data:`SOFTEST_SPEED_M_S` or slower, 127
at :data:`LOUDEST_SPEED_M_S` or faster. The two ends bracket what the planner's strikes
produce (docs/media.md has the measurements).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from pianist.music import Note, Song
from pianist.sim import constants as C

#: Key speed (m/s, at the key's front edge) that maps to MIDI velocity 1.
SOFTEST_SPEED_M_S = 0.02
#: Key speed (m/s) that maps to MIDI velocity 127.
LOUDEST_SPEED_M_S = 0.6
#: A performance note may start this much before the score note it matches (the goal is
#: quantised to control steps, and the planner aims a little early).
MATCH_EARLY_S = 0.1

KEY_LEVER_M = np.where(C.BLACK_KEY_MASK, C.BLACK_KEY_LENGTH_M, C.WHITE_KEY_LENGTH_M)
"""(88,) hinge-to-front length of each key, metres."""


def strike_speeds(
    note_events: np.ndarray,
    key_angles: np.ndarray,
    control_timestep_s: float,
    threshold_rad: np.ndarray,
    lever_m: np.ndarray = KEY_LEVER_M,
) -> np.ndarray:
    """The strike speed of every key-on event (see the module docstring).

    Args:
        note_events: (n, 3) rows (time s, key 0-87 or -1 for the pedal, 1 on / 0 off).
        key_angles: (T + 1, 88) key hinge angles (rad) at times 0, dt, ..., T dt.
        control_timestep_s: dt, seconds.
        threshold_rad: (88,) angle at which each key sounds.
        lever_m: (88,) hinge-to-front length of each key, metres.
    Returns:
        (n,) m/s for key-on rows, NaN for key-off and pedal rows.
    """
    events = np.asarray(note_events, dtype=np.float64).reshape(-1, 3)
    angles = np.asarray(key_angles, dtype=np.float64)
    speeds = np.full(len(events), np.nan)
    on = np.flatnonzero((events[:, 1] >= 0) & (events[:, 2] != 0))
    if on.size == 0:
        return speeds
    keys = events[on, 1].astype(int)
    times = events[on, 0]
    threshold = np.asarray(threshold_rad, dtype=np.float64)[keys]
    # The step whose span (t_s, t_s + dt] holds the event: event times are substep ends.
    step = np.clip(np.ceil(times / control_timestep_s - 1e-9).astype(int) - 1, 0, len(angles) - 2)
    rate = np.zeros(len(on))
    # Windows from the start of that step and of the one before: a key that went most of the
    # way down in the previous step and tipped over its threshold at the first substep of this
    # one moved fast, which only the longer window sees. The key accelerates under the
    # finger, so a window's mean speed is at most the speed at the strike: take the larger.
    for back in (0, 1):
        first = step - back
        valid = first >= 0
        first = np.maximum(first, 0)
        travel = threshold - angles[first, keys]
        elapsed = times - first * control_timestep_s
        ok = valid & (travel > 0) & (elapsed > 1e-9)
        rate = np.where(ok, np.maximum(rate, travel / np.maximum(elapsed, 1e-9)), rate)
    # A key at or above its threshold at both starts (it bounced near the bottom and sounded
    # again) keeps 0: the softest velocity.
    speeds[on] = rate * np.asarray(lever_m, dtype=np.float64)[keys]
    return speeds


def speed_to_velocity(speed_m_s: np.ndarray | float) -> np.ndarray:
    """MIDI velocity 1..127 of a key speed: 1 + 126 * clip(log(v / soft) / log(loud / soft)).

    Monotone (non-decreasing) in the speed; NaN or non-positive speeds give 1.

    Args:
        speed_m_s: key speeds, m/s, any shape.
    Returns:
        int velocities of the same shape.
    """
    speed = np.asarray(speed_m_s, dtype=np.float64)
    safe = np.where(np.isfinite(speed) & (speed > 0), speed, SOFTEST_SPEED_M_S)
    x = np.log(safe / SOFTEST_SPEED_M_S) / math.log(LOUDEST_SPEED_M_S / SOFTEST_SPEED_M_S)
    return (1 + np.round(126 * np.clip(x, 0.0, 1.0))).astype(int)


def episode_velocities(episode: Any, scene: Any) -> np.ndarray:
    """MIDI velocity of every note event of ``episode`` (0 for key-off and pedal rows).

    Args:
        episode: a :class:`pianist.eval.Episode` with ``qpos``.
        scene: the :class:`pianist.sim.scene.Scene` it was played in (key addresses).
    Returns:
        (n,) ints, aligned with ``episode.note_events``.
    """
    events = np.asarray(episode.note_events, dtype=np.float64).reshape(-1, 3)
    if episode.qpos is None:
        raise ValueError("the episode has no joint positions (qpos) to measure key speeds")
    angles = np.asarray(episode.qpos)[:, np.asarray(scene.key_qpos)]
    threshold = np.asarray(scene.key_max_angle_rad) - C.KEY_ACTIVATION_THRESHOLD_RAD
    speeds = strike_speeds(events, angles, episode.control_timestep_s, threshold)
    return np.where(np.isnan(speeds), 0, speed_to_velocity(speeds))


def with_velocities(performance: Song, note_events: np.ndarray, velocities: np.ndarray) -> Song:
    """``performance`` (from ``Episode.performance()``) with each note's velocity set from the
    key-on event that started it (same key and time)."""
    events = np.asarray(note_events, dtype=np.float64).reshape(-1, 3)
    by_start: dict[tuple[int, float], int] = {}
    for (time_s, key, on), velocity in zip(
        events.tolist(), np.asarray(velocities).tolist(), strict=True
    ):
        if key >= 0 and on:
            by_start.setdefault((int(key) + C.LOWEST_MIDI_PITCH, time_s), int(velocity))
    notes = tuple(
        dataclasses.replace(n, velocity=by_start.get((n.pitch, n.onset_s), n.velocity))
        for n in performance.notes
    )
    return dataclasses.replace(performance, notes=notes)


def match_notes(
    performance: Song, score: Song, early_s: float = MATCH_EARLY_S
) -> list[tuple[Note, Note]]:
    """Pairs (performance note, score note), one to one: same pitch, and the performance note
    starts while the score note is due (from ``early_s`` before its onset to its offset). The
    closest onsets are paired first (ties: the earlier performance note first)."""
    candidates = []
    by_pitch: dict[int, list[int]] = {}
    for j, note in enumerate(score.notes):
        by_pitch.setdefault(note.pitch, []).append(j)
    for i, note in enumerate(performance.notes):
        for j in by_pitch.get(note.pitch, []):
            due = score.notes[j]
            if due.onset_s - early_s <= note.onset_s < due.offset_s:
                candidates.append((abs(note.onset_s - due.onset_s), note.onset_s, i, j))
    used_p: set[int] = set()
    used_s: set[int] = set()
    pairs = []
    for _, _, i, j in sorted(candidates):
        if i not in used_p and j not in used_s:
            used_p.add(i)
            used_s.add(j)
            pairs.append((performance.notes[i], score.notes[j]))
    return pairs


def velocity_metrics(performance: Song, score: Song) -> dict[str, float | int | None]:
    """velocity_mae: mean |performance velocity - score velocity| over the matched notes
    (:func:`match_notes`), MIDI velocity units, None when no note matched;
    velocity_rank_correlation: Spearman's rank correlation of the performed velocities with
    the score's over the matched notes (1: louder where the score is louder), None with fewer
    than three matched notes or one velocity throughout either;
    velocity_matched_notes: how many matched; velocity_mean: the performance's mean velocity
    (None without notes)."""
    pairs = match_notes(performance, score)
    mae = float(np.mean([abs(p.velocity - s.velocity) for p, s in pairs])) if pairs else None
    mean = float(np.mean([n.velocity for n in performance.notes])) if performance.notes else None
    return {
        "velocity_mae": mae,
        "velocity_rank_correlation": rank_correlation(
            [p.velocity for p, _ in pairs], [s.velocity for _, s in pairs]
        ),
        "velocity_matched_notes": len(pairs),
        "velocity_mean": mean,
    }


def rank_correlation(a: Sequence[float], b: Sequence[float]) -> float | None:
    """Spearman's rank correlation of ``a`` and ``b`` (ties get their mean rank), or None
    with fewer than three pairs or when either is constant (no ranking to compare)."""
    if len(a) != len(b):
        raise ValueError(f"rank correlation of {len(a)} against {len(b)} values")
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return None
    from scipy.stats import rankdata

    ra, rb = rankdata(a), rankdata(b)
    return float(np.corrcoef(ra, rb)[0, 1])
