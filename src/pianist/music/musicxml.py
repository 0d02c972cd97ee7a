"""Read MusicXML scores (``.musicxml``, ``.mxl``, ``.xml``) as :class:`~pianist.music.notes.Song`.

music21 parses the score (``pip install 'pianist[musicxml]'``); it is imported only when a
score is read. Reading conventions (a caller should know these):

- Every part's notes and chords are read; tied notes are joined, voice by voice and pitch by
  pitch (in a chord only its tied pitches go on; a tie does not bridge a rest); grace notes
  (no time of their own) are left out. Repeats are played as a performer plays them (music21
  expands repeat signs, first and second endings, da capo and dal segno; an end-repeat sign
  without a start goes back to just after the previous one); a score whose repeats music21
  cannot expand, or expands into a measure played more than :data:`MAX_PLAYINGS` times, is
  played once as written, with a warning.
- Times come from the score's metronome marks (quarter = 120 before the first one, music21's
  default; a mark without a number keeps the tempo before it). Velocities from the score's
  dynamics where music21 gives them, else 80.
- Sustain-pedal marks are the song's pedal intervals, each from the onset of the first note
  under the mark to the end of the last; a pedal change inside a mark (``<pedal
  type="change">``) lifts the pedal for :data:`PEDAL_CHANGE_S` there.
- The piano has one key per pitch: a unison between voices or staves is one note (the longest),
  and a note struck while its key still sounds ends the earlier one.
- Hands: a score of exactly two parts (a piano's grand staff, or any two staves) gives the upper
  staff to the right hand and the lower to the left; in a larger score with one grand staff
  (a song's voice above its piano part), that staff's two halves do, and the other parts'
  notes get theirs estimated. Other scores give no hands (they are estimated, as for a MIDI
  file).
- Fingering: the score's finger numbers (1-5, the first of a substitution such as "4-3") are
  kept on the notes whose hand is known; a chord's numbers go to its notes in order when there
  is one per note. Notes without one are fingered by ``--fingering auto``.
- Absurd scores are refused as MIDI files are: a timeline past one hour, no notes.
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal, NamedTuple

from pianist.music.errors import MusicError, one_line
from pianist.music.fileio import require_file
from pianist.music.midi import MAX_DURATION_S
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH, out_of_range_error

#: File suffixes read as MusicXML (``.mxl`` is the compressed form).
MUSICXML_SUFFIXES = (".musicxml", ".mxl", ".xml")
#: Quarter notes per minute before a score's first metronome mark (music21's default).
DEFAULT_QUARTER_BPM = 120.0
#: Velocity of a note whose score gives none.
DEFAULT_VELOCITY = 80

#: The most times a performer plays one measure: a repeated passage inside a part played
#: again, with its repeat, after a da capo. An expansion of the repeats past it is wrong.
MAX_PLAYINGS = 4

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


#: One note as read, before the voices are merged: (pitch, onset s, offset s, velocity, hand,
#: finger 0-9 or None).
RawNote = tuple[int, float, float, int, str | None, int | None]


def seconds_of_offsets(score: Any, quarter_bpm: float | None = None) -> Callable[[float], float]:
    """The map from a music21 offset (in quarter lengths from the score's start) to seconds:
    through the score's metronome marks, or at ``quarter_bpm`` throughout when given."""
    if quarter_bpm is not None:
        return lambda ql: float(ql) * 60.0 / quarter_bpm
    bounds: list[tuple[float, float, float]] = []
    before = DEFAULT_QUARTER_BPM
    for start, end, mark in score.metronomeMarkBoundaries():
        bpm = mark.getQuarterBPM()
        if bpm is None or not bpm > 0:  # a mark without a number: the tempo goes on
            bpm = before
        bounds.append((float(start), float(end), float(bpm)))
        before = bpm

    def seconds(ql: float) -> float:
        total = 0.0
        for start, end, bpm in bounds:
            if ql <= start:
                break
            total += (min(ql, end) - start) * 60.0 / bpm
        if ql > bounds[-1][1]:
            total += (ql - bounds[-1][1]) * 60.0 / bounds[-1][2]
        return total

    return seconds


def merge_voices(raw: Iterable[RawNote]) -> list[Note]:
    """Notes of several voices on one keyboard: a unison is one note (the longest; the first of
    equals keeps its hand and finger), a note struck while its key sounds ends the earlier one,
    and notes left without length are dropped."""
    ordered = sorted(raw, key=lambda r: (r[1], r[0], -r[2]))
    kept: list[list[Any]] = []
    last_of_pitch: dict[int, list[Any]] = {}
    for pitch, onset, offset, velocity, hand, finger in ordered:
        previous = last_of_pitch.get(pitch)
        if previous is not None and abs(previous[1] - onset) < 1e-9:
            continue  # unison: the first (longest) stays
        if previous is not None and previous[2] > onset:
            previous[2] = onset
        entry = [pitch, onset, offset, velocity, hand, finger]
        kept.append(entry)
        last_of_pitch[pitch] = entry
    return [
        Note(
            pitch,
            round(onset, 6),
            round(offset, 6),
            min(127, max(1, velocity)),
            finger=finger,
            hand=hand if finger is None else None,
        )
        for pitch, onset, offset, velocity, hand, finger in kept
        if offset - onset > 1e-6
    ]


def read_musicxml(
    path: str | os.PathLike[str],
    *,
    out_of_range: Literal["error", "drop"] = "error",
    expand_repeats: bool = True,
) -> Song:
    """Read a MusicXML score into a :class:`Song` (see the module docstring's conventions).

    Args:
        path: a ``.musicxml``, ``.mxl`` or ``.xml`` file.
        out_of_range: "error" raises :class:`OutOfRangeError` when any note lies outside MIDI
            21..108; "drop" leaves such notes out.
        expand_repeats: play the repeats (False: once through, as written).

    Raises:
        MusicError: music21 missing; a missing, unreadable or non-MusicXML file; a score
            music21 parses into a shape this reader cannot follow; no notes; a timeline
            longer than one hour.
        OutOfRangeError: notes outside the piano's keys with ``out_of_range="error"``.
    """
    if out_of_range not in ("error", "drop"):
        raise ValueError(f"out_of_range must be 'error' or 'drop', got {out_of_range!r}")
    path = Path(path)
    require_file(path, MusicError, "MusicXML file")
    try:
        from music21 import converter
    except ImportError:
        raise MusicError(
            f"{path}: reading MusicXML needs music21 (pip install 'pianist[musicxml]')"
        ) from None
    try:
        score = converter.parse(str(path), format="musicxml", forceSource=True)
    except Exception as exc:  # music21 raises many types for a file it cannot read
        raise MusicError(f"{path}: not a readable MusicXML score ({one_line(exc)})") from None
    with _as_music_error(path):
        pedals = _sustain_marks(score)  # before expanding: the marks point at the score's notes
    if expand_repeats:
        try:
            score = _expand_repeats(score)
        except Exception as exc:  # music21's expander refuses repeats it cannot make sense of
            warnings.warn(
                f"{path}: its repeats could not be expanded ({one_line(exc)}); played once "
                "as written",
                stacklevel=2,
            )
    parts = list(getattr(score, "parts", ())) or [score]
    raw: list[RawNote] = []
    with _as_music_error(path):
        seconds = seconds_of_offsets(score)
        for part, hand in zip(parts, _hands_of_parts(parts), strict=True):
            raw.extend(_part_notes(part, hand, seconds))
        sustain = _pedal_intervals(pedals, score, seconds)
    outside = [r for r in raw if not LOWEST_PITCH <= r[0] <= HIGHEST_PITCH]
    if outside and out_of_range == "error":
        raise out_of_range_error(path, [r[0] for r in outside])
    notes = merge_voices(r for r in raw if LOWEST_PITCH <= r[0] <= HIGHEST_PITCH)
    if not notes:
        unpitched = len(score.recurse().getElementsByClass("Unpitched"))
        raise MusicError(
            f"{path}: no notes"
            + (" in the piano's range" if outside else "")
            + (f" (only {unpitched} unpitched percussion note(s))" if unpitched else "")
        )
    end = max(n.offset_s for n in notes)
    if end > MAX_DURATION_S:
        raise MusicError(
            f"{path}: timeline longer than {MAX_DURATION_S / 3600:g} hour (reaches {end:.0f} s); "
            "refusing an absurd length"
        )
    return Song(notes=tuple(notes), sustain=sustain, name=path.stem)


@contextmanager
def _as_music_error(path: Path) -> Iterator[None]:
    """Turn a failure inside music21's parsed score into a :class:`MusicError` naming the
    file: music21 parses many files into shapes that no reader of it can foresee."""
    try:
        yield
    except MusicError:
        raise
    except Exception as exc:
        raise MusicError(
            f"{path}: a score this reader cannot follow ({type(exc).__name__}: {one_line(exc)})"
        ) from exc


def _expand_repeats(score: Any) -> Any:
    """The score as a performer plays it, its repeats expanded by music21, after the repeat
    starts that the notation leaves implied are written in (:func:`_imply_repeat_starts`).

    Raises:
        ValueError: the expansion plays a measure more than :data:`MAX_PLAYINGS` times, as
            music21 does where it goes back to a first movement's start from a later one.
    """
    _imply_repeat_starts(score)
    played = score.expandRepeats()
    parts = list(getattr(played, "parts", ())) or [played]
    measures = parts[0].getElementsByClass("Measure")
    counts = Counter(id(m.derivation.rootDerivation or m) for m in measures)
    most = max(counts.values(), default=0)
    if most > MAX_PLAYINGS:
        raise ValueError(f"they would play a measure {most} times")
    return played


def _imply_repeat_starts(score: Any) -> None:
    """Write in, part by part, the start-repeat sign that an end-repeat sign without one
    implies: a performer goes back to just after the previous end-repeat (past that repeat's
    endings), not to the piece's start as music21 does (which plays the first section once
    more at every later repeat)."""
    from music21 import bar

    for part in list(getattr(score, "parts", ())) or [score]:
        measures = list(part.getElementsByClass("Measure"))
        back_to: int | None = None  # where an unopened repeat goes back to; None: the start
        opened = False
        for index, measure in enumerate(measures):
            left, right = measure.leftBarline, measure.rightBarline
            if isinstance(left, bar.Repeat) and left.direction == "start":
                opened = True
            if not (isinstance(right, bar.Repeat) and right.direction == "end"):
                continue
            if not opened and back_to is not None and back_to <= index:
                measures[back_to].leftBarline = bar.Repeat(direction="start")
            opened = False
            back_to = index + 1
            while back_to < len(measures) and _in_an_ending(measures[back_to]):
                back_to += 1  # the second ending is played once, after the repeat


def _in_an_ending(measure: Any) -> bool:
    """Whether a measure lies under a first, second, ... ending's bracket."""
    return any(type(s).__name__ == "RepeatBracket" for s in measure.getSpannerSites())


def _sustain_marks(score: Any) -> list[PedalMark]:
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


def _pedal_intervals(
    marks: list[PedalMark], played: Any, seconds: Callable[[float], float]
) -> tuple[tuple[float, float], ...]:
    """(start s, end s) of each sustain-pedal mark in the score as played, overlapping ones
    merged. With the repeats expanded a note is played more than once: the k-th playing of a
    mark's first note starts its k-th interval, the k-th playing of its last note ends it.
    A pedal change inside an interval lifts the pedal there for :data:`PEDAL_CHANGE_S`."""
    playings: dict[int, list[tuple[float, float]]] = {}
    for element in played.recurse().getElementsByClass(("GeneralNote", "PedalBounce")):
        source = element.derivation.rootDerivation or element  # the score's own element
        onset = float(element.getOffsetInHierarchy(played))
        span = (onset, onset + float(element.duration.quarterLength))
        playings.setdefault(id(source), []).append(span)
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


def _hands_of_parts(parts: list[Any]) -> tuple[str | None, ...]:
    """The hand of each part: two parts are the right (upper) and left hand; otherwise the two
    staves of a grand staff, if the score has exactly one, and None for the rest."""
    if len(parts) == 2:
        return (RIGHT, LEFT)
    # music21 parses a part of two staves as two PartStaff parts, in staff order.
    staves = [part for part in parts if type(part).__name__ == "PartStaff"]
    if len(staves) != 2:
        return (None,) * len(parts)
    upper, lower = staves
    return tuple(RIGHT if p is upper else LEFT if p is lower else None for p in parts)


def _part_notes(part: Any, hand: str | None, seconds: Callable[[float], float]) -> list[RawNote]:
    """The notes of one part (a staff), ties joined, grace notes left out.

    Ties are joined here, voice by voice and pitch by pitch, in one pass over the part's notes
    in time order: music21's ``stripTies`` copies the part and searches its spanners for every
    note (14 s per part of a Beethoven quartet movement, against milliseconds here), joins a
    chord's notes only all together, and bridges rests."""
    voice_of = {id(e): _voice(e) for e in part.recurse().notes}
    entries: list[list[Any]] = []  # [pitch, onset ql, offset ql, velocity, finger]
    tied: dict[tuple[str | None, int], list[Any]] = {}  # (voice, pitch) -> the tied entry
    for element in part.flatten().notes:
        length = float(element.duration.quarterLength)
        if length <= 0:  # grace notes have no time of their own
            continue
        onset = float(element.offset)  # the flattened part's offsets are the part's
        velocity = int(element.volume.velocity or DEFAULT_VELOCITY)
        pitches = [p.midi for p in element.pitches]
        ties = _ties(element, len(pitches))
        fingers = _finger_numbers(element)
        if len(fingers) != len(pitches):
            fingers = [None] * len(pitches)
        for pitch, tie, number in zip(pitches, ties, fingers, strict=True):
            key = _tied_key(tied, voice_of.get(id(element)), pitch, onset)
            if key is not None:
                # A tie carries the earlier note on; as in music21, the note a tie starts
                # towards is joined even where the file forgets to mark the tie's end.
                held = tied.pop(key)
                held[2] = onset + length
                if tie in ("start", "continue"):
                    tied[key] = held
                continue
            finger = None
            if hand is not None and number is not None:
                finger = number - 1 + (0 if hand == RIGHT else 5)
            entry = [pitch, onset, onset + length, velocity, finger]
            entries.append(entry)
            if tie in ("start", "continue"):
                tied[(voice_of.get(id(element)), pitch)] = entry
    return [
        (pitch, seconds(onset), seconds(offset), velocity, hand, finger)
        for pitch, onset, offset, velocity, finger in entries
    ]


def _voice(element: Any) -> str | None:
    """The id of the voice a note lies in within its measure (None outside voices)."""
    site = element.activeSite
    return str(site.id) if type(site).__name__ == "Voice" else None


def _tied_key(
    tied: dict[tuple[str | None, int], list[Any]], voice: str | None, pitch: int, onset: float
) -> tuple[str | None, int] | None:
    """The open tie that a note of ``pitch`` at ``onset`` (quarter lengths) continues: one in
    its own voice that ends where it starts, else one in another voice (an encoding that
    changes voice across the tie); None if none does."""
    candidates = [(voice, pitch)] + [k for k in tied if k[1] == pitch and k[0] != voice]
    for key in candidates:
        held = tied.get(key)
        if held is not None and abs(held[2] - onset) <= 1e-9:
            return key
    return None


def _ties(element: Any, count: int) -> list[str | None]:
    """The tie type ("start", "continue", "stop" or None) of each pitch of a note or chord."""
    if hasattr(element, "notes") and len(element.notes) == count:  # a chord: per pitch
        return [n.tie.type if n.tie is not None else None for n in element.notes]
    tie = element.tie.type if element.tie is not None else None
    return [tie] * count


def _finger_numbers(element: Any) -> list[int | None]:
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
