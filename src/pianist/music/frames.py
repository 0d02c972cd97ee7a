"""Goal frames: which keys, fingers and pedal are due at each control step of a song.

Frame rule (RoboPianist's, see the facts page section 4), with ``fps = 1 / dt``:

- ``T = int(duration_s * fps + 1)`` frames, ``duration_s = song.duration_s`` (last note or
  pedal end), so frame ``T - 1`` is the song's end. An empty song gives one empty frame.
- A note covers frames ``floor(onset_s * fps)`` .. ``ceil(offset_s * fps)``, both ends
  included (so always at least one frame), clipped to ``T - 1``. Products are rounded to
  1e-9 before floor/ceil so that e.g. 0.5 s * 20 is exactly frame 10, not 9.999...
- Re-struck key: when a note's first frame is at or before the frame after the previous note
  of the same key ends (no free frame between them), the previous note is cut to end two
  frames before the new one starts, leaving one frame where the key is not due so it must be
  released. If that would leave the previous note no frame at all, it keeps its first frame
  and the new note starts two frames later instead (and may vanish past the end).
- Pedal intervals cover frames the same way (no release frame is inserted for the pedal).
- ``fingers[t, key]`` is the finger (0..9) of the note covering ``key`` at ``t``, -1 if the key
  is not due or the note has no finger label; ``velocities[t, key]`` its MIDI velocity (1..127),
  0 where the key is not due.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pianist.music.notes import NUM_FINGERS, Song
from pianist.music.pitch import NUM_KEYS

#: Default control step of RoboPianist (20 Hz), seconds.
DEFAULT_DT = 0.05
#: MIDI's default velocity (mezzo-forte): what a due key's velocity is when none is given.
DEFAULT_VELOCITY = 80
# Tolerance digits for time * fps before floor/ceil: absorbs binary floating-point error.
_ROUND_DIGITS = 9


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, copy=True)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class GoalFrames:
    """Per-control-step goals of one song; all arrays are read-only.

    Attributes:
        keys: (T, 88) bool, key k (MIDI 21 + k) is due at frame t.
        sustain: (T,) bool, the pedal is due down at frame t.
        fingers: (T, 88) int8, finger 0..9 due on key k at frame t, -1 for none; only set where
            ``keys`` is True.
        dt: control step in seconds (> 0); frame t starts at t * dt.
        velocities: (T, 88) uint8, the MIDI velocity (1..127) of the note due on key k at
            frame t, 0 where none is due; not given (empty): 80 (mezzo-forte, MIDI's default)
            wherever a key is due.
        finger_mask: (T, 10) bool, computed: finger f is due at frame t.
        onsets: (T, 88) bool, computed: key k's note starts at frame t (due there and not
            at t - 1; the re-strike rule leaves a free frame between two notes of a key).
    """

    keys: np.ndarray
    sustain: np.ndarray
    fingers: np.ndarray
    dt: float
    velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, NUM_KEYS), np.uint8))
    finger_mask: np.ndarray = field(init=False, repr=False)
    onsets: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        keys = np.asarray(self.keys)
        sustain = np.asarray(self.sustain)
        fingers = np.asarray(self.fingers)
        if keys.dtype != np.bool_ or keys.ndim != 2 or keys.shape[1] != NUM_KEYS:
            raise ValueError(
                f"keys must be a (T, {NUM_KEYS}) bool array, got {keys.shape} {keys.dtype}"
            )
        num_frames = keys.shape[0]
        if num_frames < 1:
            raise ValueError("goal frames need at least one frame")
        if sustain.dtype != np.bool_ or sustain.shape != (num_frames,):
            raise ValueError(
                f"sustain must be a ({num_frames},) bool array, got {sustain.shape} {sustain.dtype}"
            )
        if fingers.dtype != np.int8 or fingers.shape != keys.shape:
            raise ValueError(
                f"fingers must be a {keys.shape} int8 array, got {fingers.shape} {fingers.dtype}"
            )
        if fingers.min() < -1 or fingers.max() >= NUM_FINGERS:
            raise ValueError(f"fingers must be -1 (none) or 0..{NUM_FINGERS - 1}")
        if np.any(fingers[~keys] != -1):
            raise ValueError("fingers may only be set (>= 0) where keys are due")
        dt = float(self.dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number of seconds > 0, got {self.dt!r}")
        velocities = np.asarray(self.velocities)
        if velocities.size == 0:  # not given
            velocities = np.where(keys, DEFAULT_VELOCITY, 0).astype(np.uint8)
        if velocities.dtype != np.uint8 or velocities.shape != keys.shape:
            raise ValueError(
                f"velocities must be a {keys.shape} uint8 array, got {velocities.shape} "
                f"{velocities.dtype}"
            )
        if np.any(velocities[~keys] != 0) or np.any(velocities[keys] == 0):
            raise ValueError("velocities must be 1..127 where keys are due and 0 elsewhere")
        mask = np.zeros((num_frames, NUM_FINGERS), dtype=bool)
        rows, cols = np.nonzero(fingers >= 0)
        mask[rows, fingers[rows, cols]] = True
        onsets = keys & ~np.vstack([np.zeros((1, NUM_KEYS), dtype=bool), keys[:-1]])
        object.__setattr__(self, "keys", _frozen(keys))
        object.__setattr__(self, "sustain", _frozen(sustain))
        object.__setattr__(self, "fingers", _frozen(fingers))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "velocities", _frozen(velocities))
        object.__setattr__(self, "finger_mask", _frozen(mask))
        object.__setattr__(self, "onsets", _frozen(onsets))

    @property
    def num_frames(self) -> int:
        """Number of frames T (= episode length in control steps)."""
        return int(self.keys.shape[0])

    @property
    def duration_s(self) -> float:
        """Episode length in seconds, ``T * dt`` (one control step per frame)."""
        return self.num_frames * self.dt

    def fingers_due(self, t: int) -> np.ndarray:
        """(10,) bool: fingers due at frame ``t``; all False past the last frame."""
        if t < 0:
            raise IndexError(f"frame {t} is negative")
        if t >= self.num_frames:
            return np.zeros(NUM_FINGERS, dtype=bool)
        return self.finger_mask[t]

    def goal_window(self, t: int, lookahead: int) -> np.ndarray:
        """(lookahead + 1, 89) bool: keys (88) and sustain (1) for frames t..t+lookahead.

        Rows past the last frame are all False, as RoboPianist zero-pads past the song's end.
        """
        if t < 0 or lookahead < 0:
            raise IndexError(f"need t >= 0 and lookahead >= 0, got t={t}, lookahead={lookahead}")
        out = np.zeros((lookahead + 1, NUM_KEYS + 1), dtype=bool)
        stop = min(t + lookahead + 1, self.num_frames)
        if stop > t:
            out[: stop - t, :NUM_KEYS] = self.keys[t:stop]
            out[: stop - t, NUM_KEYS] = self.sustain[t:stop]
        return out

    def with_lead_in(self, frames: int) -> GoalFrames:
        """These goals after ``frames`` empty frames (nothing due, pedal up).

        RoboPianist's ``initial_buffer_time``: silence before the first note, so that a player
        can take its place first (the debug songs start with a note due in the first step).
        Returns T + ``frames`` frames; ``frames`` = 0 returns ``self``.
        """
        if isinstance(frames, bool) or not isinstance(frames, int | np.integer) or frames < 0:
            raise ValueError(f"a lead-in needs a whole number of frames >= 0, got {frames!r}")
        if frames == 0:
            return self
        return GoalFrames(
            keys=np.concatenate([np.zeros((frames, NUM_KEYS), dtype=bool), self.keys]),
            sustain=np.concatenate([np.zeros(frames, dtype=bool), self.sustain]),
            fingers=np.concatenate([np.full((frames, NUM_KEYS), -1, np.int8), self.fingers]),
            dt=self.dt,
            velocities=np.concatenate([np.zeros((frames, NUM_KEYS), np.uint8), self.velocities]),
        )


def _first_frame(seconds: float, fps: float) -> int:
    return math.floor(round(seconds * fps, _ROUND_DIGITS))


def _last_frame(seconds: float, fps: float) -> int:
    return math.ceil(round(seconds * fps, _ROUND_DIGITS))


def num_goal_frames(duration_s: float, dt: float = DEFAULT_DT) -> int:
    """Frame count ``int(duration_s / dt + 1)`` (with the 1e-9 rounding tolerance)."""
    return int(round(duration_s * (1.0 / dt), _ROUND_DIGITS) + 1)


def goal_frames(song: Song, dt: float = DEFAULT_DT) -> GoalFrames:
    """Rasterise ``song`` into :class:`GoalFrames` at control step ``dt`` seconds.

    See the module docstring for the exact frame rule. Returns arrays of T frames,
    ``T = int(song.duration_s / dt + 1)``.
    """
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number of seconds > 0, got {dt!r}")
    fps = 1.0 / dt
    num_frames = num_goal_frames(song.duration_s, dt)
    last = num_frames - 1

    # [first, last] frame spans per note, fixed up per key for re-strikes before painting.
    spans: list[list[int]] = []
    previous_on_key: dict[int, list[int]] = {}
    for note in song.notes:  # sorted by onset, so per key in time order
        span = [_first_frame(note.onset_s, fps), min(_last_frame(note.offset_s, fps), last)]
        prev = previous_on_key.get(note.key)
        if prev is not None and span[0] <= prev[1] + 1:
            prev[1] = max(prev[0], span[0] - 2)
            if span[0] <= prev[1] + 1:
                span[0] = prev[1] + 2
                span[1] = max(span[1], span[0])
        spans.append(span)
        previous_on_key[note.key] = span

    keys = np.zeros((num_frames, NUM_KEYS), dtype=bool)
    fingers = np.full((num_frames, NUM_KEYS), -1, dtype=np.int8)
    velocities = np.zeros((num_frames, NUM_KEYS), dtype=np.uint8)
    for note, (first, end) in zip(song.notes, spans, strict=True):
        if first > last:
            continue  # pushed past the end by the re-strike rule
        end = min(end, last)
        keys[first : end + 1, note.key] = True
        fingers[first : end + 1, note.key] = -1 if note.finger is None else note.finger
        velocities[first : end + 1, note.key] = min(max(int(note.velocity), 1), 127)

    sustain = np.zeros(num_frames, dtype=bool)
    for start_s, end_s in song.sustain:
        sustain[_first_frame(start_s, fps) : min(_last_frame(end_s, fps), last) + 1] = True
    return GoalFrames(keys=keys, sustain=sustain, fingers=fingers, dt=dt, velocities=velocities)
