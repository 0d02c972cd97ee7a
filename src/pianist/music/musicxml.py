"""Read scores as :class:`~pianist.music.notes.Song`: MusicXML (``.musicxml``, ``.mxl``,
``.xml``), Humdrum ``**kern`` (``.krn``), ABC (``.abc``) and MEI (``.mei``).

music21 parses the score (``pip install 'pianist[musicxml]'``); it is imported only when a
score is read. Reading conventions (a caller should know these):

- Every part's notes and chords are read, at the pitch they sound (a transposing
  instrument's part, a clarinet in B-flat, is written as its player reads it); tied notes
  are joined, voice by voice and pitch by pitch (in a chord only its tied pitches go on; a
  tie does not bridge a rest).
- Ornaments are played as a performer plays them (:mod:`pianist.music.ornaments`): grace
  notes on the beat, trills, mordents, turns and tremolos (on chords too), none
  of their notes shorter than two of the goal's frames where the written note leaves room;
  rolled chords one frame per note. A chord's trill, mordent or turn keeps its written
  notes; ``ornaments=False`` reads every note as written (grace notes left out).
- Repeats are played as a performer plays them (:mod:`pianist.music.repeats`: repeat signs,
  numbered endings, da capo and dal segno, al fine and al coda; an end-repeat sign without a
  start goes back to just after the previous repeat; an ending bracket without a number is
  the next ending of its run). Marks that give no order (a dal segno without a segno, a
  measure played more than :data:`~pianist.music.repeats.MAX_PLAYINGS` times, parts of
  different numbers of measures) are played once as written, with a warning. Every part
  starts each measure together.
- Times come from the score's metronome marks (quarter = 120 before the first one, music21's
  default; a mark without a number keeps the tempo before it), and from words that name a
  tempo where no mark does at their time ("Allegro": music21's value for it, quarter = 132).
  A fermata holds its note or rest twice as long (at most 2 s longer), every part waiting.
- Velocities come from the note's own (where the file gives one), else from the part's
  dynamics marks (p, mf, ff: music21's loudness of each, times 127; sf, fz accent their
  note; a hairpin goes from one level to the next; the two staves of a grand staff share
  their marks), else 80.
- Articulation marks shape their notes (music21's shifts: staccato 0.7 of the written
  length, accent +13 velocity).
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
- A MusicXML score written measure by measure (``score-timewise``) is read as the usual
  part by part form.
- Absurd scores are refused as MIDI files are: a timeline past one hour, no notes.
"""

from __future__ import annotations

import bisect
import os
import re
import warnings
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal, NamedTuple

from pianist.music.errors import MusicError, one_line
from pianist.music.fileio import require_file
from pianist.music.midi import MAX_DURATION_S
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.ornaments import (
    ORNAMENT_NOTE_S,
    ROLL_STEP_S,
    SHORTEST_NOTE_S,
    Played,
    alternation,
    grace_length,
    mordent,
    roll_starts,
    tremolo,
    trill,
    trill_carried_on,
    turn,
)
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH, out_of_range_error
from pianist.music.repeats import Bar, RepeatError, playing_order

#: File suffixes read as MusicXML (``.mxl`` is the compressed form).
MUSICXML_SUFFIXES = (".musicxml", ".mxl", ".xml")
#: File suffixes of every score :func:`read_score` reads: MusicXML, Humdrum ``**kern``, ABC
#: and MEI (the Music Encoding Initiative's).
SCORE_SUFFIXES = (*MUSICXML_SUFFIXES, ".krn", ".abc", ".mei")
#: Per suffix, music21's name of the format and the name messages give it.
_FORMATS = {
    **{suffix: ("musicxml", "MusicXML") for suffix in MUSICXML_SUFFIXES},
    ".krn": ("humdrum", "Humdrum **kern"),
    ".abc": ("abc", "ABC"),
    ".mei": ("mei", "MEI"),
}
#: :func:`read_score`'s options that read a score as written: once through, every note as
#: its notation gives it (no ornaments, fermatas or articulations played).
AS_WRITTEN: Mapping[str, bool] = MappingProxyType(
    {"expand_repeats": False, "ornaments": False, "fermatas": False, "articulations": False}
)
#: Quarter notes per minute before a score's first metronome mark (music21's default).
DEFAULT_QUARTER_BPM = 120.0
#: Velocity of a note whose score gives none.
DEFAULT_VELOCITY = 80

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
    boundaries = score.metronomeMarkBoundaries()
    return _seconds_through([(float(start), mark.getQuarterBPM()) for start, _, mark in boundaries])


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


def read_score(
    path: str | os.PathLike[str],
    *,
    out_of_range: Literal["error", "drop"] = "error",
    expand_repeats: bool = True,
    ornaments: bool = True,
    fermatas: bool = True,
    articulations: bool = True,
) -> Song:
    """Read a score into a :class:`Song` (see the module docstring's conventions): MusicXML,
    or Humdrum ``**kern``, ABC or MEI, which music21 parses into the same shape.

    Args:
        path: a ``.musicxml``, ``.mxl`` or ``.xml`` (MusicXML), ``.krn`` (Humdrum), ``.abc``
            or ``.mei`` file. Of an ABC book of several tunes the first is read, with a
            warning, or the one ``BOOK.abc#X`` names (:func:`tune_reference`).
        out_of_range: "error" raises :class:`OutOfRangeError` when any note lies outside MIDI
            21..108; "drop" leaves such notes out.
        expand_repeats: play the repeats (False: once through, as written).
        ornaments: play grace notes, rolled chords, trills, mordents, turns and tremolos
            as a performer does (:mod:`pianist.music.ornaments`); False: grace notes are left
            out and ornamented notes and chords played as written.
        fermatas: hold the notes and rests under a fermata :data:`FERMATA_HOLD` times as
            long (every part waits); False: as written.
        articulations: shorten staccato notes and accent accented ones (music21's length
            and volume shift of each mark: staccato 0.7 of the written length, staccatissimo
            0.5; accent +13 velocity); False: as written.

    Raises:
        MusicError: music21 missing; a missing or unreadable file, or one not of its suffix's
            format; a score music21 parses into a shape this reader cannot follow; no notes;
            a timeline longer than one hour.
        OutOfRangeError: notes outside the piano's keys with ``out_of_range="error"``.
    """
    if out_of_range not in ("error", "drop"):
        raise ValueError(f"out_of_range must be 'error' or 'drop', got {out_of_range!r}")
    path, tune, score = _open(path)
    return _song_of(
        score, path, tune, out_of_range, expand_repeats, ornaments, fermatas, articulations
    )


class ScoreSummary(NamedTuple):
    """A score's song and what its reading adds to what it writes (:func:`score_summary`)."""

    #: The song as :func:`read_score` reads it by default.
    song: Song
    #: The song's duration in seconds played once through, without its repeats.
    once_through_s: float
    #: How many of each ornament of the kinds the reader plays the score writes, by name in
    #: the plural ("grace notes", "rolled chords", "trills", "mordents", "turns", "tremolos");
    #: only those present. (Ornaments too quick for the goal's frames are played as written.)
    ornaments: dict[str, int]


def score_summary(
    path: str | os.PathLike[str], *, out_of_range: Literal["error", "drop"] = "error"
) -> ScoreSummary:
    """A score's song (:func:`read_score`'s, with its defaults), its duration once through
    and its ornaments, from one parse.

    Raises:
        MusicError, OutOfRangeError: as :func:`read_score`.
    """
    path, tune, score = _open(path)
    song = _song_of(score, path, tune, out_of_range, True, True, True, True)
    written = _song_of(
        score,
        path,
        tune,
        "drop",
        expand_repeats=False,
        ornaments=False,
        fermatas=True,
        articulations=True,
    )
    counts: Counter[str] = Counter()
    for element in score.recurse().notes:
        if element.duration.isGrace:
            counts["grace notes"] += 1
        if _roll(element) is not None:
            counts["rolled chords"] += 1
        pair = _tremolo_pair(element)
        if pair is not None and pair.getFirst() is element:
            counts["tremolos"] += 1
        for mark in element.expressions:
            kind = next((k for k in _ORNAMENT_KINDS if k in mark.classes), None)
            if kind is not None and (kind == "Tremolo" or len(element.pitches) == 1):
                counts[_ORNAMENT_KINDS[kind]] += 1
                break  # the first ornament is the one played
    return ScoreSummary(song, written.duration_s, dict(counts))


#: The ornaments the reader plays: music21's class, and the name :class:`ScoreSummary` gives.
_ORNAMENT_KINDS = {
    "Trill": "trills",
    "GeneralMordent": "mordents",
    "Turn": "turns",
    "Tremolo": "tremolos",
}


def _open(path: str | os.PathLike[str]) -> tuple[Path, int | None, Any]:
    """The score's file (a ``BOOK.abc#X`` reference resolved), the ABC tune read (None for
    one tune or another format) and the parsed score."""
    reference = None if Path(path).exists() else tune_reference(os.fspath(path))
    path, tune = reference if reference is not None else (Path(path), None)
    music21_format, kind = _FORMATS.get(path.suffix.lower(), _FORMATS[".musicxml"])
    require_file(path, MusicError, f"{kind} file")
    score, tune = _parse(path, tune, music21_format, kind)
    return path, tune, score


def _song_of(
    score: Any,
    path: Path,
    tune: int | None,
    out_of_range: Literal["error", "drop"],
    expand_repeats: bool,
    ornaments: bool,
    fermatas: bool,
    articulations: bool,
) -> Song:
    """The song a parsed score plays (:func:`read_score`'s options; ``path`` and ``tune``
    name it and its errors)."""
    parts = list(getattr(score, "parts", ())) or [score]
    raw: list[RawNote] = []
    with _as_music_error(path):
        _put_at_sounding_pitch(score, parts, path)
        played = _played_measures(parts, expand_repeats, path)
        events = {id(m): _measure_events(m) for measures in played for m, _ in measures}
        seconds = _tempo_map(played, events, fermatas)
        playings: dict[int, list[tuple[float, float]]] = {}
        for measures, hand, loudness in zip(
            played, _hands_of_parts(parts), _loudness(played, parts, events), strict=True
        ):
            raw.extend(
                _part_notes(
                    measures, hand, seconds, playings, events, loudness, ornaments, articulations
                )
            )
        sustain = _pedal_intervals(_sustain_marks(score), playings, seconds)
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
    name = path.stem if tune is None else f"{path.stem}-{tune}"
    return Song(notes=tuple(notes), sustain=sustain, name=name)


def _parse(path: Path, tune: int | None, music21_format: str, kind: str) -> tuple[Any, int | None]:
    """The score music21 parses from ``path`` in ``music21_format`` (``kind`` names it in
    messages), and the reference number of the ABC tune read (``tune``, or a book's first:
    only that tune is parsed; None for one tune or another format).

    Raises:
        MusicError: music21 missing, or the file not of its format.
    """
    try:
        from music21 import converter
    except ImportError:
        raise MusicError(
            f"{path}: reading {kind} needs music21 (pip install 'pianist[musicxml]')"
        ) from None
    book: list[int] = []  # an ABC book's reference numbers, when no tune is named
    if music21_format == "abc" and tune is None:
        book = _reference_numbers(path)
        tune = book[0] if len(book) > 1 else None  # music21 then parses that tune alone
    try:
        options = {} if tune is None else {"number": tune}
        source: str = str(path)
        if path.suffix.lower() in (".musicxml", ".xml"):
            source = _partwise(path.read_bytes()) or source  # music21 reads partwise only
        if music21_format == "abc":
            source = _abc_without_shorthand_fermatas(path) or source
        score = converter.parse(source, format=music21_format, forceSource=True, **options)
    except Exception as exc:  # music21 raises many types for a file it cannot read
        raise MusicError(f"{path}: not a readable {kind} score ({one_line(exc)})") from None
    tunes = list(getattr(score, "scores", ()))  # music21 parses several tunes into an Opus
    score = tunes[0] if tunes else score
    if len(book) > 1:
        title = getattr(score.metadata, "title", None) if score.metadata else None
        warnings.warn(
            f"{path}: a book of {len(book)} tunes; the first"
            + (f", {title!r}," if title else "")
            + f" is read (name another as {path.name}#X, X its reference number)",
            stacklevel=3,
        )
    return score, tune


#: The encodings a MusicXML file comes in (music21's corpus holds UTF-16 ones).
_ENCODINGS = ("utf-8", "utf-16-le", "utf-16-be")


def _partwise(document: bytes) -> str | None:
    """A ``score-timewise`` MusicXML document (measures holding parts) turned into the
    ``score-partwise`` one music21 reads (parts holding measures); None for any other
    document, or one that is not XML (music21 then says what is wrong with it)."""
    import xml.etree.ElementTree as ET

    head = document[:65536]  # the root element's name, in UTF-8 or UTF-16
    if not any("score-timewise".encode(encoding) in head for encoding in _ENCODINGS):
        return None
    try:
        root = ET.fromstring(document)
    except ET.ParseError:
        return None
    if root.tag != "score-timewise":
        return None
    partwise = ET.Element("score-partwise", root.attrib)
    parts: dict[str, ET.Element] = {}
    for child in root:
        if child.tag != "measure":  # the header: work, identification, part-list, ...
            partwise.append(child)
            continue
        for part in child.findall("part"):
            measure = ET.SubElement(
                parts.setdefault(part.get("id", ""), ET.Element("part", part.attrib)),
                "measure",
                child.attrib,
            )
            measure.extend(list(part))
    partwise.extend(parts.values())
    return ET.tostring(partwise, encoding="unicode")


def _reference_numbers(path: Path) -> list[int]:
    """The reference numbers (``X:`` fields) of the tunes in an ABC file, in order."""
    text = path.read_text(encoding="utf-8", errors="replace")
    return [int(m[1]) for m in re.finditer(r"^X:\s*(\d+)", text, flags=re.MULTILINE)]


def _abc_without_shorthand_fermatas(path: Path) -> str | None:
    """An ABC file's text with each fermata written as the shorthand ``H`` (``HE``: E under a
    fermata) written out (``!fermata!E``), which music21 reads; None where it has none.
    music21 drops the note after the shorthand, shifting every later note of its voice
    earlier (Aird's Airs and O'Neill's 1850 in its own corpus hold 226 such lines).

    Only the music is changed: field lines (``X:``, ``H:``...), comments, quoted text,
    decorations (``!...!``, ``+...+``) and inline fields (``[K:...]``) are kept as they are."""
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.splitlines(keepends=True)
    changed = False
    for i, line in enumerate(lines):
        if re.match(r"[A-Za-z+]:", line) or "H" not in line:
            continue
        out, closing = [], ""  # closing: the character that ends the span we are in
        for k, char in enumerate(line):
            if closing:
                closing = "" if char == closing else closing
            elif char == "%":
                out.append(line[k:])
                break
            elif char in '"!+':
                closing = char
            elif char == "[" and re.match(r"\[[A-Za-z]:", line[k:]):
                closing = "]"
            elif char == "H":
                out.append("!fermata!")
                changed = True
                continue
            out.append(char)
        lines[i] = "".join(out)
    return "".join(lines) if changed else None


def tune_reference(text: str) -> tuple[Path, int] | None:
    """``BOOK.abc#X`` names the tune of reference number X (its ``X:`` field) in an ABC book:
    (the book's path, X); None for any other text."""
    match = re.fullmatch(r"(.+\.abc)#(\d+)", text, flags=re.IGNORECASE)
    return (Path(match[1]), int(match[2])) if match else None


#: The same reader, by the name it had when it read MusicXML only.
read_musicxml = read_score


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


def _put_at_sounding_pitch(score: Any, parts: list[Any], path: Path) -> None:
    """Put the parts of transposing instruments (a clarinet in B-flat, a horn in F) at the
    pitches they sound, in place: MusicXML writes their notes as the player reads them, a
    major second above the sound for the clarinet."""
    if all(getattr(part, "atSoundingPitch", True) is True for part in parts):
        return
    try:
        score.toSoundingPitch(inPlace=True)
    except Exception as exc:  # music21's transposition fails on shapes it did not foresee
        warnings.warn(
            f"{path}: its transposing instruments could not be put at the pitch they sound "
            f"({one_line(exc)}); read as written",
            stacklevel=3,
        )


class _Playing(NamedTuple):
    """One playing of a measure: the measure (music21) and where it starts as played, in
    quarter lengths from the piece's start."""

    measure: Any
    start: float


def _played_measures(parts: list[Any], expand: bool, path: Path) -> list[list[_Playing]]:
    """Per part, its measures in the order they are played, each with its start as played.

    With ``expand`` the order follows the repeats (:func:`pianist.music.repeats.playing_order`);
    without it, or where the marks give no order (then with a warning), the score is played
    once as written. The parts start each measure together (:func:`_measure_lengths`). A
    score whose parts have different numbers of measures is played part by part as music21
    lays it out, and a part without measures as one measure."""
    measures = [list(part.getElementsByClass("Measure")) for part in parts]
    if any(not ms for ms in measures) or len({len(ms) for ms in measures}) != 1:
        if expand and all(measures) and _has_repeat_marks(measures):
            warnings.warn(
                f"{path}: its repeats could not be expanded (its parts have different numbers "
                "of measures); played once as written",
                stacklevel=3,
            )
        return [
            [_Playing(m, float(m.offset)) for m in ms] if ms else [_Playing(part, 0.0)]
            for ms, part in zip(measures, parts, strict=True)
        ]
    order = list(range(len(measures[0])))
    if expand:
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
        [_Playing(ms[i], start) for i, start in zip(order, starts, strict=True)] for ms in measures
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


def _part_notes(
    played: list[_Playing],
    hand: str | None,
    seconds: Callable[[float], float],
    playings: dict[int, list[tuple[float, float]]],
    events: dict[int, list[_Event]],
    loudness: Callable[[float], int | None],
    ornaments: bool,
    articulations: bool,
) -> list[RawNote]:
    """The notes of one part (a staff) as played, ties joined; each note's and pedal
    change's playings are added to ``playings`` (see :func:`_pedal_intervals`). ``events``
    holds each measure's events (:func:`_measure_events`), ``loudness`` the velocity the
    part's dynamics give at a time as played (:func:`_loudness`). With ``ornaments`` the
    grace notes, rolled chords, trills, mordents, turns and tremolos are played
    (:mod:`pianist.music.ornaments`); without, grace notes are left out and the rest played
    as their written note. With ``articulations`` staccato notes are shortened and accented
    ones louder (:func:`_articulation`).

    Ties are joined here, voice by voice and pitch by pitch, in one pass over the part's notes
    in time order: music21's ``stripTies`` copies the part and searches its spanners for every
    note (14 s per part of a Beethoven quartet movement, against milliseconds here), joins a
    chord's notes only all together, and bridges rests."""
    entries: list[list[Any]] = []  # [pitch, onset ql, offset ql, velocity, finger]
    tied: dict[tuple[str | None, int], list[Any]] = {}  # (voice, pitch) -> the tied entry
    graces: dict[str | None, list[tuple[float, Any]]] = {}  # voice -> graces before its note
    tremolos: dict[int, tuple[float, Any]] = {}  # a two-note tremolo -> its first note, onset
    trilled: dict[tuple[str | None, int], tuple[int, float]] = {}  # tied trill -> (aux., step)
    for measure, start in played:
        for offset, element, voice, kind, source in events[id(measure)]:
            if kind in ("tempo", "tempo words", "dynamic"):
                continue
            onset = start + offset
            length = float(element.duration.quarterLength)
            playings.setdefault(source, []).append((onset, onset + length))
            if kind != "note":
                continue
            if length <= 0:  # a grace note: played before the next note of its voice
                if ornaments:
                    graces.setdefault(voice, []).append((onset, element))
                continue
            tremolo_pair = _tremolo_pair(element) if ornaments else None
            if tremolo_pair is not None and tremolo_pair.getFirst() is element:
                tremolos[id(tremolo_pair)] = (onset, element)  # played with the second note
                continue
            fraction, accent = _articulation(element) if articulations else (1.0, 0)
            velocity = int(
                element.volume.velocity or (loudness(onset) or DEFAULT_VELOCITY) + accent
            )
            quarters_per_s = 1.0 / _seconds_per_quarter(seconds, onset)
            unit = ORNAMENT_NOTE_S * quarters_per_s if ornaments else 0.0  # ornaments' pace
            shortest = SHORTEST_NOTE_S * quarters_per_s

            # Grace notes at this note's onset take their time from its start; others (a grace
            # note before a rest, or left at a part's end) are left out.
            before = [g for at, g in graces.pop(voice, []) if abs(at - onset) <= 1e-9]
            grace_notes = _grace_notes(before, length, unit, shortest)
            entries += [[p, onset + a, onset + b, velocity, None] for p, a, b in grace_notes]
            lead = grace_notes[-1][2] if grace_notes else 0.0
            if tremolo_pair is not None and id(tremolo_pair) in tremolos:
                # The second note of a two-note tremolo: the two alternate over both notes.
                begin, first = tremolos.pop(id(tremolo_pair))
                strokes, span = int(tremolo_pair.numberOfMarks), onset + length - begin
                first_pitches, second_pitches = (
                    [p.midi for p in e.pitches] for e in (first, element)
                )
                alternating = alternation(first_pitches, second_pitches, span, strokes, unit)
                entries += [[p, begin + a, begin + b, velocity, None] for p, a, b in alternating]
                continue
            pitches = [p.midi for p in element.pitches]
            delays = dict.fromkeys(pitches, 0.0)  # when each pitch starts after the onset
            if ornaments:
                delays.update(_rolled(element, length - lead, ROLL_STEP_S * quarters_per_s))
            ties = _ties(element, len(pitches))
            fingers = _finger_numbers(element)
            if len(fingers) != len(pitches):
                fingers = [None] * len(pitches)
            for pitch, tie, number in zip(pitches, ties, fingers, strict=True):
                # A note a tie carries on sounds its whole written length; the articulation
                # (staccato) shortens the last note of the tie.
                tied_on = tie in ("start", "continue")
                key = _tied_key(tied, voice, pitch, onset)
                if key is not None:
                    # A tie carries the earlier note on; as in music21, the note a tie starts
                    # towards is joined even where the file forgets to mark the tie's end.
                    held = tied.pop(key)
                    trill_so_far = trilled.pop(key, None)
                    if trill_so_far is not None and length / 2 >= shortest - 1e-9:
                        # A trill goes on through the tie (the note's finger on its strokes).
                        auxiliary, step = trill_so_far
                        more = [
                            [p, onset + a, onset + b, held[3], held[4] if p == pitch else None]
                            for p, a, b in trill_carried_on(pitch, auxiliary, length, step)
                        ]
                        entries.extend(more)
                        held = more[-1]
                        if tied_on:
                            trilled[key] = (auxiliary, step)
                    else:
                        held[2] = onset + (
                            length if tied_on else _sounding(length, fraction, shortest)
                        )
                    if tied_on:
                        tied[key] = held
                    continue
                finger = None
                if hand is not None and number is not None:
                    finger = number - 1 + (0 if hand == RIGHT else 5)
                begin = onset + lead + delays[pitch]
                rest = length - lead - delays[pitch]
                sounds = _ornament_notes(element, pitch, rest, unit) if ornaments else None
                if not sounds or min(b - a for _, a, b in sounds) < shortest - 1e-9:
                    # No ornament, or one too quick to show.
                    sounds = [
                        (pitch, 0.0, rest if tied_on else _sounding(rest, fraction, shortest))
                    ]
                # The written note's finger plays each of its own strokes; the ornament's
                # other notes are fingered like unfingered notes.
                played_notes = [
                    [p, begin + a, begin + b, velocity, finger if p == pitch else None]
                    for p, a, b in sounds
                ]
                entries.extend(played_notes)
                if tied_on:
                    tied[(voice, pitch)] = played_notes[-1]  # the ornament ends on the note
                    other = next((p for p, _, _ in sounds if p != pitch), None)
                    if other is not None and _is_trill(element):
                        trilled[(voice, pitch)] = (other, sounds[0][2] - sounds[0][1])
    return [
        (pitch, seconds(onset), seconds(offset), velocity, hand, finger)
        for pitch, onset, offset, velocity, finger in entries
    ]


def _is_trill(element: Any) -> bool:
    """Whether a single note carries a trill sign as its first ornament."""
    for mark in element.expressions:
        if {"Trill", "GeneralMordent", "Turn", "Tremolo"} & set(mark.classes):
            return "Trill" in mark.classes and len(element.pitches) == 1
    return False


def _grace_notes(graces: list[Any], length: float, unit: float, shortest: float) -> list[Played]:
    """The notes of the grace notes (music21 notes or chords) before a note of ``length``
    quarter lengths, from its onset, each :func:`pianist.music.ornaments.grace_length` long;
    none where that is shorter than ``shortest`` (too quick to show)."""
    if not graces or grace_length(len(graces), length, unit) < shortest - 1e-9:
        return []
    each = grace_length(len(graces), length, unit)
    return [(p.midi, k * each, (k + 1) * each) for k, g in enumerate(graces) for p in g.pitches]


def _tremolo_pair(element: Any) -> Any | None:
    """The two-note tremolo (music21 ``TremoloSpanner``) a note or chord is one of the two
    notes of; None for any other."""
    for spanner in element.getSpannerSites():
        if "TremoloSpanner" in spanner.classes and len(spanner.getSpannedElements()) == 2:
            return spanner
    return None


def _articulation(element: Any) -> tuple[float, int]:
    """The fraction of its written length a note or chord sounds, and the velocity its marks
    add: music21's length and volume shift of each articulation mark (staccato 0.7 of the
    length and +6 velocity, staccatissimo 0.5, accent +13, strong accent +19; tenuto's 1.1
    is kept at the written length, so a note does not overlap the next)."""
    fraction, volume = 1.0, 0.0
    for mark in element.articulations:
        fraction *= min(1.0, float(getattr(mark, "lengthShift", 1.0)))
        volume += float(getattr(mark, "volumeShift", 0.0))
    return fraction, round(volume * 127)


def _sounding(length: float, fraction: float, shortest: float) -> float:
    """How long a note of ``length`` (quarter lengths) sounds when its articulation keeps
    ``fraction`` of it: never shorter than ``shortest`` (one goal frame) unless written so."""
    return max(length * fraction, min(length, shortest))


def _seconds_per_quarter(seconds: Callable[[float], float], ql: float) -> float:
    """The tempo at ``ql`` (quarter lengths as played) as seconds per quarter length."""
    return (seconds(ql + 1e-3) - seconds(ql)) / 1e-3


def _ornament_notes(element: Any, pitch: int, length: float, unit: float) -> list[Played] | None:
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


def _rolled(element: Any, length: float, step: float) -> dict[int, float]:
    """When each pitch of a rolled chord starts after its onset, in quarter lengths
    (:func:`pianist.music.ornaments.roll_starts`: from the lowest of the roll's pitches, or
    the highest for a downward roll, ``step`` apart); empty for a note or chord not rolled
    (:func:`_roll`)."""
    roll = _roll(element)
    if roll is None:
        return {}
    down, pitches = roll
    order = sorted(set(pitches), reverse=down)
    return dict(zip(order, roll_starts(len(order), length, step), strict=True))


def _roll(element: Any) -> tuple[bool, list[int]] | None:
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


class _Event(NamedTuple):
    """What a measure holds at a time: its offset in the measure (quarter lengths), the
    music21 element, its voice, its kind ("note" for a note or chord, "other" for a rest or a
    pedal change, "tempo" for a tempo indication, "tempo words" for words that name a tempo,
    "dynamic"), and the ``id`` of the element a pedal mark names for it (music21 gives the
    staves of a grand staff copies of a pedal change, derived from the one the mark holds)."""

    offset: float
    element: Any
    voice: str | None
    kind: _EventKind
    source: int


_EventKind = Literal["note", "other", "tempo", "tempo words", "dynamic"]


def _measure_events(measure: Any) -> list[_Event]:
    """A measure's notes, chords, rests, pedal changes, tempo indications (words that name a
    tempo as the metronome mark they stand for) and dynamics, in time order (through its
    voices)."""
    from music21 import tempo

    voice_of = {id(e): _voice(e) for e in measure.recurse().notes}  # before flattening
    flat = measure.flatten()  # its offsets are the measure's
    notes = {id(e) for e in flat.notes}
    classes = ("GeneralNote", "PedalBounce", "TempoIndication", "Dynamic", "TextExpression")
    events = []
    for e in flat.getElementsByClass(classes):
        kind: _EventKind = (
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
            bpm = _words_bpm(str(e.content))
            if bpm is None:
                continue  # words that name no tempo ("dolce", "a tempo", "rit.")
            named = tempo.MetronomeMark(number=bpm, referent=1.0)  # the tempo they name
            events.append(_Event(float(e.offset), named, None, kind, id(e)))
            continue
        source = id(e.derivation.rootDerivation or e)
        events.append(_Event(float(e.offset), e, voice_of.get(id(e)), kind, source))
    return events


def _tempo_map(
    played: list[list[_Playing]], events: dict[int, list[_Event]], fermatas: bool
) -> Callable[[float], float]:
    """The map from a time as played (quarter lengths from the start) to seconds, through the
    metronome marks (and other tempo indications) of every part as played: quarter = 120
    before the first (music21's default), and a mark without a number keeps the tempo before
    it. Of marks at one time the last part's holds. Words that name a tempo without a mark
    ("Allegro", "Langsam": :func:`_words_bpm`) set it where no mark does at their time. With
    ``fermatas``, the time under a fermata in any part is held longer (:func:`_held`)."""
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


#: Words that change the tempo against the one before ("più", "piu", "meno"), not name one.
_RELATIVE_TEMPO = re.compile(r"\b(più|piu|meno)\b", re.IGNORECASE)


def _words_bpm(words: str) -> float | None:
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


#: Dynamics that accent the notes they fall on, and the level they leave after them (None: the
#: level before them goes on; "fp": loud, then soft).
_ACCENTS: dict[str, str | None] = {
    **dict.fromkeys(("sf", "sfz", "sffz", "fz", "rf", "rfz")),
    "fp": "p",
    "sfp": "p",
}


def _loudness(
    played: list[list[_Playing]], parts: list[Any], events: dict[int, list[_Event]]
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
    """The lookup :func:`_loudness` returns for one staff group's marks (time, velocity,
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
