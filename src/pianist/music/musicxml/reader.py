"""A parsed score as a :class:`~pianist.music.notes.Song`: every part's notes as played."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal, NamedTuple

from pianist.music.errors import MusicError, one_line
from pianist.music.midi import MAX_DURATION_S
from pianist.music.musicxml.files import OpenScore, as_music_error, open_score
from pianist.music.musicxml.loudness import DEFAULT_VELOCITY, part_loudness
from pianist.music.musicxml.marks import (
    articulation_of,
    finger_numbers,
    grace_note_sounds,
    is_trill,
    ornament_counts,
    ornament_sounds,
    roll_delays,
    sounding_length,
    tie_types,
    tremolo_pair_of,
)
from pianist.music.musicxml.measures import Event, Playing, measure_events, played_measures
from pianist.music.musicxml.pedal import pedal_intervals, sustain_marks
from pianist.music.musicxml.timing import seconds_per_quarter, tempo_map
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.ornaments import (
    ORNAMENT_NOTE_S,
    ROLL_STEP_S,
    SHORTEST_NOTE_S,
    alternation,
    trill_carried_on,
)
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH, out_of_range_error

#: :func:`read_score`'s options that read a score as written: once through, every note as
#: its notation gives it (no ornaments, fermatas or articulations played).
AS_WRITTEN: Mapping[str, bool] = MappingProxyType(
    {"expand_repeats": False, "ornaments": False, "fermatas": False, "articulations": False}
)


#: One note as read, before the voices are merged: (pitch, onset s, offset s, velocity, hand,
#: finger 0-9 or None).
RawNote = tuple[int, float, float, int, str | None, int | None]


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
    """Read a score into a :class:`Song` (the conventions of :mod:`pianist.music.musicxml`):
    MusicXML, or Humdrum ``**kern``, ABC or MEI, which music21 parses into the same shape.

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
        fermatas: hold the notes and rests under a fermata
            :data:`~pianist.music.musicxml.FERMATA_HOLD` times as long (every part waits);
            False: as written.
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
    opened = open_score(path)
    return _song_of(opened, out_of_range, expand_repeats, ornaments, fermatas, articulations)


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
    opened = open_score(path)
    song = _song_of(opened, out_of_range, True, True, True, True)
    written = _song_of(
        opened,
        "drop",
        expand_repeats=False,
        ornaments=False,
        fermatas=True,
        articulations=True,
    )
    return ScoreSummary(song, written.duration_s, ornament_counts(opened.score))


def _song_of(
    opened: OpenScore,
    out_of_range: Literal["error", "drop"],
    expand_repeats: bool,
    ornaments: bool,
    fermatas: bool,
    articulations: bool,
) -> Song:
    """The song an opened score plays (:func:`read_score`'s options)."""
    path, tune, score, sections, staves = opened
    parts = list(getattr(score, "parts", ())) or [score]
    raw: list[RawNote] = []
    with as_music_error(path):
        _put_at_sounding_pitch(score, parts, path)
        played = played_measures(parts, expand_repeats, path, sections)
        events = {id(m): measure_events(m) for measures in played for m, _ in measures}
        seconds = tempo_map(played, events, fermatas)
        playings: dict[int, list[tuple[float, float]]] = {}
        for measures, hand, loudness in zip(
            played,
            _hands_of_parts(parts, staves),
            part_loudness(played, parts, events),
            strict=True,
        ):
            raw.extend(
                _part_notes(
                    measures, hand, seconds, playings, events, loudness, ornaments, articulations
                )
            )
        sustain = pedal_intervals(sustain_marks(score), playings, seconds)
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


#: The same reader, by the name it had when it read MusicXML only.
read_musicxml = read_score


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


def _hands_of_parts(parts: list[Any], staves: list[int] | None) -> tuple[str | None, ...]:
    """The hand of each part: two parts are the right (upper) and left hand; otherwise the two
    staves of a grand staff, if the score has exactly one, and None for the rest. Where
    ``staves`` says which staff each part was written in (an ABC overlay's part shares its
    voice's), two staves are the two hands, and one or more than two give none."""
    if staves is not None and len(staves) == len(parts):
        upper, *others = sorted(set(staves))
        if len(others) != 1:
            return (None,) * len(parts)
        return tuple(RIGHT if staff == upper else LEFT for staff in staves)
    if len(parts) == 2:
        return (RIGHT, LEFT)
    # music21 parses a part of two staves as two PartStaff parts, in staff order.
    staves = [part for part in parts if type(part).__name__ == "PartStaff"]
    if len(staves) != 2:
        return (None,) * len(parts)
    upper, lower = staves
    return tuple(RIGHT if p is upper else LEFT if p is lower else None for p in parts)


def _part_notes(
    played: list[Playing],
    hand: str | None,
    seconds: Callable[[float], float],
    playings: dict[int, list[tuple[float, float]]],
    events: dict[int, list[Event]],
    loudness: Callable[[float], int | None],
    ornaments: bool,
    articulations: bool,
) -> list[RawNote]:
    """The notes of one part (a staff) as played, ties joined; each note's and pedal
    change's playings are added to ``playings`` (see :func:`pedal_intervals`). ``events``
    holds each measure's events (:func:`measure_events`), ``loudness`` the velocity the
    part's dynamics give at a time as played (:func:`part_loudness`). With ``ornaments`` the
    grace notes, rolled chords, trills, mordents, turns and tremolos are played
    (:mod:`pianist.music.ornaments`); without, grace notes are left out and the rest played
    as their written note. With ``articulations`` staccato notes are shortened and accented
    ones louder (:func:`articulation_of`).

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
            tremolo_pair = tremolo_pair_of(element) if ornaments else None
            if tremolo_pair is not None and tremolo_pair.getFirst() is element:
                tremolos[id(tremolo_pair)] = (onset, element)  # played with the second note
                continue
            fraction, accent = articulation_of(element) if articulations else (1.0, 0)
            velocity = int(
                element.volume.velocity or (loudness(onset) or DEFAULT_VELOCITY) + accent
            )
            quarters_per_s = 1.0 / seconds_per_quarter(seconds, onset)
            unit = ORNAMENT_NOTE_S * quarters_per_s if ornaments else 0.0  # ornaments' pace
            shortest = SHORTEST_NOTE_S * quarters_per_s

            # Grace notes at this note's onset take their time from its start; others (a grace
            # note before a rest, or left at a part's end) are left out.
            before = [g for at, g in graces.pop(voice, []) if abs(at - onset) <= 1e-9]
            grace_notes = grace_note_sounds(before, length, unit, shortest)
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
                delays.update(roll_delays(element, length - lead, ROLL_STEP_S * quarters_per_s))
            ties = tie_types(element, len(pitches))
            fingers = finger_numbers(element)
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
                            length if tied_on else sounding_length(length, fraction, shortest)
                        )
                    if tied_on:
                        tied[key] = held
                    continue
                finger = None
                if hand is not None and number is not None:
                    finger = number - 1 + (0 if hand == RIGHT else 5)
                begin = onset + lead + delays[pitch]
                rest = length - lead - delays[pitch]
                sounds = ornament_sounds(element, pitch, rest, unit) if ornaments else None
                if not sounds or min(b - a for _, a, b in sounds) < shortest - 1e-9:
                    # No ornament, or one too quick to show.
                    sounds = [
                        (pitch, 0.0, rest if tied_on else sounding_length(rest, fraction, shortest))
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
                    if other is not None and is_trill(element):
                        trilled[(voice, pitch)] = (other, sounds[0][2] - sounds[0][1])
    return [
        (pitch, seconds(onset), seconds(offset), velocity, hand, finger)
        for pitch, onset, offset, velocity, finger in entries
    ]


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
