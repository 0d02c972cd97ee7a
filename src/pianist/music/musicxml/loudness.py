"""How loud a score's notes are: its dynamics marks, accents and hairpins, per staff group."""

from __future__ import annotations

import bisect
from collections.abc import Callable
from typing import Any

from pianist.music.musicxml.measures import Event, Playing

#: Velocity of a note whose score gives none.
DEFAULT_VELOCITY = 80


#: Dynamics that accent the notes they fall on, and the level they leave after them (None: the
#: level before them goes on; "fp": loud, then soft).
_ACCENTS: dict[str, str | None] = {
    **dict.fromkeys(("sf", "sfz", "sffz", "fz", "rf", "rfz")),
    "fp": "p",
    "sfp": "p",
}


def part_loudness(
    played: list[list[Playing]], parts: list[Any], events: dict[int, list[Event]]
) -> list[Callable[[float], int | None]]:
    """Per part, the velocity (1-127) its dynamics give a note at a time as played (quarter
    lengths): an accent (sf, fz, ...) on the note's own time, else the last level (pp, mf,
    ...) at or before it, or on a crescendo or diminuendo hairpin the way from one level to
    the next (:func:`_loudness_of`); None before the first. music21's loudness of each mark
    (p 0.35, f 0.7 of full) scales 127. The two staves of a grand staff share their marks: a
    mark printed between them belongs to both."""
    from music21 import dynamics

    marks: dict[str, list[tuple[float, int, bool]]] = {}  # staff group -> (time, velocity, accent)
    ramps: dict[str, list[tuple[float, float, bool]]] = {}  # group -> (start, end, louder)
    for measures, part in zip(played, parts, strict=True):
        group = marks.setdefault(_staff_group(part), [])
        hairpins = ramps.setdefault(_staff_group(part), [])
        started: dict[int, float] = {}  # a hairpin -> when its first note is played
        for measure, start in measures:
            for event in events[id(measure)]:
                if event.kind == "note":
                    at = start + event.offset
                    for wedge in event.element.getSpannerSites():
                        if "DynamicWedge" not in wedge.classes:
                            continue
                        if wedge.getFirst() is event.element:
                            started[id(wedge)] = at
                        if wedge.getLast() is event.element and id(wedge) in started:
                            end = at + float(event.element.duration.quarterLength)
                            louder = "Crescendo" in wedge.classes
                            hairpins.append((started.pop(id(wedge)), end, louder))
                scalar = event.element.volumeScalar if event.kind == "dynamic" else None
                if scalar is None or not scalar > 0:
                    continue
                at, value = start + event.offset, str(event.element.value)
                group.append((at, _velocity(scalar), value in _ACCENTS))
                after = _ACCENTS.get(value)
                if after is not None:
                    group.append((at, _velocity(dynamics.Dynamic(after).volumeScalar), False))
    return [_loudness_of(marks[_staff_group(part)], ramps[_staff_group(part)]) for part in parts]


def _velocity(scalar: float) -> int:
    """A MIDI velocity from music21's loudness scalar (0-1)."""
    return max(1, min(127, round(127 * float(scalar))))


def _staff_group(part: Any) -> str:
    """The part's instrument: music21 names the staves of one grand staff "P1-Staff1",
    "P1-Staff2"."""
    return str(part.id).split("-Staff")[0] if type(part).__name__ == "PartStaff" else str(id(part))


#: How much a crescendo or diminuendo hairpin changes the velocity when no level mark after it
#: says (music21's levels are about 0.1 of full apart: mp 0.5, mf 0.55, f 0.7).
HAIRPIN_STEP = 13


def _loudness_of(
    marks: list[tuple[float, int, bool]], ramps: list[tuple[float, float, bool]]
) -> Callable[[float], int | None]:
    """The lookup :func:`part_loudness` returns for one staff group's marks (time, velocity,
    accent) and hairpins (start, end in quarter lengths as played, crescendo or not). A
    hairpin goes linearly, over its notes' time, from the level at its start (80 before any)
    to the level marked within a quarter note of its end; where no mark there goes its way,
    to :data:`HAIRPIN_STEP` louder or softer, which stays the level after it."""
    levels = sorted((at, velocity) for at, velocity, accent in marks if not accent)
    accents = {round(at, 6): velocity for at, velocity, accent in marks if accent}

    def level(ql: float) -> int | None:
        k = bisect.bisect_right([at for at, _ in levels], ql + 1e-9) - 1
        return levels[k][1] if k >= 0 else None

    ways: list[tuple[float, float, int, int]] = []  # (start, end, velocity at each)
    for begin, end, louder in sorted(ramps):
        first = level(begin) or DEFAULT_VELOCITY
        marked = [v for at, v in levels if abs(at - end) <= 1.0 + 1e-9]
        goes_its_way = [v for v in marked if (v > first if louder else v < first)]
        if goes_its_way:
            last = goes_its_way[0]
        else:
            last = max(1, min(127, first + (HAIRPIN_STEP if louder else -HAIRPIN_STEP)))
            bisect.insort(levels, (end, last))  # the hairpin's level goes on after it
        ways.append((begin, end, first, last))
    times = [at for at, _ in levels]
    starts = [begin for begin, _, _, _ in ways]

    def loudness(ql: float) -> int | None:
        if round(ql, 6) in accents:
            return accents[round(ql, 6)]
        k = bisect.bisect_right(starts, ql + 1e-9) - 1
        if k >= 0 and ql < ways[k][1]:
            begin, end, first, last = ways[k]
            return round(first + (last - first) * (ql - begin) / (end - begin))
        k = bisect.bisect_right(times, ql + 1e-9) - 1
        return levels[k][1] if k >= 0 else None

    return loudness
