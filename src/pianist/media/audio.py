"""Piano audio from note events or songs, synthesised with a General MIDI SoundFont.

The synthesiser is TinySoundFont (the ``tinysoundfont`` wheel, self-contained) and the default
SoundFont is ``TimGM6mb.sf2``, which ships inside the ``pretty_midi`` package, so rendering
needs no system package and no download.

Install note: ``tinysoundfont`` declares ``pyaudio`` as a requirement, which has no Linux wheel
and needs PortAudio headers to build. PyAudio is only used for live playback, which this module
never does, so ``pip install --no-deps tinysoundfont`` is enough.

TinySoundFont ignores the sustain-pedal controller (MIDI CC 64), so the pedal is implemented
here the way a piano's damper pedal works: while it is down, a released key's note-off is held
back and sent when the pedal lifts (unless the key was pressed again meanwhile).

Loudness: the synthesiser's raw level depends on the soundfont and on how many notes sound at
once (one mezzo-forte note peaks near -22 dBFS). :func:`normalise_loudness` scales a recording
to a gated RMS loudness of :data:`TARGET_LOUDNESS_DBFS` (400 ms blocks, gated as EBU R128 gates
but without its K-weighting filter) unless that would push its peak over
:data:`PEAK_CEILING_DBFS`, in which case the peak sets the gain: one rule for every file, so a
performance and its score play back at comparable levels.
"""

from __future__ import annotations

import importlib.util
import math
import os
import wave
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.files import atomic_path
from pianist.media.errors import MediaError

if TYPE_CHECKING:
    from pianist.music import Song

LOWEST_PITCH = 21  # MIDI pitch of key 0 (A0)
NUM_KEYS = 88
PEDAL_KEY = -1
DEFAULT_SAMPLE_RATE = 44100
DEFAULT_TAIL_S = 1.0
DEFAULT_SOUNDFONT_NAME = "TimGM6mb.sf2"
#: Gated RMS loudness (dBFS) a written recording is scaled to (see :func:`loudness_dbfs`).
TARGET_LOUDNESS_DBFS = -18.0
#: No sample of a normalised recording exceeds this (dBFS).
PEAK_CEILING_DBFS = -1.0
_BLOCK_S = 0.4
_ABSOLUTE_GATE_DBFS = -70.0
_RELATIVE_GATE_DB = -10.0
_GAIN_ROUNDS = 4  # corrections of the loudness gain (see normalise_loudness)

# Event kinds, in the order they are applied when several happen at the same time: a key
# released and pressed again at one instant must restart the note, and a pedal change takes
# effect before the notes of that instant.
_PEDAL, _OFF, _ON = 0, 1, 2
_CHANNEL = 0


def default_soundfont() -> Path:
    """Path of the General MIDI SoundFont ``TimGM6mb.sf2`` shipped with ``pretty_midi``.

    The package is located without being imported (its import pulls in much more than a file).

    Raises:
        MediaError: ``pretty_midi`` is not installed or does not contain the file.
    """
    spec = importlib.util.find_spec("pretty_midi")
    if spec is None or not spec.submodule_search_locations:
        raise MediaError("the default soundfont comes with pretty_midi: pip install pretty_midi")
    for folder in spec.submodule_search_locations:
        path = Path(folder) / DEFAULT_SOUNDFONT_NAME
        if path.is_file():
            return path
    raise MediaError(f"soundfont not found: {DEFAULT_SOUNDFONT_NAME} is missing from pretty_midi")


def synthesize_events(
    events: np.ndarray,
    duration_s: float,
    *,
    sample_rate: int = DEFAULT_SAMPLE_RATE,
    soundfont: str | os.PathLike[str] | None = None,
    velocity: int = 80,
    program: int = 0,
    tail_s: float = DEFAULT_TAIL_S,
    gain_db: float = 0.0,
    velocities: np.ndarray | None = None,
) -> np.ndarray:
    """Render key and pedal events, e.g. :attr:`pianist.eval.Episode.note_events`.

    Each event is applied at its exact sample (``round(time_s * sample_rate)``): the synthesiser
    renders up to that sample, then the event is applied. At ``duration_s`` every key and the
    pedal are released and ``tail_s`` more seconds of release are rendered; events after
    ``duration_s`` are ignored.

    Args:
        events: (n, 3) rows (time s, key 0-87 or -1 for the sustain pedal, 1 on / 0 off), in
            any order (stable-sorted by time here).
        duration_s: seconds of performance, >= 0.
        sample_rate: output rate in Hz.
        soundfont: an .sf2/.sf3 file; None for :func:`default_soundfont`.
        velocity: MIDI velocity 1-127 of every note, unless ``velocities`` is given.
        velocities: None, or (n,) MIDI velocities aligned with ``events`` (read on key-on rows,
            1-127 there), e.g. from :func:`pianist.media.dynamics.episode_velocities`.
        program: General MIDI program 0-127 of bank 0 (0 is the acoustic grand piano).
        tail_s: seconds rendered after ``duration_s``, >= 0.
        gain_db: output gain in dB (0: one mezzo-forte note peaks near 0.08).
    Returns:
        (round((duration_s + tail_s) * sample_rate), 2) float32 stereo samples, nominally in
        [-1, 1] (loud chords may exceed it; :func:`write_wav` clips).
    Raises:
        MediaError: bad arguments or events, a missing or unreadable soundfont.
    """
    events = np.asarray(events, dtype=np.float64)
    if events.size == 0:
        events = events.reshape(0, 3)
    if events.ndim != 2 or events.shape[1] != 3:
        raise MediaError(f"note events must have shape (n, 3), not {events.shape}")
    if not np.all(np.isfinite(events)):
        raise MediaError("note events contain NaN or Inf")
    keys = events[:, 1]
    if np.any(keys != np.round(keys)) or np.any((keys < PEDAL_KEY) | (keys >= NUM_KEYS)):
        raise MediaError(f"note event keys must be integers in -1..{NUM_KEYS - 1}")
    velocity = _check_midi_value(velocity, "velocity", low=1)
    per_event = np.full(len(events), velocity, dtype=int)
    if velocities is not None:
        given = np.asarray(velocities)
        if given.shape != (len(events),) or not np.all(np.isfinite(given)):
            raise MediaError(f"velocities must be {len(events)} finite numbers, one per event")
        on_rows = (keys != PEDAL_KEY) & (events[:, 2] != 0)
        if np.any((given[on_rows] < 1) | (given[on_rows] > 127)):
            raise MediaError("velocities of key-on events must be in 1..127")
        per_event = np.where(on_rows, np.round(given), velocity).astype(int)
    order = np.argsort(events[:, 0], kind="stable")
    schedule = []
    for (time_s, key, on), vel in zip(
        events[order].tolist(), per_event[order].tolist(), strict=True
    ):
        if key == PEDAL_KEY:
            schedule.append((time_s, _PEDAL, int(on != 0), 0))
        else:
            kind = _ON if on != 0 else _OFF
            schedule.append((time_s, kind, LOWEST_PITCH + int(key), vel))
    return _render(schedule, duration_s, sample_rate, soundfont, program, tail_s, gain_db)


def synthesize_song(
    song: Song,
    *,
    sample_rate: int = DEFAULT_SAMPLE_RATE,
    soundfont: str | os.PathLike[str] | None = None,
    velocity: int | None = None,
    program: int = 0,
    tail_s: float = DEFAULT_TAIL_S,
    gain_db: float = 0.0,
) -> np.ndarray:
    """Render a :class:`pianist.music.Song`: its notes and sustain-pedal intervals.

    Args:
        song: the song; it lasts ``song.duration_s``.
        velocity: None to use each note's velocity, or one MIDI velocity 1-127 for all.
        sample_rate, soundfont, program, tail_s, gain_db: as in :func:`synthesize_events`.
    Returns:
        (round((song.duration_s + tail_s) * sample_rate), 2) float32 stereo samples.
    Raises:
        MediaError: bad arguments, a missing or unreadable soundfont.
    """
    if velocity is not None:
        velocity = _check_midi_value(velocity, "velocity", low=1)
    schedule = []
    for note in song.notes:
        note_velocity = velocity if velocity is not None else int(note.velocity)
        schedule.append((float(note.onset_s), _ON, int(note.pitch), note_velocity))
        schedule.append((float(note.offset_s), _OFF, int(note.pitch), 0))
    for start, end in song.sustain:
        schedule.append((float(start), _PEDAL, 1, 0))
        schedule.append((float(end), _PEDAL, 0, 0))
    return _render(schedule, song.duration_s, sample_rate, soundfont, program, tail_s, gain_db)


def write_wav(
    samples: np.ndarray, path: str | os.PathLike[str], sample_rate: int = DEFAULT_SAMPLE_RATE
) -> None:
    """Write float samples as a 16-bit PCM WAV file, atomically (temporary file + rename).

    Args:
        samples: (n, 2) stereo or (n,) mono floats in [-1, 1]; values outside are clipped.
        path: the .wav file to write; its folder must exist.
        sample_rate: Hz.
    Raises:
        MediaError: bad samples or rate, or the file cannot be written.
    """
    samples = np.asarray(samples)
    if samples.ndim == 1:
        samples = samples[:, None]
    if samples.ndim != 2 or samples.shape[1] not in (1, 2):
        raise MediaError(f"samples must have shape (n,) or (n, 2), not {samples.shape}")
    if not np.all(np.isfinite(samples)):
        raise MediaError("samples contain NaN or Inf")
    sample_rate = _check_sample_rate(sample_rate)
    pcm = np.round(np.clip(samples, -1.0, 1.0) * 32767.0).astype("<i2")
    path = Path(path)
    with atomic_path(path, suffix=".wav", error=MediaError) as tmp:
        try:
            with wave.open(str(tmp), "wb") as w:
                w.setnchannels(pcm.shape[1])
                w.setsampwidth(2)
                w.setframerate(sample_rate)
                w.writeframes(pcm.tobytes())
        except OSError as exc:
            raise MediaError(f"cannot write {path}: {exc.strerror or exc}") from None


def loudness_dbfs(samples: np.ndarray, sample_rate: int = DEFAULT_SAMPLE_RATE) -> float:
    """Gated RMS loudness of a recording, dB relative to a full-scale square wave.

    The mean square over both channels of each 400 ms block (consecutive, the last partial one
    dropped unless it is the only one) is a block's power; blocks under -70 dBFS are dropped
    (silence), then those more than 10 dB under the mean of the rest (pauses, release tails);
    the loudness is the mean power of the blocks left. A pure sine of amplitude 1 reads -3 dBFS.

    Args:
        samples: (n,) or (n, channels) floats.
        sample_rate: Hz.
    Returns:
        dBFS, or -inf for a recording with no block above -70 dBFS.
    """
    x = np.asarray(samples, dtype=np.float64)
    x = x[:, None] if x.ndim == 1 else x
    block = max(1, round(_BLOCK_S * sample_rate))
    count = max(1, len(x) // block)
    power = np.array([np.mean(x[i * block : (i + 1) * block] ** 2) for i in range(count)])
    with np.errstate(divide="ignore"):
        level = 10 * np.log10(power)
    kept = power[level > _ABSOLUTE_GATE_DBFS]
    if kept.size == 0:
        return -math.inf
    relative = 10 * math.log10(float(kept.mean())) + _RELATIVE_GATE_DB
    kept = kept[10 * np.log10(kept) > relative]
    return 10 * math.log10(float(kept.mean()))


def normalise_loudness(
    samples: np.ndarray,
    sample_rate: int = DEFAULT_SAMPLE_RATE,
    *,
    target_dbfs: float = TARGET_LOUDNESS_DBFS,
    ceiling_dbfs: float = PEAK_CEILING_DBFS,
) -> tuple[np.ndarray, float]:
    """Scale ``samples`` to ``target_dbfs`` (:func:`loudness_dbfs`), or less if the peak would
    pass ``ceiling_dbfs``.

    Returns:
        (scaled float32 samples of the same shape, gain applied in dB); a silent recording
        comes back unchanged with a gain of 0 dB.
    """
    x = np.asarray(samples, dtype=np.float32)
    loudness = loudness_dbfs(x, sample_rate)
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if not math.isfinite(loudness) or peak == 0.0:
        return x, 0.0
    # The -70 dBFS gate is absolute, so scaling moves quiet blocks (release tails) across
    # it and the loudness is not exactly linear in the gain: correct the gain on the scaled
    # recording a few times, keeping the closest.
    gain_db, best, miss = target_dbfs - loudness, target_dbfs - loudness, math.inf
    for _ in range(_GAIN_ROUNDS):
        error = target_dbfs - loudness_dbfs(x * np.float32(10 ** (gain_db / 20)), sample_rate)
        if abs(error) < miss:
            best, miss = gain_db, abs(error)
        if abs(error) < 0.01:
            break
        gain_db += error
    gain_db = min(best, ceiling_dbfs - 20 * math.log10(peak))
    return (x * np.float32(10 ** (gain_db / 20))).astype(np.float32), gain_db


def stereo_comparison(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """A stereo track with ``left``'s mono mix on the left and ``right``'s on the right.

    Args:
        left, right: (n,) or (n, channels) floats; the shorter is padded with silence.
    Returns:
        (max(n_left, n_right), 2) float32.
    """
    mixes = []
    for track in (left, right):
        x = np.asarray(track, dtype=np.float32)
        mixes.append(x if x.ndim == 1 else x.mean(axis=1))
    n = max(len(m) for m in mixes)
    out = np.zeros((n, 2), dtype=np.float32)
    for channel, mix in enumerate(mixes):
        out[: len(mix), channel] = mix
    return out


# --------------------------------------------------------------------------------- internals


def _check_midi_value(value: Any, name: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise MediaError(f"{name} must be an integer, not {value!r}")
    if not low <= int(value) <= 127:
        raise MediaError(f"{name} must be in {low}..127, not {value}")
    return int(value)


def _check_sample_rate(sample_rate: Any) -> int:
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, int | np.integer):
        raise MediaError(f"sample rate must be an integer number of Hz, not {sample_rate!r}")
    if not 1000 <= int(sample_rate) <= 384000:
        raise MediaError(f"sample rate must be in 1000..384000 Hz, not {sample_rate}")
    return int(sample_rate)


def _check_seconds(value: Any, name: str) -> float:
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        raise MediaError(f"{name} must be a number of seconds, not {value!r}") from None
    if not math.isfinite(seconds) or seconds < 0:
        raise MediaError(f"{name} must be a finite number of seconds >= 0, not {value!r}")
    return seconds


def check_soundfont(soundfont: str | os.PathLike[str] | None, program: int = 0) -> Path:
    """The soundfont that will be used, checked to load and to hold ``program``.

    Returns:
        The path (the default soundfont when ``soundfont`` is None).
    Raises:
        MediaError: a missing or unreadable file, no such program, no tinysoundfont.
    """
    _load_synth(soundfont, _check_midi_value(program, "program"), DEFAULT_SAMPLE_RATE, 0.0)
    return default_soundfont() if soundfont is None else Path(soundfont)


def _load_synth(
    soundfont: str | os.PathLike[str] | None, program: int, sample_rate: int, gain_db: float
) -> Any:
    """A TinySoundFont synthesiser with ``program`` of bank 0 on channel 0."""
    path = default_soundfont() if soundfont is None else Path(soundfont)
    if path.is_dir():
        raise MediaError(f"soundfont {path} is a folder, not a .sf2/.sf3 file")
    if not path.is_file():
        raise MediaError(f"soundfont not found: {path}")
    try:
        import tinysoundfont
    except ImportError:
        raise MediaError(
            "audio synthesis needs tinysoundfont: pip install --no-deps 'tinysoundfont>=0.3.7'"
        ) from None
    synth = tinysoundfont.Synth(gain=gain_db, samplerate=sample_rate)
    try:
        sfid = synth.sfload(str(path))
    except (RuntimeError, OSError):
        raise MediaError(f"cannot read soundfont {path}: not a readable SF2/SF3 file") from None
    if synth.sfpreset_name(sfid, 0, program) is None:
        raise MediaError(f"soundfont {path} has no program {program} in bank 0")
    try:
        synth.program_select(_CHANNEL, sfid, 0, program)
    except RuntimeError as exc:
        raise MediaError(f"soundfont {path}: cannot select program {program}: {exc}") from exc
    return synth


def _render(
    schedule: Iterable[tuple[float, int, int, int]],
    duration_s: float,
    sample_rate: int,
    soundfont: str | os.PathLike[str] | None,
    program: int,
    tail_s: float,
    gain_db: float,
) -> np.ndarray:
    """Render (time s, kind, pitch or pedal state, velocity) events; see synthesize_events."""
    duration_s = _check_seconds(duration_s, "duration")
    tail_s = _check_seconds(tail_s, "tail")
    sample_rate = _check_sample_rate(sample_rate)
    program = _check_midi_value(program, "program")
    try:
        gain_db = float(gain_db)
    except (TypeError, ValueError):
        raise MediaError(f"gain must be a number of dB, not {gain_db!r}") from None
    if not math.isfinite(gain_db):
        raise MediaError(f"gain must be a finite number of dB, not {gain_db}")
    synth = _load_synth(soundfont, program, sample_rate, gain_db)

    total = round((duration_s + tail_s) * sample_rate)
    end = min(round(duration_s * sample_rate), total)
    out = np.zeros((total, 2), dtype=np.float32)
    done = 0  # samples rendered so far

    def render_until(sample: int) -> None:
        nonlocal done
        if sample > done:
            # Render straight into the output array (a contiguous block of float32 pairs).
            synth.generate(sample - done, buffer=out[done:sample].data.cast("B"))
            done = sample

    down: set[int] = set()  # pitches whose key is down
    held: set[int] = set()  # pitches released while the pedal was down, still sounding
    pedal = False
    # Time order; events at the very same time in kind order (see _PEDAL, _OFF, _ON).
    ordered = sorted(
        (max(0, round(t * sample_rate)), t, kind, value, vel) for t, kind, value, vel in schedule
    )
    for sample, _, kind, value, vel in ordered:
        if sample > end:
            break
        render_until(sample)
        if kind == _PEDAL:
            pedal = bool(value)
            if not pedal:
                for pitch in held - down:
                    synth.noteoff(_CHANNEL, pitch)
                held.clear()
        elif kind == _ON:
            if value in down or value in held:
                # Restrike: end the old voice first (TinySoundFont would layer a second one).
                synth.noteoff(_CHANNEL, value)
                held.discard(value)
            synth.noteon(_CHANNEL, value, vel)
            down.add(value)
        elif value in down:
            down.discard(value)
            if pedal:
                held.add(value)
            else:
                synth.noteoff(_CHANNEL, value)
    render_until(end)
    synth.notes_off(_CHANNEL)  # the performance is over: release everything into the tail
    render_until(total)
    return out
