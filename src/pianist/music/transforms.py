"""Pure functions that return a modified copy of a :class:`~pianist.music.notes.Song`.

Fingers and hands are carried over unchanged (after a transposition they may no longer be a
comfortable fingering, but every note keeps a label).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

from pianist.music.errors import OutOfRangeError
from pianist.music.notes import Note, Song
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH


def stretch(song: Song, factor: float) -> Song:
    """Multiply every time by ``factor`` (> 0): 2.0 plays twice as slowly, 0.5 twice as fast."""
    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"stretch factor must be a finite number > 0, got {factor!r}")
    notes = tuple(
        dataclasses.replace(n, onset_s=n.onset_s * factor, offset_s=n.offset_s * factor)
        for n in song.notes
    )
    sustain = tuple((s * factor, e * factor) for s, e in song.sustain)
    return dataclasses.replace(song, notes=notes, sustain=sustain)


def delay(song: Song, seconds: float) -> Song:
    """Add ``seconds`` (>= 0) of silence before the song: every time moves later by it."""
    if not (math.isfinite(seconds) and seconds >= 0):
        raise ValueError(f"delay must be a finite number of seconds >= 0, got {seconds!r}")
    if seconds == 0:
        return song
    notes = tuple(
        dataclasses.replace(n, onset_s=n.onset_s + seconds, offset_s=n.offset_s + seconds)
        for n in song.notes
    )
    sustain = tuple((s + seconds, e + seconds) for s, e in song.sustain)
    return dataclasses.replace(song, notes=notes, sustain=sustain)


def transpose(song: Song, semitones: int, out_of_range: Literal["error", "drop"] = "error") -> Song:
    """Shift every pitch by ``semitones`` (12 = one octave up).

    Raises:
        OutOfRangeError: with ``out_of_range="error"`` when a shifted note leaves MIDI 21..108
            ("drop" leaves such notes out instead).
    """
    if out_of_range not in ("error", "drop"):
        raise ValueError(f"out_of_range must be 'error' or 'drop', got {out_of_range!r}")
    semitones = int(semitones)
    shifted = [n.pitch + semitones for n in song.notes]
    outside = [p for p in shifted if not LOWEST_PITCH <= p <= HIGHEST_PITCH]
    if outside and out_of_range == "error":
        raise OutOfRangeError(
            f"song {song.name or '(unnamed)'}: transposing by {semitones:+d} semitones puts "
            f"{len(outside)} note(s) outside MIDI {LOWEST_PITCH}..{HIGHEST_PITCH} "
            f"(pitches {min(outside)}..{max(outside)})"
        )
    notes = tuple(
        dataclasses.replace(n, pitch=p)
        for n, p in zip(song.notes, shifted, strict=True)
        if LOWEST_PITCH <= p <= HIGHEST_PITCH
    )
    return dataclasses.replace(song, notes=notes)


def _clip_shift(note: Note, start_s: float, end_s: float) -> Note:
    return dataclasses.replace(
        note,
        onset_s=max(note.onset_s, start_s) - start_s,
        offset_s=min(note.offset_s, end_s) - start_s,
    )


def _clip_intervals(
    intervals: tuple[tuple[float, float], ...], start_s: float, end_s: float
) -> tuple[tuple[float, float], ...]:
    """Intersect intervals with [start_s, end_s] and shift them by -start_s; drop empty ones."""
    clipped = ((max(s, start_s) - start_s, min(e, end_s) - start_s) for s, e in intervals)
    return tuple((s, e) for s, e in clipped if e > s)


def trim_silence(song: Song) -> Song:
    """Remove leading and trailing silence.

    Shifts the song so the first onset is at 0 s, and clips sustain to the span from the first
    onset to the last note offset (pedal before the music or after it changes nothing a player
    must do). A song without notes is returned unchanged.
    """
    if not song.notes:
        return song
    start = song.notes[0].onset_s  # notes are sorted by onset
    end = max(n.offset_s for n in song.notes)
    notes = tuple(_clip_shift(n, start, end) for n in song.notes)
    return dataclasses.replace(song, notes=notes, sustain=_clip_intervals(song.sustain, start, end))


def window(song: Song, start_s: float, end_s: float) -> Song:
    """Cut the excerpt ``[start_s, end_s]`` (seconds), shifted to begin at 0 s.

    Notes and pedal intervals that overlap the window are kept and clipped to it; the rest is
    dropped. The result may have no notes.
    """
    if not (math.isfinite(start_s) and math.isfinite(end_s) and 0 <= start_s < end_s):
        raise ValueError(f"window needs 0 <= start_s < end_s, got ({start_s}, {end_s})")
    notes = tuple(
        _clip_shift(n, start_s, end_s)
        for n in song.notes
        if n.onset_s < end_s and n.offset_s > start_s
    )
    return dataclasses.replace(
        song, notes=notes, sustain=_clip_intervals(song.sustain, start_s, end_s)
    )
