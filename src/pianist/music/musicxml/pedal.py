"""A score's sustain-pedal marks as the song's pedal intervals."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

#: How long the pedal is up at a pedal change inside a mark, in seconds: a quick change of a
#: pianist's foot. (The goal's 20 Hz frames show it as one frame up only where the change
#: falls on a frame's time; the score's audio always has it.)
PEDAL_CHANGE_S = 0.1


class PedalMark(NamedTuple):
    """A sustain-pedal mark as music21 parses it: its first and last note or chord, and the
    pedal changes (music21 ``PedalBounce`` objects) inside it."""

    first: Any
    last: Any
    changes: list[Any]


def sustain_marks(score: Any) -> list[PedalMark]:
    """The score's sustain-pedal marks: the first and last note or chord under each, and the
    pedal changes ("change": up and down again at once) inside it."""
    marks = []
    for mark in score.recurse().getElementsByClass("PedalMark"):
        kind = getattr(mark, "pedalType", None)
        if kind is not None and getattr(kind, "name", str(kind)) != "Sustain":
            continue  # the sostenuto and soft pedals do not hold the keys' notes
        under = mark.getSpannedElements()
        notes = [e for e in under if hasattr(e, "pitches")]  # not the gaps and changes
        changes = [e for e in under if type(e).__name__ == "PedalBounce"]
        if notes:
            marks.append(PedalMark(notes[0], notes[-1], changes))
    return marks


def pedal_intervals(
    marks: list[PedalMark],
    playings: dict[int, list[tuple[float, float]]],
    seconds: Callable[[float], float],
) -> tuple[tuple[float, float], ...]:
    """(start s, end s) of each sustain-pedal mark in the score as played, overlapping ones
    merged. ``playings`` holds each note's and pedal change's playings, (onset, end) in
    quarter lengths as played, by the element's ``id``: with the repeats expanded a note is
    played more than once, and the k-th playing of a mark's first note starts its k-th
    interval, the k-th playing of its last note ends it. A pedal change inside an interval
    lifts the pedal there for :data:`PEDAL_CHANGE_S`."""
    spans: list[tuple[float, float]] = []
    for mark in marks:
        starts = sorted(playings.get(id(mark.first), []))
        ends = sorted(playings.get(id(mark.last), []))
        lifts = sorted(
            seconds(onset) for change in mark.changes for onset, _ in playings.get(id(change), [])
        )
        for (onset, _), (_, end) in zip(starts, ends, strict=False):
            start_s, end_s = seconds(onset), seconds(end)
            for lift_s in lifts:
                if start_s < lift_s < end_s:
                    spans.append((round(start_s, 6), round(lift_s, 6)))
                    start_s = min(lift_s + PEDAL_CHANGE_S, end_s)
            if end_s > start_s:
                spans.append((round(start_s, 6), round(end_s, 6)))
    merged: list[list[float]] = []
    for start, end in sorted(spans):
        if merged and start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], end)
        else:
            merged.append([start, end])
    return tuple((start, end) for start, end in merged)
