"""Built-in debug songs written in code (every note fingered) and :func:`load_song`.

The ``debug`` songs follow the shape of RoboPianist's debug set (facts section 4): Twinkle
Twinkle (one hand, 8 s, 14 notes), C and D major scales (one hand 15 notes / two hands 30
notes, 7.5 s) and a C major chord progression (two hands, 4 s, 16 notes). They differ from
the original's notes in places: Twinkle's fingering keeps the thumb on C until the long G,
the scales' right hand plays an octave lower (from C4/D4, the left from C3/D3), and the
chords move by close voice leading over a bass (the original plays root-position triads that
jump, over C3 F2 G2 C3). The ``robopianist-debug`` suite has the original's six songs note
for note under the original's names (``CMajorChordProgressionTwoHands``, or its environment
id ``RoboPianist-debug-CMajorChordProgressionTwoHands-v0``), to compare with published runs.
Fingers use pianists' numbers 1 (thumb) .. 5 (little) in the tables below and are mapped to
0-4 (right) / 5-9 (left).
"""

from __future__ import annotations

import difflib
import os
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Literal

from pianist.music.errors import MidiFileError, MusicError, UnknownSongError
from pianist.music.fingering import FingeringMode, assign_fingering, ensure_fingering
from pianist.music.marked_dynamics import DYNAMICS_SONGS, DYNAMICS_SUITE
from pianist.music.midi import read_midi
from pianist.music.musicxml import AS_WRITTEN, SCORE_SUFFIXES, read_score, tune_reference
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.open_library import (
    OPEN_SUITE,
    list_open_songs,
    load_open_song,
    open_song_info,
)
from pianist.music.parts import midi_hand_hints
from pianist.music.pig import read_pig
from pianist.music.pig_dataset import (
    ETUDE_12,
    PIG_DIR_ENV,
    PIG_SUITES,
    find_pig_song,
    is_pig_name,
    list_pig_songs,
    load_pig_song,
    pig_data_dir,
    pig_dataset_imported,
)
from pianist.music.pitch import name_to_pitch
from pianist.music.stretch import OCTAVE_SONGS, OCTAVE_SUITE

_MAJOR_STEPS = (0, 2, 4, 5, 7, 9, 11, 12)  # semitones above the tonic, one octave
# Standard one-octave major-scale fingerings (C, D, ... share them), ascending.
_RIGHT_SCALE_FINGERS = (1, 2, 3, 1, 2, 3, 4, 5)
_LEFT_SCALE_FINGERS = (5, 4, 3, 2, 1, 3, 2, 1)
_NOTE_S = 0.5


def _finger(hand: str, number: int) -> int:
    """Pianist's finger number 1..5 on ``hand`` -> finger index 0..9."""
    return number - 1 if hand == RIGHT else number + 4


def _melody(
    pitches: Sequence[str],
    beats: Sequence[float],
    fingers: Sequence[int],
    hand: str,
    beat_s: float = _NOTE_S,
) -> list[Note]:
    """Consecutive notes starting at 0 s, each lasting its beats times ``beat_s``."""
    notes = []
    onset = 0.0
    for name, length, number in zip(pitches, beats, fingers, strict=True):
        offset = onset + length * beat_s
        notes.append(Note(name_to_pitch(name), onset, offset, finger=_finger(hand, number)))
        onset = offset
    return notes


def _scale_up_down(tonic: str, hand: str) -> list[Note]:
    """One octave up and back down from ``tonic``: 15 notes of 0.5 s (7.5 s)."""
    root = name_to_pitch(tonic)
    up = [root + step for step in _MAJOR_STEPS]
    fingers_up = _RIGHT_SCALE_FINGERS if hand == RIGHT else _LEFT_SCALE_FINGERS
    pitches = up + up[-2::-1]
    fingers = list(fingers_up) + list(fingers_up[-2::-1])
    notes = []
    for index, (pitch, number) in enumerate(zip(pitches, fingers, strict=True)):
        onset = index * _NOTE_S
        notes.append(Note(pitch, onset, onset + _NOTE_S, finger=_finger(hand, number)))
    return notes


def _scale_song(tonic: str, both_hands: bool, right_octave: int = 4) -> list[Note]:
    """Right hand from ``tonic`` in ``right_octave``; with ``both_hands`` the left from octave 3
    (an octave lower, or two for the original's songs with ``right_octave`` 5)."""
    notes = _scale_up_down(f"{tonic}{right_octave}", RIGHT)
    if both_hands:
        notes += _scale_up_down(f"{tonic}3", LEFT)
    return notes


def _twinkle() -> list[Note]:
    # Thumb on C, pinky reaching A; the hand shifts down one step during the long G so that
    # F E D C fall under 4 3 2 1.
    pitches = ("C4 C4 G4 G4 A4 A4 G4 F4 F4 E4 E4 D4 D4 C4").split()
    beats = (1, 1, 1, 1, 1, 1, 2, 1, 1, 1, 1, 1, 1, 2)
    fingers = (1, 1, 4, 4, 5, 5, 4, 4, 4, 3, 3, 2, 2, 1)
    return _melody(pitches, beats, fingers, RIGHT)


# I - IV - V - I in C, one second each: right-hand triads (close voice leading) over a left-hand
# bass note. Entries: (right-hand names, right fingers, bass name, left finger).
_CHORDS = (
    (("C4", "E4", "G4"), (1, 3, 5), "C3", 5),
    (("C4", "F4", "A4"), (1, 3, 5), "F3", 2),
    (("B3", "D4", "G4"), (1, 2, 5), "G3", 1),
    (("C4", "E4", "G4"), (1, 3, 5), "C3", 5),
)


def _chords() -> list[Note]:
    notes = []
    for index, (names, fingers, bass, bass_finger) in enumerate(_CHORDS):
        onset, offset = float(index), float(index + 1)
        for name, number in zip(names, fingers, strict=True):
            notes.append(Note(name_to_pitch(name), onset, offset, finger=_finger(RIGHT, number)))
        notes.append(Note(name_to_pitch(bass), onset, offset, finger=_finger(LEFT, bass_finger)))
    return notes


def _original_twinkle() -> list[Note]:
    # The original's fingering: the hand sits with the thumb on E from the first G.
    pitches = ("C4 C4 G4 G4 A4 A4 G4 F4 F4 E4 E4 D4 D4 C4").split()
    beats = (1, 1, 1, 1, 1, 1, 2, 1, 1, 1, 1, 1, 1, 2)
    fingers = (1, 1, 3, 3, 4, 4, 3, 4, 4, 3, 3, 2, 2, 1)
    return _melody(pitches, beats, fingers, RIGHT)


# The original's progression: root-position right-hand triads (fingers 1 3 5) that jump from
# chord to chord, over a left-hand bass. Entries: (triad's root, bass name, left finger).
_ORIGINAL_CHORDS = (("C4", "C3", 1), ("F4", "F2", 4), ("G4", "G2", 3), ("C4", "C3", 1))


def _original_chords() -> list[Note]:
    notes = []
    for index, (root, bass, bass_finger) in enumerate(_ORIGINAL_CHORDS):
        onset, offset = float(index), float(index + 1)
        notes.append(Note(name_to_pitch(bass), onset, offset, finger=_finger(LEFT, bass_finger)))
        for step, number in zip((0, 4, 7), (1, 3, 5), strict=True):
            pitch = name_to_pitch(root) + step
            notes.append(Note(pitch, onset, offset, finger=_finger(RIGHT, number)))
    return notes


ORIGINAL_DEBUG_SUITE = "robopianist-debug"
_ORIGINAL_ID_PREFIX = "RoboPianist-debug-"
_ORIGINAL_SONGS: dict[str, tuple[str, Callable[[], list[Note]]]] = {
    "TwinkleTwinkleLittleStar": (
        "the original's Twinkle Twinkle, right hand, 14 notes, 8 s",
        _original_twinkle,
    ),
    "CMajorScaleOneHand": (
        "the original's C major scale, right hand from C5, 15 notes, 7.5 s",
        lambda: _scale_song("C", both_hands=False, right_octave=5),
    ),
    "CMajorScaleTwoHands": (
        "the original's C major scale, hands two octaves apart (C5 / C3), 30 notes, 7.5 s",
        lambda: _scale_song("C", both_hands=True, right_octave=5),
    ),
    "DMajorScaleOneHand": (
        "the original's D major scale, right hand from D5, 15 notes, 7.5 s",
        lambda: _scale_song("D", both_hands=False, right_octave=5),
    ),
    "DMajorScaleTwoHands": (
        "the original's D major scale, hands two octaves apart (D5 / D3), 30 notes, 7.5 s",
        lambda: _scale_song("D", both_hands=True, right_octave=5),
    ),
    "CMajorChordProgressionTwoHands": (
        "the original's C major progression: root-position triads that jump, over C3 F2 G2 C3, "
        "16 notes, 4 s",
        _original_chords,
    ),
}


def _original_name(name: str) -> str | None:
    """The ``robopianist-debug`` song that ``name`` gives (by its own name or its environment
    id), or None."""
    if name.startswith(_ORIGINAL_ID_PREFIX) and name.endswith("-v0"):
        name = name[len(_ORIGINAL_ID_PREFIX) : -len("-v0")]
    return name if name in _ORIGINAL_SONGS else None


_SONGS: dict[str, tuple[str, Callable[[], list[Note]]]] = {
    "twinkle-twinkle": (
        "Twinkle Twinkle Little Star, right hand, 14 notes, 8 s",
        _twinkle,
    ),
    "c-major-scale-right": (
        "C major scale up and down, right hand, 15 notes, 7.5 s",
        lambda: _scale_song("C", both_hands=False),
    ),
    "c-major-scale-both": (
        "C major scale up and down, both hands an octave apart, 30 notes, 7.5 s",
        lambda: _scale_song("C", both_hands=True),
    ),
    "d-major-scale-right": (
        "D major scale up and down, right hand, 15 notes, 7.5 s",
        lambda: _scale_song("D", both_hands=False),
    ),
    "d-major-scale-both": (
        "D major scale up and down, both hands an octave apart, 30 notes, 7.5 s",
        lambda: _scale_song("D", both_hands=True),
    ),
    "c-major-chords": (
        "C major chords I-IV-V-I, right-hand triads over left-hand bass, 16 notes, 4 s",
        _chords,
    ),
}


#: The suites built by code, each: song name -> (description, builder of its notes).
_BUILT_SUITES = {OCTAVE_SUITE: OCTAVE_SONGS, DYNAMICS_SUITE: DYNAMICS_SONGS}
#: Every built song: name -> (its suite, (description, builder)).
_BUILT = {
    name: (suite, entry) for suite, songs in _BUILT_SUITES.items() for name, entry in songs.items()
}
#: Suites :func:`list_songs` knows: the debug songs, the original's debug songs, the built
#: suites, the shipped open library, and the PIG-based suites of the paper (once
#: ``pianist import-pig`` has run).
SUITES = ("debug", ORIGINAL_DEBUG_SUITE, OCTAVE_SUITE, DYNAMICS_SUITE, OPEN_SUITE, *PIG_SUITES)


def list_songs(suite: str | None = None) -> list[str]:
    """Names of the songs of ``suite``, in a stable order; by default the built-in debug songs.

    Args:
        suite: None or "debug" (the debug songs), "robopianist-debug" (the original's debug
            songs note for note), "octaves" (pieces at an octave's stretch,
            :mod:`pianist.music.stretch`), "dynamics" (pieces with marked loudness,
            :mod:`pianist.music.marked_dynamics`), "open-etude-12" (the shipped open
            library), "etude-12" or "repertoire-150" (imported PIG pieces).

    Raises:
        ValueError: unknown suite.
        PigDatasetError: a PIG suite before ``pianist import-pig`` has run.
    """
    if suite is None or suite == "debug":
        return list(_SONGS)
    if suite == ORIGINAL_DEBUG_SUITE:
        return list(_ORIGINAL_SONGS)
    if suite in _BUILT_SUITES:
        return list(_BUILT_SUITES[suite])
    if suite == OPEN_SUITE:
        return list_open_songs()
    if suite in PIG_SUITES:
        return list_pig_songs(suite)
    raise ValueError(f"unknown suite {suite!r}; choose from {', '.join(SUITES)}")


def _unknown(name: str) -> UnknownSongError:
    known = list(_SONGS) + list(_ORIGINAL_SONGS) + list(_BUILT) + list_open_songs()
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
    hint = f"did you mean {', '.join(close)}? " if close else ""
    pig = ""
    if not close and re.fullmatch(r"[A-Z][A-Za-z0-9]+", name) and not pig_dataset_imported():
        # A RoboPianist-style name (repertoire-150 pieces are not all gym-style ids).
        pig = (
            f"; a PIG piece resolves once imported in {pig_data_dir()} (`pianist import-pig "
            f"DIR`; for an import made with --dest D, set {PIG_DIR_ENV}=D)"
        )
    return UnknownSongError(
        f"unknown song {name!r}: {hint}run `pianist songs` to list the built-in songs, "
        "or give a path to a .mid/.midi, PIG .txt or score (.musicxml, .mxl, .krn, .abc, .mei) "
        f"file{pig}"
    )


def song_description(name: str) -> str:
    """One-line description of built-in song ``name``.

    Raises:
        UnknownSongError: ``name`` is not a built-in song.
    """
    if name in _SONGS:
        return _SONGS[name][0]
    if name in _BUILT:
        suite, (description, _) = _BUILT[name]
        return f"{description} ({suite})"
    original = _original_name(name)
    if original is not None:
        return f"{_ORIGINAL_SONGS[original][0]} ({ORIGINAL_DEBUG_SUITE})"
    if name in list_open_songs():
        info = open_song_info(name)
        return (
            f"{info['composer']}: {info['title']}, {info['segment']['description']} ({OPEN_SUITE})"
        )
    raise _unknown(name)


def get_song(name: str) -> Song:
    """Build built-in song ``name`` (fully fingered): a debug song (ours or the original's) or
    an open-library piece.

    Raises:
        UnknownSongError: ``name`` is not a built-in song.
    """
    if name in _SONGS:
        return Song(notes=tuple(_SONGS[name][1]()), name=name)
    if name in _BUILT:
        return Song(notes=tuple(_BUILT[name][1][1]()), name=name)
    original = _original_name(name)
    if original is not None:
        return Song(notes=tuple(_ORIGINAL_SONGS[original][1]()), name=original)
    if name in list_open_songs():
        return load_open_song(name)
    raise _unknown(name)


def load_song(
    name_or_path: str | os.PathLike[str] | Song,
    out_of_range: Literal["error", "drop"] = "error",
    fingering: FingeringMode | None = None,
    *,
    as_written: bool = False,
) -> Song:
    """Resolve a song given as a :class:`Song`, a built-in name or a file path.

    Names: the debug songs, the original's (``robopianist-debug``, also by environment id
    ``RoboPianist-debug-TwinkleTwinkleLittleStar-v0``), the ``open-etude-12`` pieces, and
    (once ``pianist import-pig`` has run; looked up in ``$PIANIST_PIG``, else the user data
    folder, see :func:`pianist.music.pig_dataset.pig_data_dir`) the PIG pieces by RoboPianist name
    (``FrenchSuiteNo1Allemande``, ``RoboPianist-etude-12-FrenchSuiteNo1Allemande-v0``,
    ``pig-001``).
    ``.mid``/``.midi`` files go to :func:`read_midi` (no fingering), ``.txt`` files to
    :func:`read_pig`, ``.musicxml``/``.mxl``/``.xml``, ``.krn``, ``.abc`` and ``.mei`` scores to
    :func:`pianist.music.musicxml.read_score` (hands from the staves, the score's finger
    numbers; needs music21; ``BOOK.abc#X`` names one tune of an ABC book; ``as_written``
    reads a score once through with no ornaments, fermatas or articulations played:
    :data:`pianist.music.musicxml.AS_WRITTEN`); ``out_of_range`` is passed to each. A
    built-in name wins over a file of the same name in the working directory.

    ``fingering`` (None leaves the song as loaded) applies
    :func:`pianist.music.fingering.ensure_fingering`: "auto" estimates the missing fingers
    (for a MIDI file, hands come from its tracks/channels when they name them), "file"
    requires the file's own complete fingering, "robot" re-estimates every finger for this
    robot hand (keeping the song's hands), "none" returns it unfingered.

    Raises:
        UnknownSongError: not a built-in name and does not look like a path (close matches are
            suggested).
        MidiFileError: looks like a path (has a suffix or a directory part) but does not exist.
        MusicError: the file exists but its suffix is not .mid, .midi, .txt or MusicXML's; or
            any reader error; or ``fingering="file"`` and some notes have no finger.
        PigDatasetError: a PIG piece name before ``pianist import-pig`` has run.
    """
    song = _load_song(name_or_path, out_of_range, AS_WRITTEN if as_written else {})
    if fingering is None or fingering == "none":
        return song
    if (fingering == "auto" and not song.has_full_fingering) or fingering == "robot":
        hints = None
        if not isinstance(name_or_path, Song):
            path = Path(os.fspath(name_or_path))
            if path.suffix.lower() in (".mid", ".midi") and path.is_file():
                hints = midi_hand_hints(path, song)
        return assign_fingering(song, keep_existing=fingering == "auto", hands=hints)
    return ensure_fingering(song, fingering)


def _load_song(
    name_or_path: str | os.PathLike[str] | Song,
    out_of_range: Literal["error", "drop"],
    reading: Mapping[str, bool],
) -> Song:
    """:func:`load_song` without the fingering (``reading``: :func:`read_score`'s options)."""
    if isinstance(name_or_path, Song):
        return name_or_path
    text = os.fspath(name_or_path)
    builtin = text in _SONGS or text in _BUILT or _original_name(text) is not None
    if isinstance(name_or_path, str) and builtin:
        return get_song(text)
    if isinstance(name_or_path, str) and text in list_open_songs():
        return load_open_song(text)
    if isinstance(name_or_path, str) and not Path(text).exists():
        if is_pig_name(text) or text in ETUDE_12 or find_pig_song(text) is not None:
            return load_pig_song(text)
    path = Path(text)
    if not path.exists() and tune_reference(text) is not None:  # BOOK.abc#X
        return read_score(text, out_of_range=out_of_range, **reading)
    book, hash_mark, reference = text.partition("#")
    if not path.exists() and hash_mark and book.lower().endswith(".abc") and Path(book).is_file():
        raise MusicError(
            f"{text}: a tune of an ABC book is named BOOK.abc#X, X the number of its X: field, "
            f"not {reference!r}"
        )
    looks_like_path = bool(path.suffix) or "/" in text or os.sep in text
    if not path.exists():
        if looks_like_path or not isinstance(name_or_path, str):
            raise MidiFileError(f"{path}: file not found")
        raise _unknown(text)
    suffix = path.suffix.lower()
    if suffix in (".mid", ".midi"):
        return read_midi(path, out_of_range=out_of_range)
    if suffix == ".txt":
        return read_pig(path, out_of_range=out_of_range)
    if suffix in SCORE_SUFFIXES:
        return read_score(path, out_of_range=out_of_range, **reading)
    if path.is_dir():
        raise MusicError(f"{path}: is a directory, not a song file")
    raise MusicError(
        f"{path}: unsupported song file type (use .mid, .midi, a PIG .txt, a MusicXML score: "
        ".musicxml, .mxl, .xml, a Humdrum .krn, an ABC .abc or an MEI .mei)"
    )
