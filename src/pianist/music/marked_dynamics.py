"""The ``dynamics`` suite: short pieces whose notes carry very different MIDI velocities.

A robot pianist that plays only the right keys at the right time plays every note about as
loud as the next; these pieces ask for the loudness the score marks, in the forms piano
music marks it:

- ``crescendo-scale``: a C major scale up and down, both hands an octave apart, from
  pianissimo (velocity 30) up to fortissimo (110) at the top and back down;
- ``accents``: broken C major chords in the right hand, every third note accented (100
  against 50), over soft half-note fifths in the left (45);
- ``voiced-melody``: a right-hand melody (95) over a soft left-hand accompaniment (40);
- ``soft-melody-loud-bass``: the reverse, a soft melody (40) over a loud bass (105).

Every note is on a white key within a hand's reach (no shifts wider than a five-finger
position), fingered as a pianist would, so what the pieces measure is the loudness. Pitches
are MIDI numbers; times in s.
"""

from __future__ import annotations

from collections.abc import Callable

from pianist.music.notes import Note

DYNAMICS_SUITE = "dynamics"

_STEP_S = 0.4
_SCALE = (60, 62, 64, 65, 67, 69, 71, 72)


def _right(number: int) -> int:
    return number - 1  # pianist's finger 1..5 -> 0..4


def _left(number: int) -> int:
    return number + 4  # pianist's finger 1..5 -> 5..9


def _crescendo_scale() -> list[Note]:
    up_fingers = (1, 2, 3, 1, 2, 3, 4, 5)  # right hand; the left mirrors it
    left_fingers = (5, 4, 3, 2, 1, 3, 2, 1)
    pitches = list(_SCALE) + list(_SCALE[-2::-1])
    right = list(up_fingers) + list(up_fingers[-2::-1])
    left = list(left_fingers) + list(left_fingers[-2::-1])
    top = len(_SCALE) - 1
    notes = []
    for i, pitch in enumerate(pitches):
        # 30 at either end, 110 at the top of the scale, in even steps.
        velocity = round(30 + 80 * (1 - abs(i - top) / top))
        onset, offset = i * _STEP_S, (i + 1) * _STEP_S - 0.02
        notes.append(Note(pitch, onset, offset, velocity=velocity, finger=_right(right[i])))
        notes.append(Note(pitch - 12, onset, offset, velocity=velocity, finger=_left(left[i])))
    return notes


def _accents() -> list[Note]:
    pattern = ((60, 1), (64, 3), (67, 5))  # C E G with fingers 1 3 5
    notes = []
    for i in range(18):
        pitch, finger = pattern[i % 3]
        onset = i * _STEP_S / 2
        velocity = 100 if i % 3 == 0 else 50
        notes.append(Note(pitch, onset, onset + _STEP_S / 2 - 0.02, velocity, _right(finger)))
    for bar in range(3):
        onset, offset = bar * 3 * _STEP_S / 2, (bar + 1) * 3 * _STEP_S / 2 - 0.02
        notes.append(Note(48, onset, offset, velocity=45, finger=_left(5)))
        notes.append(Note(55, onset, offset, velocity=45, finger=_left(1)))
    return notes


def _melody_over_bass(melody_velocity: int, bass_velocity: int) -> list[Note]:
    melody = ((72, 1), (74, 2), (76, 3), (77, 4), (79, 5), (77, 4), (76, 3), (74, 2), (72, 1))
    bass = ((48, 5), (52, 3), (55, 1), (52, 3))  # C E G E under each pair of melody notes
    notes = []
    for i, (pitch, finger) in enumerate(melody):
        onset, offset = i * _STEP_S, (i + 1) * _STEP_S - 0.02
        notes.append(Note(pitch, onset, offset, velocity=melody_velocity, finger=_right(finger)))
    for i in range(2 * len(melody)):
        pitch, finger = bass[i % len(bass)]
        onset = i * _STEP_S / 2
        notes.append(
            Note(pitch, onset, onset + _STEP_S / 2 - 0.02, bass_velocity, finger=_left(finger))
        )
    return notes


#: The suite's pieces: name -> (description, builder).
DYNAMICS_SONGS: dict[str, tuple[str, Callable[[], list[Note]]]] = {
    "crescendo-scale": (
        "C major scale up and down, both hands, crescendo 30 -> 110 and back, 30 notes, 6 s",
        _crescendo_scale,
    ),
    "accents": (
        "broken C major chords, every third note accented (100 / 50), 24 notes, 3.6 s",
        _accents,
    ),
    "voiced-melody": (
        "a right-hand melody (95) over a soft left-hand accompaniment (40), 27 notes, 3.6 s",
        lambda: _melody_over_bass(95, 40),
    ),
    "soft-melody-loud-bass": (
        "a soft right-hand melody (40) over a loud left-hand bass (105), 27 notes, 3.6 s",
        lambda: _melody_over_bass(40, 105),
    ),
}
