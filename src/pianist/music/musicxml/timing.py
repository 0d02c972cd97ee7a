"""When a score's notes are played, in seconds: its metronome marks, the words that name a
tempo, and fermatas (all in quarter lengths as played)."""

from __future__ import annotations

import bisect
from collections.abc import Callable
from typing import Any

from pianist.music.musicxml.measures import Event, Playing

#: Quarter notes per minute before a score's first metronome mark (music21's default).
DEFAULT_QUARTER_BPM = 120.0


def seconds_of_offsets(score: Any, quarter_bpm: float | None = None) -> Callable[[float], float]:
    """The map from a music21 offset (in quarter lengths from the score's start) to seconds:
    through the score's metronome marks, or at ``quarter_bpm`` throughout when given."""
    if quarter_bpm is not None:
        return lambda ql: float(ql) * 60.0 / quarter_bpm
    boundaries = score.metronomeMarkBoundaries()
    return _seconds_through([(float(start), mark.getQuarterBPM()) for start, _, mark in boundaries])


def seconds_per_quarter(seconds: Callable[[float], float], ql: float) -> float:
    """The tempo at ``ql`` (quarter lengths as played) as seconds per quarter length."""
    return (seconds(ql + 1e-3) - seconds(ql)) / 1e-3


def tempo_map(
    played: list[list[Playing]], events: dict[int, list[Event]], fermatas: bool
) -> Callable[[float], float]:
    """The map from a time as played (quarter lengths from the start) to seconds, through the
    metronome marks (and other tempo indications) of every part as played: quarter = 120
    before the first (music21's default), and a mark without a number keeps the tempo before
    it. Of marks at one time the last part's holds. Words that name a tempo without a mark
    ("Allegro", "Langsam": :func:`~pianist.music.musicxml.measures.words_bpm`) set it where
    no mark does at their time. With ``fermatas``, the time under a fermata in any part is
    held longer (:func:`_held`)."""
    marks: list[tuple[float, float | None]] = []
    words: list[tuple[float, float | None]] = []
    holds: list[tuple[float, float]] = []
    for measures in played:
        for measure, start in measures:
            for event in events[id(measure)]:
                at = start + event.offset
                if event.kind == "tempo":
                    bpm = event.element.getSoundingMetronomeMark().getQuarterBPM()
                    marks.append((at, bpm))
                elif event.kind == "tempo words":
                    words.append((at, event.element.getQuarterBPM()))
                elif fermatas and any(
                    "Fermata" in mark.classes for mark in getattr(event.element, "expressions", ())
                ):
                    holds.append((at, at + float(event.element.duration.quarterLength)))
    seconds = _seconds_through(words + marks)  # at one time the later (a mark) holds
    return _held(seconds, holds) if holds else seconds


#: How much longer than written a note or rest under a fermata lasts (a pianist holds one
#: about twice its value), and the most it adds, in seconds (a final whole note is not held
#: for twice its length at a slow tempo).
FERMATA_HOLD = 2.0


FERMATA_MAX_EXTRA_S = 2.0


def _held(
    seconds: Callable[[float], float], holds: list[tuple[float, float]]
) -> Callable[[float], float]:
    """``seconds`` (quarter lengths to seconds) with the time inside each hold (start, end in
    quarter lengths; overlapping ones, the parts' fermatas over one chord, joined) stretched
    :data:`FERMATA_HOLD` times, adding at most :data:`FERMATA_MAX_EXTRA_S` each."""
    joined: list[list[float]] = []
    for begin, end in sorted(holds):
        if joined and begin <= joined[-1][1]:
            joined[-1][1] = max(joined[-1][1], end)
        elif end > begin:
            joined.append([begin, end])
    starts = [begin for begin, _ in joined]
    stretch, before = [], [0.0]  # per hold: the factor on its time; extra seconds before it
    for begin, end in joined:
        written = seconds(end) - seconds(begin)
        extra = min((FERMATA_HOLD - 1.0) * written, FERMATA_MAX_EXTRA_S)
        stretch.append(extra / written if written > 0 else 0.0)
        before.append(before[-1] + extra)

    def held(ql: float) -> float:
        k = bisect.bisect_right(starts, ql) - 1
        if k < 0:
            return seconds(ql)
        begin, end = joined[k]
        inside = seconds(min(ql, end)) - seconds(begin)
        return seconds(ql) + before[k] + stretch[k] * inside

    return held


def _seconds_through(changes: list[tuple[float, float | None]]) -> Callable[[float], float]:
    """The map from quarter lengths to seconds through tempo changes (time in quarter
    lengths, quarter notes per minute): quarter = 120 before the first, a change without a
    number keeps the tempo before it, and of changes at one time the last holds."""
    starts, bpms = [0.0], [DEFAULT_QUARTER_BPM]
    for at, bpm in sorted(changes, key=lambda change: change[0]):
        if bpm is None or not bpm > 0:  # a mark without a number: the tempo goes on
            bpm = bpms[-1]
        if at <= starts[-1]:
            bpms[-1] = float(bpm)
        else:
            starts.append(at)
            bpms.append(float(bpm))
    elapsed = [0.0]  # seconds at each tempo's start
    for k in range(1, len(starts)):
        elapsed.append(elapsed[-1] + (starts[k] - starts[k - 1]) * 60.0 / bpms[k - 1])

    def seconds(ql: float) -> float:
        k = max(0, bisect.bisect_right(starts, ql) - 1)
        return elapsed[k] + (ql - starts[k]) * 60.0 / bpms[k]

    return seconds
