"""How a performer plays a score's ornaments and grace notes: the notes each stands for.

A score writes a trill, a mordent, a turn, a tremolo or a grace note as a sign; a pianist
plays notes. These functions give those notes for one written note, in quarter lengths from
the written note's onset, for a reader that knows the ornament's pitches (the note above
or below, as the key and the sign's accidental make it) and the local tempo.

The pace: no ornament note is made shorter than ``unit`` (quarter lengths) where the written
note leaves room, and the reader sets ``unit`` to :data:`ORNAMENT_NOTE_S` at the local tempo.
A pianist's trill runs at 8-12 notes a second; the goal's frames are 20 a second, so a
note of 0.1 s is two frames, the fastest a key is pressed, released and pressed again
cleanly at the environment's control rate. Where the written note is too short for that pace
the ornament's notes share it evenly (a trill on a short note still has its three notes),
down to :data:`SHORTEST_NOTE_S`: the reader plays an ornament whose notes would be shorter
as its written note, and leaves such grace notes out (the goal could not show them).

Conventions (the common modern ones; a reader wanting others writes the notes out):

- trill: starts on the written note, alternates with the note above, and ends on the
  written note (an odd number of notes), over the written note's whole length, and on over
  the notes a tie carries it to;
- mordent (written note, note below, written note) and inverted mordent (with the note
  above): the first two notes at the pace, the written note holds the rest;
- turn (above, written, below, written) and inverted turn (below, written, above, written):
  on the beat, the last written note holding the rest; a delayed turn holds the written note
  first and plays (above, written, below, written) at the note's end;
- tremolo on one note: the note repeated at its strokes' value (one stroke: eighths; two:
  sixteenths; three: thirty-seconds), or at the pace where that is faster; between two notes
  (or chords): the two alternating so over both notes' time, from the first;
- grace notes: on the beat, before their note, which they shorten; each at the pace, and
  together at most half of their note;
- a rolled (arpeggiated) chord: its notes struck one after another from the lowest (from
  the highest for a downward roll), :data:`ROLL_STEP_S` apart, all held to the chord's end
  (a roll across both staves goes through both hands' notes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

#: The pace of ornaments and grace notes, in seconds per note: none is made shorter where the
#: written note leaves room (two of the goal's 20 Hz frames; see the module docstring).
ORNAMENT_NOTE_S = 0.1

#: The shortest ornament or grace note the reader plays, in seconds: one of the goal's frames.
SHORTEST_NOTE_S = 0.05

#: Time between the notes of a rolled chord, in seconds: one of the goal's frames (a pianist's
#: roll spreads its notes 30-60 ms apart).
ROLL_STEP_S = 0.05

#: One played note: (MIDI pitch, start, end), in quarter lengths from the written note's onset.
Played = tuple[int, float, float]

_EPS = 1e-9


def trill(principal: int, auxiliary: int, length: float, unit: float) -> list[Played]:
    """A trill on ``principal`` with ``auxiliary`` (the note above; below for an inverted
    trill) over ``length`` quarter lengths: an odd number of notes, at least three, none
    shorter than ``unit`` where the length allows, filling the length evenly."""
    count = max(3, math.floor(length / unit + _EPS) if unit > 0 else 3)
    if count % 2 == 0:
        count -= 1  # end on the written note
    step = length / count
    pitches = [principal if k % 2 == 0 else auxiliary for k in range(count)]
    return [(p, k * step, (k + 1) * step) for k, p in enumerate(pitches)]


def trill_carried_on(principal: int, auxiliary: int, length: float, step: float) -> list[Played]:
    """A trill carried on by a tie over a further ``length`` quarter lengths (the trill so far
    ended on ``principal``): from ``auxiliary``, alternating, ending on ``principal``; an even
    number of notes, at least two, none shorter than ``step`` where the length allows."""
    count = max(2, 2 * math.floor(length / (2 * step) + _EPS))
    each = length / count
    return [
        (auxiliary if k % 2 == 0 else principal, k * each, (k + 1) * each) for k in range(count)
    ]


def mordent(principal: int, auxiliary: int, length: float, unit: float) -> list[Played]:
    """A mordent on ``principal`` with ``auxiliary`` (the note below; above for an inverted
    mordent): two quick notes, then the written note holds the rest of ``length``."""
    step = min(unit, length / 3)
    return [(principal, 0.0, step), (auxiliary, step, 2 * step), (principal, 2 * step, length)]


def turn(
    principal: int, first: int, second: int, length: float, unit: float, *, delayed: bool = False
) -> list[Played]:
    """A turn: ``first``, ``principal``, ``second``, ``principal`` (the note above first, or
    below for an inverted turn). On the beat, the last note holds the rest of ``length``;
    ``delayed``, the written note holds first and the four notes end the length."""
    if delayed:
        step = min(unit, length / 5)
        held = length - 4 * step
        notes = [(principal, 0.0, held)]
        for k, pitch in enumerate((first, principal, second, principal)):
            notes.append((pitch, held + k * step, held + (k + 1) * step))
        return notes
    step = min(unit, length / 4)
    return [
        (first, 0.0, step),
        (principal, step, 2 * step),
        (second, 2 * step, 3 * step),
        (principal, 3 * step, length),
    ]


def tremolo(principal: int, length: float, strokes: int, unit: float) -> list[Played]:
    """A tremolo on one note: ``principal`` repeated at the value its ``strokes`` give (an
    eighth for one, halved for each more), or at ``unit`` where that is slower, filling
    ``length`` evenly (the written note alone when no repetition fits)."""
    value = max(0.5 ** max(1, strokes), unit)
    count = max(1, math.floor(length / value + _EPS))
    step = length / count
    return [(principal, k * step, (k + 1) * step) for k in range(count)]


def alternation(
    first: Sequence[int], second: Sequence[int], length: float, strokes: int, unit: float
) -> list[Played]:
    """A tremolo between two notes or chords (their pitches ``first`` and ``second``) over
    both notes' ``length``: the two alternating, from the first, at the value the
    ``strokes`` give (as :func:`tremolo`) or at ``unit`` where that is slower; an even
    number of strokes, at least two, filling the length evenly."""
    value = max(0.5 ** max(1, strokes), unit)
    count = max(2, 2 * math.floor(length / (2 * value) + _EPS))
    step = length / count
    return [
        (pitch, k * step, (k + 1) * step)
        for k in range(count)
        for pitch in (first if k % 2 == 0 else second)
    ]


def grace_length(count: int, length: float, unit: float) -> float:
    """How long each of ``count`` grace notes before a note of ``length`` quarter lengths
    lasts: ``unit``, or less so that together they take at most half of the note."""
    return min(unit, length / (2 * count))


def roll_starts(count: int, length: float, step: float) -> list[float]:
    """When each of a rolled chord's ``count`` notes starts, in quarter lengths from its onset,
    in the order struck: ``step`` apart, or closer so that the last starts within the first
    half of the chord's ``length``."""
    if count < 2:
        return [0.0] * count
    each = min(step, length / (2 * (count - 1)))
    return [k * each for k in range(count)]
