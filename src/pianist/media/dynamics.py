"""Note velocities of a performance, and how far they are from the score's.

Each played note's velocity is its key's strike speed mapped to MIDI velocity
(:mod:`pianist.env.loudness`, the same estimate the environment's ``velocity`` reward term
uses), measured from the key angles the episode records once per control step
(``Episode.qpos``) and the substep at which each key started sounding
(``Episode.note_events``). :func:`velocity_metrics` matches performed notes to the score's
(same pitch, onset within a tolerance) and reports the mean absolute difference and the rank
correlation of their velocities.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from pianist.env.loudness import (
    KEY_LEVER_M,
    LOUDEST_SPEED_M_S,
    SOFTEST_SPEED_M_S,
    speed_to_velocity,
    strike_speeds,
)
from pianist.music import Note, Song
from pianist.sim import constants as C

__all__ = [
    "KEY_LEVER_M",
    "LOUDEST_SPEED_M_S",
    "MATCH_EARLY_S",
    "SOFTEST_SPEED_M_S",
    "episode_velocities",
    "match_notes",
    "rank_correlation",
    "speed_to_velocity",
    "strike_speeds",
    "velocity_metrics",
    "with_velocities",
]

#: A performance note may start this much before the score note it matches (the goal is
#: quantised to control steps, and the planner aims a little early).
MATCH_EARLY_S = 0.1


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
