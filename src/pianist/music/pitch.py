"""Spelled pitch names (``C#4``, ``Bb3``) to MIDI numbers and back; C4 = 60."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence

from pianist.music.errors import MusicError, OutOfRangeError

#: Lowest and highest MIDI pitch of the 88-key piano (A0 and C8).
LOWEST_PITCH = 21
HIGHEST_PITCH = 108
NUM_KEYS = HIGHEST_PITCH - LOWEST_PITCH + 1

_SHARP_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
_STEP = {"C": 0, "D": 2, "E": 4, "F": 5, "G": 7, "A": 9, "B": 11}
# Letter, any run of sharps or flats, then an octave that may be negative (C-1 = MIDI 0).
_NAME_RE = re.compile(r"^([A-Ga-g])([#b]*)(-?\d+)$")


def out_of_range_error(path: str | os.PathLike[str], pitches: Sequence[int]) -> OutOfRangeError:
    """The error a song file's reader raises for its notes outside the piano's keys (the
    pitches of those notes), naming how to leave them out instead."""
    return OutOfRangeError(
        f"{path}: {len(pitches)} note(s) outside the piano's range MIDI "
        f"{LOWEST_PITCH}..{HIGHEST_PITCH} (pitches {min(pitches)}..{max(pitches)}); "
        "leave them out with out_of_range='drop' (pianist play --out-of-range drop)"
    )


def pitch_to_name(pitch: int) -> str:
    """Spell MIDI ``pitch`` (0..127) with sharps, e.g. 61 -> ``"C#4"``, 21 -> ``"A0"``."""
    if not 0 <= int(pitch) <= 127:
        raise MusicError(f"MIDI pitch {pitch} is outside 0..127")
    pitch = int(pitch)
    return f"{_SHARP_NAMES[pitch % 12]}{pitch // 12 - 1}"


def name_to_pitch(name: str) -> int:
    """Parse a spelled pitch such as ``"Db4"``, ``"C#4"``, ``"B#3"`` or ``"A0"`` to MIDI (0..127).

    ``#`` raises and ``b`` lowers by a semitone (repeatable, e.g. ``F##4``); the octave number
    follows scientific pitch notation (C4 = 60) and may be negative.
    """
    match = _NAME_RE.match(name.strip())
    if match is None:
        raise MusicError(f"cannot read pitch name {name!r} (expected e.g. C4, C#4 or Db4)")
    letter, accidentals, octave = match.groups()
    pitch = (
        (int(octave) + 1) * 12
        + _STEP[letter.upper()]
        + accidentals.count("#")
        - accidentals.count("b")
    )
    if not 0 <= pitch <= 127:
        raise MusicError(f"pitch name {name!r} is MIDI {pitch}, outside 0..127")
    return pitch
