"""What the marks on one note or chord say: its ornament's notes, its roll, its articulation,
its ties and its finger numbers (music21 elements in, quarter lengths out)."""

from __future__ import annotations

from collections import Counter
from typing import Any

from pianist.music.ornaments import (
    Played,
    grace_length,
    mordent,
    roll_starts,
    tremolo,
    trill,
    turn,
)

#: The ornaments the reader plays: music21's class, and the name
#: :class:`~pianist.music.musicxml.ScoreSummary` gives.
_ORNAMENT_KINDS = {
    "Trill": "trills",
    "GeneralMordent": "mordents",
    "Turn": "turns",
    "Tremolo": "tremolos",
}


def is_trill(element: Any) -> bool:
    """Whether a single note carries a trill sign as its first ornament."""
    for mark in element.expressions:
        if {"Trill", "GeneralMordent", "Turn", "Tremolo"} & set(mark.classes):
            return "Trill" in mark.classes and len(element.pitches) == 1
    return False


def grace_note_sounds(
    graces: list[Any], length: float, unit: float, shortest: float
) -> list[Played]:
    """The notes of the grace notes (music21 notes or chords) before a note of ``length``
    quarter lengths, from its onset, each :func:`pianist.music.ornaments.grace_length` long;
    none where that is shorter than ``shortest`` (too quick to show)."""
    if not graces or grace_length(len(graces), length, unit) < shortest - 1e-9:
        return []
    each = grace_length(len(graces), length, unit)
    return [(p.midi, k * each, (k + 1) * each) for k, g in enumerate(graces) for p in g.pitches]


def tremolo_pair_of(element: Any) -> Any | None:
    """The two-note tremolo (music21 ``TremoloSpanner``) a note or chord is one of the two
    notes of; None for any other."""
    for spanner in element.getSpannerSites():
        if "TremoloSpanner" in spanner.classes and len(spanner.getSpannedElements()) == 2:
            return spanner
    return None


def articulation_of(element: Any) -> tuple[float, int]:
    """The fraction of its written length a note or chord sounds, and the velocity its marks
    add: music21's length and volume shift of each articulation mark (staccato 0.7 of the
    length and +6 velocity, staccatissimo 0.5, accent +13, strong accent +19; tenuto's 1.1
    is kept at the written length, so a note does not overlap the next)."""
    fraction, volume = 1.0, 0.0
    for mark in element.articulations:
        fraction *= min(1.0, float(getattr(mark, "lengthShift", 1.0)))
        volume += float(getattr(mark, "volumeShift", 0.0))
    return fraction, round(volume * 127)


def sounding_length(length: float, fraction: float, shortest: float) -> float:
    """How long a note of ``length`` (quarter lengths) sounds when its articulation keeps
    ``fraction`` of it: never shorter than ``shortest`` (one goal frame) unless written so."""
    return max(length * fraction, min(length, shortest))


def ornament_sounds(element: Any, pitch: int, length: float, unit: float) -> list[Played] | None:
    """The notes that ``pitch`` of a note or chord plays for the element's first ornament
    (:mod:`pianist.music.ornaments`) over ``length`` quarter lengths at the pace ``unit``: a
    single-note tremolo's repetitions (each pitch of a chord repeated), or a single note's trill,
    mordent or turn; None where there is none, on a chord's other ornaments, or on a mark
    music21 cannot resolve (the written note is played)."""
    for mark in element.expressions:
        classes = set(mark.classes)
        if "Tremolo" in classes:
            return tremolo(pitch, length, int(mark.numberOfMarks), unit)
        if not classes & {"Trill", "GeneralMordent", "Turn"} or len(element.pitches) != 1:
            continue
        try:
            mark.resolveOrnamentalPitches(element)  # the key's and the sign's accidentals
            others = [p.midi for p in mark.ornamentalPitches]
        except Exception:  # music21 raises many types on marks it cannot resolve
            return None
        if "Trill" in classes and others:
            return trill(pitch, others[0], length, unit)
        if "GeneralMordent" in classes and others:
            return mordent(pitch, others[0], length, unit)
        if "Turn" in classes and len(others) == 2:
            upper, lower = others
            first, second = (lower, upper) if "InvertedTurn" in classes else (upper, lower)
            delayed = str(mark.delay) != "noDelay"
            return turn(pitch, first, second, length, unit, delayed=delayed)
    return None


def roll_delays(element: Any, length: float, step: float) -> dict[int, float]:
    """When each pitch of a rolled chord starts after its onset, in quarter lengths
    (:func:`pianist.music.ornaments.roll_starts`: from the lowest of the roll's pitches, or
    the highest for a downward roll, ``step`` apart); empty for a note or chord not rolled
    (:func:`roll_of`)."""
    roll = roll_of(element)
    if roll is None:
        return {}
    down, pitches = roll
    order = sorted(set(pitches), reverse=down)
    return dict(zip(order, roll_starts(len(order), length, step), strict=True))


def roll_of(element: Any) -> tuple[bool, list[int]] | None:
    """A rolled chord's direction (True: downwards) and every pitch its roll spans: a roll
    across both staves (music21's ``ArpeggioMarkSpanner``) spans the notes and chords of
    both, an arpeggio sign on one chord that chord's. None for a note or chord not rolled,
    or under the bracket that says not to roll it."""
    for spanner in element.getSpannerSites():
        if "ArpeggioMarkSpanner" in spanner.classes and spanner.type != "non-arpeggio":
            spanned = spanner.getSpannedElements()
            return spanner.type == "down", [p.midi for e in spanned for p in e.pitches]
    if len(element.pitches) > 1:
        for mark in element.expressions:
            if "ArpeggioMark" in mark.classes and mark.type != "non-arpeggio":
                return mark.type == "down", [p.midi for p in element.pitches]
    return None


def ornament_counts(score: Any) -> dict[str, int]:
    """How many of each ornament of the kinds the reader plays a parsed score writes, by the
    name :class:`~pianist.music.musicxml.reader.ScoreSummary` gives it; only those present."""
    counts: Counter[str] = Counter()
    for element in score.recurse().notes:
        if "Harmony" in element.classes:
            continue  # a chord symbol, not a note
        if element.duration.isGrace:
            counts["grace notes"] += 1
        if roll_of(element) is not None:
            counts["rolled chords"] += 1
        pair = tremolo_pair_of(element)
        if pair is not None and pair.getFirst() is element:
            counts["tremolos"] += 1
        for mark in element.expressions:
            kind = next((k for k in _ORNAMENT_KINDS if k in mark.classes), None)
            if kind is not None and (kind == "Tremolo" or len(element.pitches) == 1):
                counts[_ORNAMENT_KINDS[kind]] += 1
                break  # the first ornament is the one played
    return dict(counts)


def tie_types(element: Any, count: int) -> list[str | None]:
    """The tie type ("start", "continue", "stop" or None) of each pitch of a note or chord."""
    if hasattr(element, "notes") and len(element.notes) == count:  # a chord: per pitch
        return [n.tie.type if n.tie is not None else None for n in element.notes]
    tie = element.tie.type if element.tie is not None else None
    return [tie] * count


def finger_numbers(element: Any) -> list[int | None]:
    """The finger numbers (1-5) of a note's or chord's fingering marks, in order; None for a
    mark that is not one."""
    numbers: list[int | None] = []
    for mark in element.articulations:
        if type(mark).__name__ != "Fingering":
            continue
        text = str(mark.fingerNumber).strip()
        first = text[:1]  # "4-3", a substitution: the finger that strikes
        numbers.append(int(first) if first and first in "12345" else None)
    return numbers
