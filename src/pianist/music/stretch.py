"""The ``octaves`` suite: short pieces at an octave's stretch, fingered, for both hands.

An octave is 0.1645 m between the keys' press points; the Shadow hand with its wrist straight
spans ~0.13 m from the thumb to the little finger, turned towards the thumb and flexed
~0.17 m. These pieces ask for that stretch in the forms piano music uses it:

- ``block-octaves``: a C major scale in octaves, both hands, 0.5 s a step;
- ``broken-octaves``: the same scale, each octave's bottom then top (thumb, little finger);
- ``stride-bass``: a left hand leaping between a bass octave and a chord an octave up, under
  a right-hand melody;
- ``octave-chords``: root-position triads with the root doubled an octave up (C-E-G-C),
  both hands;
- ``seventh-chords``: four-note seventh chords in root position (a seventh's span), both
  hands;
- ``octave-melody``: a melody in octaves in the right hand over a walking left-hand bass.

Every note is on a white key (the turned hand plays no black key,
``forearm.plan_reaches``), and fingered as a pianist would (thumb and little finger on an
octave). Pitches are MIDI numbers; times in s.
"""

from __future__ import annotations

from collections.abc import Callable

from pianist.music.notes import Note

OCTAVE_SUITE = "octaves"

_STEP_S = 0.5
_C_MAJOR = (0, 2, 4, 5, 7, 9, 11, 12)  # semitones above C


def _right(number: int) -> int:
    return number - 1  # pianist's finger 1..5 -> 0..4


def _left(number: int) -> int:
    return number + 4  # pianist's finger 1..5 -> 5..9


def _scale() -> list[int]:
    """C4 up to C5 and back down: 15 pitches."""
    up = [60 + step for step in _C_MAJOR]
    return up + up[-2::-1]


def _block_octaves() -> list[Note]:
    notes = []
    for i, low in enumerate(_scale()):
        onset, offset = i * _STEP_S, (i + 1) * _STEP_S - 0.02
        notes += [
            Note(low, onset, offset, finger=_right(1)),
            Note(low + 12, onset, offset, finger=_right(5)),
        ]
        bass = low - 24
        notes += [
            Note(bass, onset, offset, finger=_left(5)),
            Note(bass + 12, onset, offset, finger=_left(1)),
        ]
    return notes


def _broken_octaves() -> list[Note]:
    notes = []
    half = _STEP_S / 2
    for i, low in enumerate(_scale()):
        onset = i * _STEP_S
        notes += [
            Note(low, onset, onset + half, finger=_right(1)),
            Note(low + 12, onset + half, onset + _STEP_S, finger=_right(5)),
            Note(low - 24, onset, onset + half, finger=_left(5)),
            Note(low - 12, onset + half, onset + _STEP_S, finger=_left(1)),
        ]
    return notes


def _stride_bass() -> list[Note]:
    # I - IV - V - I: beat 1 a bass octave, beat 2 a chord from the octave above it.
    bars = ((36, (48, 52, 55)), (41, (48, 53, 57)), (43, (47, 50, 55)), (36, (48, 52, 55)))
    melody = (72, 74, 76, 77, 77, 76, 74, 72)
    notes = []
    for bar, (bass, chord) in enumerate(bars):
        start = bar * 2 * _STEP_S
        notes += [
            Note(bass, start, start + _STEP_S - 0.02, finger=_left(5)),
            Note(bass + 12, start, start + _STEP_S - 0.02, finger=_left(1)),
        ]
        for pitch, number in zip(chord, (5, 3, 1), strict=True):
            notes.append(
                Note(pitch, start + _STEP_S, start + 2 * _STEP_S - 0.02, finger=_left(number))
            )
    for i, (pitch, number) in enumerate(zip(melody, (1, 2, 3, 4, 4, 3, 2, 1), strict=True)):
        notes.append(Note(pitch, i * _STEP_S, (i + 1) * _STEP_S - 0.02, finger=_right(number)))
    return notes


def _chords(shapes: tuple[tuple[int, ...], ...], seconds: float = 1.0) -> list[Note]:
    """Each shape (semitones above its root) on C, F, G, C, right hand from the fourth octave,
    left hand two octaves lower; fingers 1 2 3 5 (right), 5 3 2 1 (left)."""
    notes = []
    for i, (root, shape) in enumerate(zip((60, 65, 67, 60), shapes, strict=True)):
        onset, offset = i * seconds, (i + 1) * seconds - 0.02
        for step, right, left in zip(shape, (1, 2, 3, 5), (5, 3, 2, 1), strict=True):
            notes.append(Note(root + step, onset, offset, finger=_right(right)))
            notes.append(Note(root + step - 24, onset, offset, finger=_left(left)))
    return notes


def _octave_chords() -> list[Note]:
    major = (0, 4, 7, 12)
    return _chords((major, major, major, major))


def _seventh_chords() -> list[Note]:
    # Cmaj7, Fmaj7, G7, Cmaj7: the seventh above the root is 11 or 10 semitones.
    return _chords(((0, 4, 7, 11), (0, 4, 7, 11), (0, 4, 7, 10), (0, 4, 7, 11)))


def _octave_melody() -> list[Note]:
    melody = (67, 69, 71, 72, 71, 69, 67, 64)
    bass = (43, 45, 47, 48, 47, 45, 43, 40)
    notes = []
    for i, (top, low) in enumerate(zip(melody, bass, strict=True)):
        onset, offset = i * _STEP_S, (i + 1) * _STEP_S - 0.02
        notes += [
            Note(top - 12, onset, offset, finger=_right(1)),
            Note(top, onset, offset, finger=_right(5)),
            Note(low, onset, offset, finger=_left(3)),
        ]
    return notes


#: The suite's pieces: name -> (description, builder).
OCTAVE_SONGS: dict[str, tuple[str, Callable[[], list[Note]]]] = {
    "block-octaves": (
        "C major scale in block octaves, both hands, 60 notes, 7.5 s",
        _block_octaves,
    ),
    "broken-octaves": (
        "C major scale in broken octaves (bottom, top), both hands, 60 notes, 7.5 s",
        _broken_octaves,
    ),
    "stride-bass": (
        "stride bass (bass octave, then a chord) under a right-hand melody, 28 notes, 4 s",
        _stride_bass,
    ),
    "octave-chords": (
        "root-position triads with the octave doubled (C-E-G-C), both hands, 32 notes, 4 s",
        _octave_chords,
    ),
    "seventh-chords": (
        "root-position seventh chords (Cmaj7 Fmaj7 G7 Cmaj7), both hands, 32 notes, 4 s",
        _seventh_chords,
    ),
    "octave-melody": (
        "a melody in right-hand octaves over a left-hand bass, 24 notes, 4 s",
        _octave_melody,
    ),
}
