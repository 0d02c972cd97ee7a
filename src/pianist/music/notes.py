"""The song model: :class:`Note` (one key press) and :class:`Song` (notes plus sustain pedal)."""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable
from dataclasses import dataclass, field

from pianist.music.errors import MusicError, OutOfRangeError
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH

RIGHT = "right"
LEFT = "left"
HANDS = (RIGHT, LEFT)
#: Fingers 0-4 are the right thumb..little finger, 5-9 the left thumb..little finger.
NUM_FINGERS = 10


def hand_of_finger(finger: int) -> str:
    """Hand ("right" or "left") that owns ``finger`` (0-9)."""
    return RIGHT if finger < 5 else LEFT


def _as_int(value: object, what: str) -> int:
    # Accept NumPy integers too, but not bools or floats (a float pitch is a caller bug).
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise MusicError(f"note {what} must be an integer, got {value!r}")
    return int(value)


def _as_time(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise MusicError(f"note {what} must be a number of seconds, got {value!r}")
    seconds = float(value)
    if not math.isfinite(seconds):
        raise MusicError(f"note {what} must be finite, got {value!r}")
    return seconds


@dataclass(frozen=True)
class Note:
    """One piano note.

    Attributes:
        pitch: MIDI pitch, 21 (A0) .. 108 (C8).
        onset_s: key-down time in seconds, >= 0.
        offset_s: key-up time in seconds, > ``onset_s``.
        velocity: MIDI velocity 1..127.
        finger: 0-4 right thumb..little, 5-9 left thumb..little, or None (no label).
        hand: "right", "left" or None; derived from ``finger`` when only the finger is given.
    """

    pitch: int
    onset_s: float
    offset_s: float
    velocity: int = 80
    finger: int | None = None
    hand: str | None = None

    def __post_init__(self) -> None:
        pitch = _as_int(self.pitch, "pitch")
        if not LOWEST_PITCH <= pitch <= HIGHEST_PITCH:
            raise OutOfRangeError(
                f"note pitch {pitch} is outside the piano's range MIDI "
                f"{LOWEST_PITCH}..{HIGHEST_PITCH}"
            )
        onset = _as_time(self.onset_s, "onset")
        offset = _as_time(self.offset_s, "offset")
        if onset < 0:
            raise MusicError(f"note onset {onset} s is negative")
        if offset <= onset:
            raise MusicError(f"note offset {offset} s is not after its onset {onset} s")
        velocity = _as_int(self.velocity, "velocity")
        if not 1 <= velocity <= 127:
            raise MusicError(f"note velocity {velocity} is outside 1..127")
        finger = self.finger
        if finger is not None:
            finger = _as_int(finger, "finger")
            if not 0 <= finger < NUM_FINGERS:
                raise MusicError(f"note finger {finger} is outside 0..9")
        hand = self.hand
        if hand is not None and hand not in HANDS:
            raise MusicError(f"note hand {hand!r} is not 'right', 'left' or None")
        if finger is not None:
            if hand is None:
                hand = hand_of_finger(finger)
            elif hand != hand_of_finger(finger):
                raise MusicError(f"note finger {finger} belongs to the other hand than {hand!r}")
        # Normalise types (e.g. NumPy scalars) so that equality and hashing behave.
        object.__setattr__(self, "pitch", pitch)
        object.__setattr__(self, "onset_s", onset)
        object.__setattr__(self, "offset_s", offset)
        object.__setattr__(self, "velocity", velocity)
        object.__setattr__(self, "finger", finger)
        object.__setattr__(self, "hand", hand)

    @property
    def key(self) -> int:
        """Piano key index 0 (A0) .. 87 (C8)."""
        return self.pitch - LOWEST_PITCH

    @property
    def duration_s(self) -> float:
        """Length of the note in seconds."""
        return self.offset_s - self.onset_s


def _clean_sustain(
    intervals: Iterable[tuple[float, float]],
) -> tuple[tuple[float, float], ...]:
    """Validate pedal-down intervals (seconds), sort them and merge overlapping/touching ones."""
    cleaned: list[tuple[float, float]] = []
    for interval in intervals:
        try:
            start, end = interval
        except (TypeError, ValueError):
            raise MusicError(f"sustain interval {interval!r} is not a (start, end) pair") from None
        start = _as_time(start, "sustain start")
        end = _as_time(end, "sustain end")
        if start < 0 or end <= start:
            raise MusicError(f"sustain interval ({start}, {end}) s needs 0 <= start < end")
        cleaned.append((start, end))
    cleaned.sort()
    merged: list[tuple[float, float]] = []
    for start, end in cleaned:
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return tuple(merged)


@dataclass(frozen=True)
class Song:
    """A piece to play: notes sorted by (onset, pitch) plus sustain-pedal intervals.

    Attributes:
        notes: the notes, stored sorted by (onset_s, pitch).
        sustain: pedal-down (start_s, end_s) intervals, sorted, non-overlapping (merged).
        name: a label for messages and file names.

    A song without notes is a valid object (e.g. an empty window) but the file readers refuse
    to return one.
    """

    notes: tuple[Note, ...]
    sustain: tuple[tuple[float, float], ...] = ()
    name: str = field(default="")

    def __post_init__(self) -> None:
        notes = tuple(self.notes)
        for note in notes:
            if not isinstance(note, Note):
                raise MusicError(f"song {self.name!r}: {note!r} is not a Note")
        notes = tuple(sorted(notes, key=lambda n: (n.onset_s, n.pitch)))
        object.__setattr__(self, "notes", notes)
        object.__setattr__(self, "sustain", _clean_sustain(self.sustain))
        object.__setattr__(self, "name", str(self.name))

    @property
    def duration_s(self) -> float:
        """Seconds until the last note or pedal interval ends; 0.0 for an empty song."""
        ends = [n.offset_s for n in self.notes] + [end for _, end in self.sustain]
        return max(ends, default=0.0)

    @property
    def num_notes(self) -> int:
        """Number of notes."""
        return len(self.notes)

    @property
    def hands(self) -> frozenset[str]:
        """Hands ("right"/"left") named by at least one note; notes without a hand add nothing."""
        return frozenset(n.hand for n in self.notes if n.hand is not None)

    @property
    def fingering_coverage(self) -> float:
        """Fraction (0..1) of notes that carry a finger label; 0.0 for an empty song."""
        if not self.notes:
            return 0.0
        return sum(n.finger is not None for n in self.notes) / len(self.notes)

    @property
    def has_full_fingering(self) -> bool:
        """True when the song has notes and every one of them carries a finger."""
        return bool(self.notes) and all(n.finger is not None for n in self.notes)
