"""Read and write Standard MIDI Files (via mido) as :class:`~pianist.music.notes.Song`.

Reading conventions (a caller should know these):

- Formats 0 and 1, any number of tracks and channels; all tracks are merged on one timeline and
  tempo changes (from any track) apply from their tick onwards. Format 2 and SMPTE time
  division are refused.
- ``note_on`` with velocity 0 is a note-off.
- The piano has one key per pitch, so notes are tracked per pitch across channels. A note-on of
  a pitch that is already sounding ends the sounding note at that moment and starts a new one.
  Note-offs are matched first-in-first-out: each closes the oldest note-on of that pitch still
  waiting for its note-off (if that note was already cut short by a re-strike, the note-off is
  simply consumed). Notes still open at the end of the file close at the end time.
- Notes of zero length (note-off at the note-on's tick) are dropped, also when written
  note-off first (a note-off that closes nothing, then at the same tick a note-on of that
  pitch on that channel: music21 writes grace notes so). Read in file order, that note-on
  would wait for the pitch's next note-off, however far away.
- Notes on MIDI channel 10 (``PERCUSSION_CHANNEL``, 9 counted from 0) are left out: General
  MIDI plays drums there, and a drum hit's note number names an instrument, not a pitch.
- Sustain comes from CC64 on any channel: value >= 64 is pedal down, < 64 pedal up.
- Hand and finger are never read from MIDI: every note has ``hand=None, finger=None``.
- Absurd files are refused: any tempo below 1 or above 1000 BPM, or a timeline past one hour.
"""

from __future__ import annotations

import io
import os
from collections import deque
from pathlib import Path
from typing import Literal

import mido

from pianist.files import write_bytes_atomic
from pianist.music.errors import MidiFileError, one_line
from pianist.music.fileio import require_file
from pianist.music.notes import Note, Song
from pianist.music.pitch import HIGHEST_PITCH, LOWEST_PITCH, out_of_range_error

#: The General MIDI percussion channel (channel 10, counted from 0): its notes are drums.
PERCUSSION_CHANNEL = 9
#: Longest timeline accepted by :func:`read_midi`, seconds.
MAX_DURATION_S = 3600.0
#: Tempo limits accepted by :func:`read_midi`, beats per minute.
MIN_BPM = 1.0
MAX_BPM = 1000.0
#: Resolution and tempo used by :func:`write_midi`: 480 ticks per beat at 120 BPM = 960 ticks/s.
WRITE_TICKS_PER_BEAT = 480
WRITE_TEMPO_US = 500_000
_WRITE_TICKS_PER_S = WRITE_TICKS_PER_BEAT * 1_000_000 / WRITE_TEMPO_US
_SUSTAIN_CC = 64
_DEFAULT_TEMPO_US = 500_000  # the MIDI standard's tempo until the first set_tempo

OutOfRange = Literal["error", "drop"]


def _load(path: Path) -> mido.MidiFile:
    require_file(path, MidiFileError, "MIDI file")
    try:
        with path.open("rb") as handle:
            magic = handle.read(4)
    except OSError as exc:
        raise MidiFileError(f"{path}: cannot read MIDI file ({exc.strerror or exc})") from exc
    if magic != b"MThd":
        raise MidiFileError(f"{path}: not a MIDI file (no 'MThd' header)")
    try:
        midi = mido.MidiFile(path)
    except EOFError as exc:
        raise MidiFileError(f"{path}: truncated MIDI file (ends in the middle of data)") from exc
    except Exception as exc:
        # mido's parser raises a wide, undocumented mix (OSError, ValueError, KeyError,
        # IndexError, struct.error, ...) on corrupt input; all mean the same to a caller.
        detail = one_line(exc) or type(exc).__name__
        raise MidiFileError(f"{path}: corrupt MIDI file ({detail})") from exc
    if midi.type not in (0, 1):
        raise MidiFileError(f"{path}: MIDI format {midi.type} is not supported (only 0 and 1)")
    if midi.ticks_per_beat == 0:
        raise MidiFileError(f"{path}: corrupt MIDI file (its header gives 0 ticks per beat)")
    if midi.ticks_per_beat < 0:
        raise MidiFileError(f"{path}: SMPTE time division is not supported (need ticks per beat)")
    return midi


class _OpenNote:
    """A note-on waiting for its note-off; ``end_s`` is set early if a re-strike cut it."""

    __slots__ = ("pitch", "onset_s", "velocity", "end_s")

    def __init__(self, pitch: int, onset_s: float, velocity: int) -> None:
        self.pitch = pitch
        self.onset_s = onset_s
        self.velocity = velocity
        self.end_s: float | None = None


def read_midi(path: str | os.PathLike[str], *, out_of_range: OutOfRange = "error") -> Song:
    """Read a MIDI file into a :class:`Song` (times in seconds, ``hand``/``finger`` None).

    Args:
        path: a ``.mid``/``.midi`` file, format 0 or 1.
        out_of_range: "error" raises :class:`OutOfRangeError` when any note lies outside MIDI
            21..108; "drop" silently leaves such notes out.

    Raises:
        MidiFileError: missing, directory, empty, not MIDI, truncated or corrupt file; no notes
            (drums alone included); tempo outside 1..1000 BPM; timeline longer than one hour.
        OutOfRangeError: notes outside the piano's keys with ``out_of_range="error"``.
    """
    if out_of_range not in ("error", "drop"):
        raise ValueError(f"out_of_range must be 'error' or 'drop', got {out_of_range!r}")
    path = Path(path)
    midi = _load(path)
    tpb = midi.ticks_per_beat

    # Seconds are computed per tempo segment (base + ticks * seconds-per-tick) rather than by
    # summing per-message floats, so long files do not accumulate rounding error.
    tempo = _DEFAULT_TEMPO_US
    segment_tick, segment_s = 0, 0.0
    tick, now = 0, 0.0
    waiting: dict[int, deque[_OpenNote]] = {}
    finished: list[tuple[int, float, float, int]] = []
    pedal_since: float | None = None
    sustain: list[tuple[float, float]] = []
    drum_hits = 0
    # (channel, pitch) of note-offs that closed nothing at the current tick: a note-on that
    # follows one at the same tick is a zero-length note written note-off first.
    stray_offs: set[tuple[int, int]] = set()

    def close(note: _OpenNote, end_s: float) -> None:
        finished.append((note.pitch, note.onset_s, end_s, note.velocity))

    try:
        merged = mido.merge_tracks(midi.tracks)
    except Exception as exc:  # same reasoning as in _load: any failure means a corrupt file
        raise MidiFileError(f"{path}: corrupt MIDI file ({one_line(exc)})") from exc
    for msg in merged:
        if msg.time:
            stray_offs.clear()
            tick += msg.time
            now = segment_s + (tick - segment_tick) * tempo / (1_000_000 * tpb)
            if now > MAX_DURATION_S:
                raise MidiFileError(
                    f"{path}: timeline longer than {MAX_DURATION_S / 3600:g} hour "
                    f"(reaches {now:.0f} s); refusing an absurd length"
                )
        kind = msg.type
        if kind == "set_tempo":
            bpm = 60_000_000 / msg.tempo if msg.tempo > 0 else float("inf")
            if not MIN_BPM <= bpm <= MAX_BPM:
                raise MidiFileError(
                    f"{path}: absurd tempo {bpm:.4g} BPM at {now:.3f} s "
                    f"(accepted {MIN_BPM:g}..{MAX_BPM:g} BPM)"
                )
            tempo, segment_tick, segment_s = msg.tempo, tick, now
        elif kind in ("note_on", "note_off") and msg.channel == PERCUSSION_CHANNEL:
            if kind == "note_on" and msg.velocity > 0:
                drum_hits += 1
        elif kind == "note_on" and msg.velocity > 0:
            if (msg.channel, msg.note) in stray_offs:
                stray_offs.discard((msg.channel, msg.note))
                continue  # a zero-length note, its note-off written first
            queue = waiting.setdefault(msg.note, deque())
            for note in queue:
                if note.end_s is None:  # re-strike: the key must come up and go down again
                    note.end_s = now
            queue.append(_OpenNote(msg.note, now, msg.velocity))
        elif kind in ("note_on", "note_off"):
            pending = waiting.get(msg.note)
            if pending:
                note = pending.popleft()
                close(note, now if note.end_s is None else note.end_s)
            else:
                stray_offs.add((msg.channel, msg.note))
        elif kind == "control_change" and msg.control == _SUSTAIN_CC:
            if msg.value >= 64 and pedal_since is None:
                pedal_since = now
            elif msg.value < 64 and pedal_since is not None:
                sustain.append((pedal_since, now))
                pedal_since = None
    for queue in waiting.values():
        for note in queue:
            close(note, now if note.end_s is None else note.end_s)
    if pedal_since is not None:
        sustain.append((pedal_since, now))

    finished = [n for n in finished if n[2] > n[1]]
    outside = [n for n in finished if not LOWEST_PITCH <= n[0] <= HIGHEST_PITCH]
    if outside and out_of_range == "error":
        raise out_of_range_error(path, [n[0] for n in outside])
    notes = [
        Note(pitch, onset, offset, velocity)
        for pitch, onset, offset, velocity in finished
        if LOWEST_PITCH <= pitch <= HIGHEST_PITCH
    ]
    if not notes:
        where = " in the piano's range" if outside else ""
        drums = (
            f" (only {drum_hits} drum hit(s) on the percussion channel, MIDI channel 10, "
            "which are not pitches)"
            if drum_hits
            else ""
        )
        raise MidiFileError(f"{path}: no notes{where}{drums}")
    return Song(
        notes=tuple(notes),
        sustain=tuple((s, e) for s, e in sustain if e > s),
        name=path.stem,
    )


def _ticks(seconds: float) -> int:
    return round(seconds * _WRITE_TICKS_PER_S)


def song_to_midi(song: Song, *, midi_type: int = 1) -> mido.MidiFile:
    """Build an in-memory :class:`mido.MidiFile` of ``song`` (480 ticks/beat, 120 BPM, ch. 0).

    Times are rounded to the nearest tick (1/960 s); a note or pedal interval shorter than a
    tick is stretched to one tick so it survives a round trip. Format 1 puts tempo and name on
    track 0 and the notes and CC64 on track 1; format 0 puts everything on one track.
    """
    if midi_type not in (0, 1):
        raise ValueError(f"midi_type must be 0 or 1, got {midi_type!r}")
    # (tick, order, message): at equal ticks note-offs come first so a re-struck key ends its
    # previous note before the new note-on, and pedal-up precedes pedal-down.
    events: list[tuple[int, int, mido.Message]] = []
    for note in song.notes:
        on = _ticks(note.onset_s)
        off = max(_ticks(note.offset_s), on + 1)
        events.append((on, 3, mido.Message("note_on", note=note.pitch, velocity=note.velocity)))
        events.append((off, 0, mido.Message("note_off", note=note.pitch, velocity=64)))
    for start_s, end_s in song.sustain:
        down = _ticks(start_s)
        up = max(_ticks(end_s), down + 1)
        events.append((down, 2, mido.Message("control_change", control=_SUSTAIN_CC, value=127)))
        events.append((up, 1, mido.Message("control_change", control=_SUSTAIN_CC, value=0)))
    events.sort(key=lambda e: (e[0], e[1]))

    header = [
        mido.MetaMessage("track_name", name=song.name or "pianist", time=0),
        mido.MetaMessage("set_tempo", tempo=WRITE_TEMPO_US, time=0),
    ]
    body: list[mido.Message | mido.MetaMessage] = []
    last = 0
    for tick, _, msg in events:
        body.append(msg.copy(time=tick - last))
        last = tick
    midi = mido.MidiFile(type=midi_type, ticks_per_beat=WRITE_TICKS_PER_BEAT)
    if midi_type == 0:
        midi.tracks.append(mido.MidiTrack([*header, *body, mido.MetaMessage("end_of_track")]))
    else:
        midi.tracks.append(mido.MidiTrack([*header, mido.MetaMessage("end_of_track")]))
        midi.tracks.append(mido.MidiTrack([*body, mido.MetaMessage("end_of_track")]))
    return midi


def write_midi(song: Song, path: str | os.PathLike[str], *, midi_type: int = 1) -> None:
    """Write ``song`` as a MIDI file at ``path`` atomically (temp file + ``os.replace``).

    See :func:`song_to_midi` for the layout. Hand and finger labels are not written (MIDI has
    no standard place for them): use :func:`pianist.music.pig.write_pig` to keep fingering.

    Raises:
        MidiFileError: the file cannot be written.
    """
    buffer = io.BytesIO()
    song_to_midi(song, midi_type=midi_type).save(file=buffer)
    write_bytes_atomic(buffer.getvalue(), path, error=MidiFileError)
