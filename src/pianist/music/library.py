"""Built-in debug songs written in code (every note fingered) and :func:`load_song`.

The songs follow RoboPianist's debug set (facts section 4): Twinkle Twinkle (one hand, 8 s,
14 notes), C and D major scales (one hand 15 notes / two hands 30 notes, 7.5 s) and a C major
chord progression (two hands, 4 s, 16 notes). Fingers use pianists' numbers 1 (thumb) ..
5 (little) in the tables below and are mapped to 0-4 (right) / 5-9 (left).
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Literal

from pianist.music.errors import MidiFileError, MusicError, UnknownSongError
from pianist.music.midi import read_midi
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.pig import read_pig
from pianist.music.pitch import name_to_pitch

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


def _scale_song(tonic: str, both_hands: bool) -> list[Note]:
    """Right hand from ``tonic`` in octave 4; with ``both_hands`` the left an octave lower."""
    notes = _scale_up_down(f"{tonic}4", RIGHT)
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


def list_songs() -> list[str]:
    """Names of the built-in songs, in a stable order."""
    return list(_SONGS)


def _unknown(name: str) -> UnknownSongError:
    close = difflib.get_close_matches(name, list(_SONGS), n=3, cutoff=0.5)
    hint = f"did you mean {', '.join(close)}? " if close else ""
    return UnknownSongError(
        f"unknown song {name!r}: {hint}run `pianist songs` to list the built-in songs, "
        "or give a path to a .mid/.midi or PIG .txt file"
    )


def song_description(name: str) -> str:
    """One-line description of built-in song ``name``.

    Raises:
        UnknownSongError: ``name`` is not a built-in song.
    """
    if name not in _SONGS:
        raise _unknown(name)
    return _SONGS[name][0]


def get_song(name: str) -> Song:
    """Build built-in song ``name`` (fully fingered, no sustain).

    Raises:
        UnknownSongError: ``name`` is not a built-in song.
    """
    if name not in _SONGS:
        raise _unknown(name)
    return Song(notes=tuple(_SONGS[name][1]()), name=name)


def load_song(
    name_or_path: str | os.PathLike[str] | Song,
    out_of_range: Literal["error", "drop"] = "error",
) -> Song:
    """Resolve a song given as a :class:`Song`, a built-in name or a file path.

    ``.mid``/``.midi`` files go to :func:`read_midi` (no fingering), ``.txt`` files to
    :func:`read_pig`; ``out_of_range`` is passed to both. A built-in name wins over a file of
    the same name in the working directory.

    Raises:
        UnknownSongError: not a built-in name and does not look like a path (close matches are
            suggested).
        MidiFileError: looks like a path (has a suffix or a directory part) but does not exist.
        MusicError: the file exists but its suffix is not .mid, .midi or .txt; or any reader
            error.
    """
    if isinstance(name_or_path, Song):
        return name_or_path
    text = os.fspath(name_or_path)
    if isinstance(name_or_path, str) and text in _SONGS:
        return get_song(text)
    path = Path(text)
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
    if path.is_dir():
        raise MusicError(f"{path}: is a directory, not a song file")
    raise MusicError(f"{path}: unsupported song file type (use .mid, .midi or a PIG .txt)")
