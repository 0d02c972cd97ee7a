"""A score's measures in the order they are played, and what each holds at what time."""

from __future__ import annotations

import re
import warnings
from collections import Counter
from pathlib import Path
from typing import Any, Literal, NamedTuple

from pianist.music.musicxml.humdrum import SectionOrder
from pianist.music.repeats import Bar, RepeatError, playing_order


class Playing(NamedTuple):
    """One playing of a measure: the measure (music21) and where it starts as played, in
    quarter lengths from the piece's start."""

    measure: Any
    start: float


def played_measures(
    parts: list[Any], expand: bool, path: Path, sections: SectionOrder | None = None
) -> list[list[Playing]]:
    """Per part, its measures in the order they are played, each with its start as played.

    With ``expand`` the order is a Humdrum score's ``sections`` where it has them (and music21
    gives the measures they count), else it follows the repeats
    (:func:`pianist.music.repeats.playing_order`); without ``expand``, or where the marks give
    no order (then with a warning), the score is played once as written. The parts start each
    measure together (:func:`_measure_lengths`). A score whose parts have different numbers of
    measures is played part by part as music21 lays it out, and a part without measures as
    one measure."""
    measures = [list(part.getElementsByClass("Measure")) for part in parts]
    if any(not ms for ms in measures) or len({len(ms) for ms in measures}) != 1:
        if expand and all(measures) and _has_repeat_marks(measures):
            warnings.warn(
                f"{path}: its repeats could not be expanded (its parts have different numbers "
                "of measures); played once as written",
                stacklevel=3,
            )
        return [
            [Playing(m, float(m.offset)) for m in ms] if ms else [Playing(part, 0.0)]
            for ms, part in zip(measures, parts, strict=True)
        ]
    order = list(range(len(measures[0])))
    if expand and sections is not None and sections.total == len(order):
        order = sections.measures
    elif expand:
        if sections is not None:
            warnings.warn(
                f"{path}: its sections' order could not be followed (music21 read "
                f"{len(order)} measures where the score has {sections.total}); its repeat "
                "signs are played",
                stacklevel=3,
            )
        try:
            order = playing_order(_bars(measures))
        except RepeatError as exc:
            warnings.warn(
                f"{path}: its repeats could not be expanded ({exc}); played once as written",
                stacklevel=3,
            )
    lengths = _measure_lengths(measures)
    starts = [0.0]
    for index in order[:-1]:
        starts.append(starts[-1] + lengths[index])
    return [
        [Playing(ms[i], start) for i, start in zip(order, starts, strict=True)] for ms in measures
    ]


def _has_repeat_marks(measures: list[list[Any]]) -> bool:
    """Whether any measure holds a repeat sign, an ending's bracket or a jump mark."""
    from music21 import bar

    for m in (m for ms in measures for m in ms):
        if isinstance(m.leftBarline, bar.Repeat) or isinstance(m.rightBarline, bar.Repeat):
            return True
        if any(type(s).__name__ == "RepeatBracket" for s in m.getSpannerSites()):
            return True
        if m.recurse().getElementsByClass("RepeatExpression"):
            return True
    return False


def _measure_lengths(measures: list[list[Any]]) -> list[float]:
    """Each measure's length in quarter lengths, the same for every part: the length most
    parts give it (the longest of equally common ones), each part's measure reaching to its
    next one's start, the last one its own duration. A measure that one part's file leaves
    short or overfull (a quartet's "measure 96 in Violin II is overfull") then does not shift
    that part against the others for the rest of the piece, as music21's layout does."""
    per_part = []
    for ms in measures:
        pairs = zip(ms[:-1], ms[1:], strict=True)
        lengths = [max(0.0, float(b.offset) - float(a.offset)) for a, b in pairs]
        per_part.append([*lengths, float(ms[-1].duration.quarterLength)])
    consensus = []
    for column in zip(*per_part, strict=True):
        counts = Counter(round(length, 6) for length in column)
        consensus.append(max(counts.items(), key=lambda item: (item[1], item[0]))[0])
    return consensus


def _bars(measures: list[list[Any]]) -> list[Bar]:
    """What each measure's marks say about the order of playing, over all parts (a mark in any
    part counts: scores often write a da capo or a segno over the top staff only)."""
    from music21 import bar

    count = len(measures[0])
    endings = _ending_numbers(measures)
    marks = [
        [e for ms in measures for e in ms[i].recurse().getElementsByClass("RepeatExpression")]
        for i in range(count)
    ]
    kinds = [{type(e).__name__ for e in column} for column in marks]
    to_coda = [any(_is_to_coda(e) for e in column) for column in marks]
    coda = [
        any(type(e).__name__ == "Coda" and not _is_to_coda(e) for e in column) for column in marks
    ]
    if not any(to_coda) and sum(coda) >= 2:  # two coda signs: the first is where to leave
        first = coda.index(True)
        to_coda[first], coda[first] = True, False
    movements = _new_movements(measures[0])
    bars = []
    for i in range(count):
        column = [ms[i] for ms in measures]
        ends = [
            m.rightBarline
            for m in column
            if isinstance(m.rightBarline, bar.Repeat) and m.rightBarline.direction == "end"
        ]
        jump, jump_to = _JUMPS.get(next(iter(sorted(kinds[i] & set(_JUMPS))), ""), (None, None))
        bars.append(
            Bar(
                start_repeat=any(
                    isinstance(m.leftBarline, bar.Repeat) and m.leftBarline.direction == "start"
                    for m in column
                ),
                end_repeat=bool(ends),
                times=max((int(r.times) for r in ends if r.times), default=None),
                ending=endings[i],
                segno="Segno" in kinds[i],
                coda=coda[i],
                to_coda=to_coda[i],
                fine="Fine" in kinds[i],
                jump=jump,
                jump_to=jump_to,
                new_movement=movements[i],
            )
        )
    return bars


def _new_movements(measures: list[Any]) -> list[bool]:
    """Per measure, whether it starts a new movement: both its time and its key signature
    change there (a trio or a middle section rarely changes both; a file holding a quartet's
    movements does at each, and often nothing else marks them)."""
    starts = [False] * len(measures)
    meter, key = None, None
    for i, measure in enumerate(measures):
        meters = measure.getElementsByClass("TimeSignature")
        keys = measure.getElementsByClass("KeySignature")
        new_meter = meters[0].ratioString if meters else meter
        new_key = keys[0].sharps if keys else key
        starts[i] = i > 0 and new_meter != meter and new_key != key
        meter, key = new_meter, new_key
    return starts


#: music21's jump marks: (where the jump goes, where it goes on to).
_JUMPS: dict[str, tuple[Literal["capo", "segno"], Literal["fine", "coda"] | None]] = {
    "DaCapo": ("capo", None),
    "DaCapoAlFine": ("capo", "fine"),
    "DaCapoAlCoda": ("capo", "coda"),
    "DalSegno": ("segno", None),
    "DalSegnoAlFine": ("segno", "fine"),
    "DalSegnoAlCoda": ("segno", "coda"),
}


def _is_to_coda(mark: Any) -> bool:
    """Whether a music21 ``Coda`` mark is a to-coda mark (its text "To Coda" or "al Coda"),
    not the coda's own sign."""
    if type(mark).__name__ != "Coda":
        return False
    text = str(mark.getText() or "").strip().lower()
    return text.startswith(("to", "al"))


def _ending_numbers(measures: list[list[Any]]) -> list[frozenset[int]]:
    """Per measure, the numbers of the ending bracket over it (in any part). A bracket without
    a number, or numbered as an ending before it in the same run (the file's slip), is the next
    ending of its run: music21's own expansion refuses such scores."""
    numbers: list[set[int]] = [set() for _ in measures[0]]
    for ms in measures:
        index = {id(m): i for i, m in enumerate(ms)}
        brackets = {
            id(s): s for m in ms for s in m.getSpannerSites() if type(s).__name__ == "RepeatBracket"
        }
        spans = []
        for bracket in brackets.values():
            covered = [index[id(m)] for m in bracket.getSpannedElements() if id(m) in index]
            if covered:
                spans.append((min(covered), max(covered), list(bracket.numberRange)))
        last, highest = -2, 0
        for first, final, listed in sorted(spans, key=lambda s: (s[0], s[1])):
            before = highest if first == last + 1 else 0  # the run's endings so far
            wanted = [n for n in listed if n > before]
            if not wanted or len(wanted) < len(listed):
                wanted = [before + 1]
            for i in range(first, final + 1):
                numbers[i].update(wanted)
            last, highest = final, max(wanted)
    return [frozenset(n) for n in numbers]


class Event(NamedTuple):
    """What a measure holds at a time: its offset in the measure (quarter lengths), the
    music21 element, its voice, its kind ("note" for a note or chord, "other" for a rest or a
    pedal change, "tempo" for a tempo indication, "tempo words" for words that name a tempo,
    "dynamic"), and the ``id`` of the element a pedal mark names for it (music21 gives the
    staves of a grand staff copies of a pedal change, derived from the one the mark holds)."""

    offset: float
    element: Any
    voice: str | None
    kind: EventKind
    source: int


EventKind = Literal["note", "other", "tempo", "tempo words", "dynamic"]


def measure_events(measure: Any) -> list[Event]:
    """A measure's notes, chords, rests, pedal changes, tempo indications (words that name a
    tempo as the metronome mark they stand for) and dynamics, in time order (through its
    voices). Chord symbols (a lead sheet's "Am7", music21's ``Harmony``) are not notes: music21
    gives them as chords of no length, which would play as grace notes."""
    from music21 import tempo

    voice_of = {id(e): _voice(e) for e in measure.recurse().notes}  # before flattening
    flat = measure.flatten()  # its offsets are the measure's
    notes = {id(e) for e in flat.notes}
    classes = ("GeneralNote", "PedalBounce", "TempoIndication", "Dynamic", "TextExpression")
    events = []
    for e in flat.getElementsByClass(classes):
        if "Harmony" in e.classes:
            continue  # a chord symbol names a chord for an accompanist; it writes no notes
        kind: EventKind = (
            "note"
            if id(e) in notes
            else "tempo"
            if "TempoIndication" in e.classes
            else "dynamic"
            if "Dynamic" in e.classes
            else "tempo words"
            if "TextExpression" in e.classes
            else "other"
        )
        if kind == "tempo words":
            bpm = words_bpm(str(e.content))
            if bpm is None:
                continue  # words that name no tempo ("dolce", "a tempo", "rit.")
            named = tempo.MetronomeMark(number=bpm, referent=1.0)  # the tempo they name
            events.append(Event(float(e.offset), named, None, kind, id(e)))
            continue
        source = id(e.derivation.rootDerivation or e)
        events.append(Event(float(e.offset), e, voice_of.get(id(e)), kind, source))
    return events


def _voice(element: Any) -> str | None:
    """The id of the voice a note lies in within its measure (None outside voices)."""
    site = element.activeSite
    return str(site.id) if type(site).__name__ == "Voice" else None


#: Words that change the tempo against the one before ("più", "piu", "meno"), not name one.
_RELATIVE_TEMPO = re.compile(r"\b(più|piu|meno)\b", re.IGNORECASE)


def words_bpm(words: str) -> float | None:
    """The tempo, in quarter notes per minute, that a text expression's words name: "Allegro
    ma non troppo" gives music21's value for Allegro, 132; None for words that name none, or
    only a change ("poco più lento", "meno mosso": music21 would read the first as Lento).
    The value counts quarter notes in every metre, as music21's table does: in alla breve,
    fast words then read slower than they are played (Presto in 2/2 at quarter = 184 is
    half = 92), where counting half notes would read them twice as fast (half = 184)."""
    from music21 import tempo

    if _RELATIVE_TEMPO.search(words):
        return None
    bpm = tempo.MetronomeMark(text=words).getQuarterBPM()
    return None if bpm is None else float(bpm)
