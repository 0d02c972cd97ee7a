"""Generated etudes: short two-hand pieces built from the figures of real keyboard music.

A training corpus of chorales shows a policy four slow voices with the hands in place; real
pieces also have a left hand that leaps between a bass note and a chord (a rag's stride), broken
chords (Alberti basses, arpeggios), scale runs, repeated chords in dance rhythms (a polonaise)
and melodies with leaps. :func:`generate_etude` writes a few measures of such figures over a
chord progression, one figure per hand, from a seed alone (deterministic).

The notes carry their hand (right or left) and no finger: :func:`pianist.music.assign_fingering`
fingers them. Pitches are MIDI numbers, times seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pianist.music.notes import LEFT, RIGHT, Note, Song

#: Scale steps (semitones above the tonic) of the major and the harmonic minor scale.
SCALES = {"major": (0, 2, 4, 5, 7, 9, 11), "minor": (0, 2, 3, 5, 7, 8, 11)}

#: Progressions, one chord per measure, as scale degrees (0 = the tonic's chord).
PROGRESSIONS = ((0, 3, 4, 0), (0, 5, 1, 4), (0, 4, 5, 3), (0, 3, 0, 4), (5, 1, 4, 0))

RIGHT_FIGURES = ("melody", "scale", "arpeggio", "chords", "polonaise", "leaps", "repeated")
LEFT_FIGURES = ("stride", "alberti", "held", "walking", "broken")

#: Where each hand plays (MIDI pitches, both ends included): the right hand's figures stay
#: within its register, the left's bass notes go down to the low end and its chords up to the
#: high one, so the hands never share a key.
RIGHT_REGISTER = (60, 86)
LEFT_REGISTER = (33, 59)


@dataclass(frozen=True)
class Harmony:
    """The key and the chord of one measure: pitch classes of the scale and of the triad."""

    tonic: int
    scale: tuple[int, ...]
    degree: int

    def scale_pitches(self, low: int, high: int) -> list[int]:
        """The scale's pitches in [low, high], ascending."""
        classes = {(self.tonic + s) % 12 for s in self.scale}
        return [p for p in range(low, high + 1) if p % 12 in classes]

    def chord_classes(self) -> tuple[int, int, int]:
        """Root, third and fifth of the measure's triad (pitch classes)."""
        steps = [self.scale[(self.degree + k) % 7] for k in (0, 2, 4)]
        return tuple((self.tonic + s) % 12 for s in steps)  # type: ignore[return-value]

    def chord_pitches(self, low: int, high: int) -> list[int]:
        """The triad's pitches in [low, high], ascending."""
        classes = set(self.chord_classes())
        return [p for p in range(low, high + 1) if p % 12 in classes]

    def root_at_or_below(self, pitch: int) -> int:
        """The highest pitch of the chord's root at or below ``pitch``."""
        root = self.chord_classes()[0]
        return pitch - (pitch - root) % 12


@dataclass(frozen=True)
class Measure:
    """What a figure writes over: the measure's beats and harmony (figures count in beats;
    :func:`generate_etude` turns beats into seconds)."""

    beats: int
    harmony: Harmony


#: A note of a figure: (pitch, onset, length), onset and length in beats from the measure's
#: start.
Event = tuple[int, float, float]
#: A figure: (measure, random generator, the hand's state) -> its events. The state dict
#: carries what a figure continues from one measure to the next (the melody's last pitch, a
#: run's direction).
Figure = Callable[[Measure, np.random.Generator, dict], list[Event]]


def _lift(pitch: int) -> int:
    """``pitch`` raised by octaves into the left hand's register."""
    while pitch < LEFT_REGISTER[0]:
        pitch += 12
    return pitch


def _nearest(pitches: list[int], target: float) -> int:
    return min(pitches, key=lambda p: (abs(p - target), p))


def _melody(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    scale = m.harmony.scale_pitches(*RIGHT_REGISTER)
    i = scale.index(_nearest(scale, state.get("last", 72)))
    out: list[Event] = []
    t = 0.0
    while t < m.beats - 1e-9:
        length = float(rng.choice([0.5, 0.5, 1.0, 1.0, 1.5, 2.0]))
        length = min(length, m.beats - t)
        i = int(np.clip(i + rng.integers(-2, 3), 0, len(scale) - 1))
        out.append((scale[i], t, length))
        if rng.random() < 0.25 and i >= 2:  # a third below: a two-note chord
            out.append((scale[i - 2], t, length))
        t += length
    state["last"] = scale[i]
    return out


def _scale_run(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    scale = m.harmony.scale_pitches(*RIGHT_REGISTER)
    i = scale.index(_nearest(scale, state.get("last", 67)))
    step = state.get("direction", 1)
    out: list[Event] = []
    for k in range(m.beats * 4):  # sixteenths
        if not 0 <= i + step < len(scale):
            step = -step
        i += step
        out.append((scale[i], k * 0.25, 0.25))
    if rng.random() < 0.5:
        step = -step
    state["last"], state["direction"] = scale[i], step
    return out


def _arpeggio(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    low = int(rng.integers(RIGHT_REGISTER[0], RIGHT_REGISTER[0] + 8))
    tones = m.harmony.chord_pitches(low, low + 19)  # about an octave and a half
    path = tones + tones[-2:0:-1]
    unit = 0.5 if rng.random() < 0.5 else 0.25
    count = int(round(m.beats / unit))
    return [(path[k % len(path)], k * unit, unit) for k in range(count)]


def _block_chords(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    out: list[Event] = []
    unit = float(rng.choice([0.5, 1.0]))
    for k in range(int(round(m.beats / unit))):
        top = _nearest(m.harmony.chord_pitches(*RIGHT_REGISTER), int(rng.integers(68, 82)))
        below = m.harmony.chord_pitches(max(top - 9, RIGHT_REGISTER[0]), top - 1)[-2:]
        for p in [*below, top]:
            out.append((p, k * unit, unit))
    return out


def _polonaise(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    # The dance's rhythm (in beats): an eighth, two sixteenths, then eighths to the bar's end.
    onsets = [0.0, 0.5, 0.75] + [1.0 + 0.5 * k for k in range(2 * (m.beats - 1))]
    ends = [*onsets[1:], float(m.beats)]
    out: list[Event] = []
    chord_tones = m.harmony.chord_pitches(*RIGHT_REGISTER)
    for start, end in zip(onsets, ends, strict=True):
        top = _nearest(chord_tones, int(rng.integers(67, 84)))
        out.append((top, start, end - start))
        lower = [p for p in chord_tones if p < top]
        if lower and rng.random() < 0.6:
            out.append((_nearest(lower, top - 5), start, end - start))
    return _unique(out)


def _leaps(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    tones = m.harmony.chord_pitches(*RIGHT_REGISTER)
    out = []
    high = bool(rng.random() < 0.5)
    for k in range(m.beats * 2):
        half = tones[len(tones) // 2 :] if high else tones[: len(tones) // 2 + 1]
        out.append((int(rng.choice(half)), k * 0.5, 0.5))
        high = not high
    return out


def _repeated(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    tones = m.harmony.chord_pitches(*RIGHT_REGISTER)
    top = _nearest(tones, int(rng.integers(67, 80)))
    lower = [p for p in tones if p < top]
    pair = [top, _nearest(lower, top - 4)] if lower else [top]
    return [(p, k * 0.5, 0.5) for k in range(m.beats * 2) for p in pair]


def _stride(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    out: list[Event] = []
    for k in range(m.beats):
        if k % 2 == 0:  # the bass: the root, or on the third beat the fifth, low down
            bass = m.harmony.root_at_or_below(int(rng.integers(38, 46)))
            if k == 2:
                fifth = m.harmony.chord_classes()[2]
                bass = bass + (fifth - bass) % 12 - 12 * int(rng.random() < 0.5)
            out.append((_lift(bass), float(k), 1.0))
        else:  # the chord, a tenth or more above
            for p in m.harmony.chord_pitches(50, LEFT_REGISTER[1] - 1)[:3]:
                out.append((p, float(k), 1.0))
    return out


def _alberti(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    root = m.harmony.root_at_or_below(int(rng.integers(45, 53)))
    third, fifth = (root + (c - root) % 12 for c in m.harmony.chord_classes()[1:])
    pattern = [root, fifth, third, fifth]
    unit = 0.5 if rng.random() < 0.6 else 0.25
    return [(pattern[k % 4], k * unit, unit) for k in range(int(round(m.beats / unit)))]


def _held(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    root = _lift(m.harmony.root_at_or_below(int(rng.integers(40, 50))))
    tones = m.harmony.chord_pitches(root, root + 9)[:3]
    return [(p, 0.0, float(m.beats)) for p in tones]


def _walking(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    scale = m.harmony.scale_pitches(36, 55)
    start = m.harmony.root_at_or_below(int(rng.integers(40, 50)))
    i = scale.index(_nearest(scale, start))
    out: list[Event] = []
    for k in range(m.beats):
        out.append((scale[i], float(k), 1.0))
        i = int(np.clip(i + rng.choice([-2, -1, 1, 2]), 0, len(scale) - 1))
    return out


def _broken(m: Measure, rng: np.random.Generator, state: dict) -> list[Event]:
    root = _lift(m.harmony.root_at_or_below(int(rng.integers(36, 44))))
    fifth = root + (m.harmony.chord_classes()[2] - root) % 12
    third = root + 12 + (m.harmony.chord_classes()[1] - root) % 12  # a tenth above the root
    pattern = [root, fifth, third, fifth]
    return [(pattern[k % 4], k * 0.5, 0.5) for k in range(m.beats * 2)]


FIGURES: dict[str, Figure] = {
    "melody": _melody,
    "scale": _scale_run,
    "arpeggio": _arpeggio,
    "chords": _block_chords,
    "polonaise": _polonaise,
    "leaps": _leaps,
    "repeated": _repeated,
    "stride": _stride,
    "alberti": _alberti,
    "held": _held,
    "walking": _walking,
    "broken": _broken,
}


def _unique(events: list[Event]) -> list[Event]:
    """One event per (pitch, onset): a chord's doubled tone is played once."""
    seen: dict[tuple[int, float], Event] = {}
    for event in events:
        seen.setdefault((event[0], event[1]), event)
    return list(seen.values())


def generate_etude(
    seed: int,
    measures: int = 4,
    right: str | None = None,
    left: str | None = None,
    name: str | None = None,
) -> Song:
    """A two-hand etude of ``measures`` measures, the same for the same arguments.

    Args:
        seed: chooses everything left open: the key (any of the 12, major or minor), the
            progression, the tempo (quarter = 60-126), the metre (3/4 for a polonaise, else
            4/4 or 3/4), each hand's figure when not given, and the figures' notes.
        measures: number of measures (>= 1); the progression repeats past four.
        right, left: the hands' figures, from :data:`RIGHT_FIGURES` and :data:`LEFT_FIGURES`.
        name: the song's name (default ``etude-<seed>-<right>-<left>``).

    Returns:
        The song, every note with its hand and no finger; notes of one hand never overlap
        on a key (each sounds 90 % of its written length).

    Raises:
        ValueError: an unknown figure, or ``measures`` < 1.
    """
    if measures < 1:
        raise ValueError(f"an etude needs at least one measure, not {measures}")
    rng = np.random.default_rng(seed)
    right = right or str(rng.choice(RIGHT_FIGURES))
    left = left or str(rng.choice(LEFT_FIGURES))
    if right not in RIGHT_FIGURES or left not in LEFT_FIGURES:
        raise ValueError(
            f"unknown figure {right!r} / {left!r}: the right hand plays one of "
            f"{', '.join(RIGHT_FIGURES)}; the left one of {', '.join(LEFT_FIGURES)}"
        )
    tonic = int(rng.integers(0, 12))
    scale = SCALES[str(rng.choice(list(SCALES)))]
    progression = PROGRESSIONS[int(rng.integers(len(PROGRESSIONS)))]
    beats = 3 if right == "polonaise" or rng.random() < 0.25 else 4
    beat_s = 60.0 / float(rng.integers(60, 127))
    notes: list[Note] = []
    for hand, figure in ((RIGHT, right), (LEFT, left)):
        state: dict = {}
        for k in range(measures):
            harmony = Harmony(tonic, scale, progression[k % len(progression)])
            measure = Measure(beats, harmony)
            for pitch, onset, length in FIGURES[figure](measure, rng, state):
                start = (k * beats + onset) * beat_s
                notes.append(Note(int(pitch), start, start + 0.9 * length * beat_s, 80, None, hand))
    return Song(tuple(notes), name=name or f"etude-{seed}-{right}-{left}")
