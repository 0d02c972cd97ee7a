"""Read and write PIG fingering files (Nakamura et al., ``NNN-k_fingering.txt``).

Format: lines starting with ``//`` are comments (the first is a version header), blank lines
are ignored, every other line is one note of 8 whitespace-separated fields::

    note_id  onset_s  offset_s  pitch_name  onset_velocity  offset_velocity  channel  finger

``channel`` is 0 for the right hand and 1 for the left; ``finger`` is +1..+5 (right thumb..
little) or -1..-5 (left thumb..little), mapped to 0..4 and 5..9. ``a_b`` (a finger change on
a held note) keeps the first finger ``a``. The finger's sign decides the hand; the channel is
only used for notes whose finger is ``0`` (unlabelled). Notes of zero length are dropped.
PIG has no sustain pedal, so :func:`write_pig` drops the song's sustain.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Literal

from pianist.files import write_text_atomic
from pianist.music.errors import MusicError, PigFormatError, one_line
from pianist.music.fileio import require_file
from pianist.music.midi import MAX_DURATION_S
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.pitch import (
    HIGHEST_PITCH,
    LOWEST_PITCH,
    name_to_pitch,
    out_of_range_error,
    pitch_to_name,
)

PIG_HEADER = "//Version: PianoFingering_v170101"
_NUM_FIELDS = 8


def pig_finger_to_index(text: str) -> int | None:
    """Map a PIG finger field (``"3"``, ``"-2"``, ``"2_1"``) to 0..9, or None for ``"0"``."""
    first = text.split("_", 1)[0]
    value = int(first)
    if value == 0:
        return None
    if not 1 <= abs(value) <= 5:
        raise ValueError(f"finger {text!r} is outside +-1..5")
    return value - 1 if value > 0 else 4 - value


def index_to_pig_finger(finger: int) -> int:
    """Map finger 0..9 to PIG's +1..+5 (right) / -1..-5 (left)."""
    return finger + 1 if finger < 5 else -(finger - 4)


def _parse_row(fields: list[str]) -> tuple[int, float, float, int, int | None, str]:
    if len(fields) != _NUM_FIELDS:
        raise ValueError(f"expected {_NUM_FIELDS} fields, found {len(fields)}")
    onset, offset = float(fields[1]), float(fields[2])
    if not (math.isfinite(onset) and math.isfinite(offset)) or onset < 0 or offset < onset:
        raise ValueError(f"bad times onset {fields[1]} s, offset {fields[2]} s")
    try:
        pitch = name_to_pitch(fields[3])
    except MusicError as exc:
        raise ValueError(str(exc)) from None
    velocity = int(fields[4])
    channel = int(fields[6])
    if channel not in (0, 1):
        raise ValueError(f"channel {channel} is not 0 (right) or 1 (left)")
    finger = pig_finger_to_index(fields[7])
    hand = RIGHT if channel == 0 else LEFT
    return pitch, onset, offset, velocity, finger, hand


def read_pig(
    path: str | os.PathLike[str], *, out_of_range: Literal["error", "drop"] = "error"
) -> Song:
    """Read a PIG fingering file into a fully (or partly) fingered :class:`Song`, no sustain.

    Velocities outside 1..127 are clipped into that range (some files write 0 or 64/80
    placeholders). ``out_of_range`` works as in :func:`~pianist.music.midi.read_midi`.

    Raises:
        PigFormatError: missing/empty/unreadable file, a malformed row (message gives the line
            number) or no notes.
        OutOfRangeError: pitches outside MIDI 21..108 with ``out_of_range="error"``.
    """
    if out_of_range not in ("error", "drop"):
        raise ValueError(f"out_of_range must be 'error' or 'drop', got {out_of_range!r}")
    path = Path(path)
    require_file(path, PigFormatError, "PIG file")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise PigFormatError(f"{path}: cannot read PIG file ({one_line(exc)})") from exc
    notes: list[Note] = []
    outside: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("//"):
            continue
        try:
            pitch, onset, offset, velocity, finger, hand = _parse_row(stripped.split())
        except ValueError as exc:
            raise PigFormatError(f"{path}:{number}: bad PIG row ({one_line(exc)})") from None
        if offset > MAX_DURATION_S:  # as MIDI files and scores are: not hours of goal frames
            raise PigFormatError(
                f"{path}:{number}: a note ends at {offset:.0f} s, past "
                f"{MAX_DURATION_S / 3600:g} hour; refusing an absurd length"
            )
        if not LOWEST_PITCH <= pitch <= HIGHEST_PITCH:
            outside.append(pitch)
            continue
        if offset == onset:
            continue
        velocity = min(max(velocity, 1), 127)
        # A labelled finger decides the hand (Note derives it); the channel only fills in
        # the hand of unlabelled notes.
        notes.append(Note(pitch, onset, offset, velocity, finger, hand if finger is None else None))
    if outside and out_of_range == "error":
        raise out_of_range_error(path, outside)
    if not notes:
        raise PigFormatError(f"{path}: no notes")
    return Song(notes=tuple(notes), name=path.stem)


def song_to_pig(song: Song) -> str:
    """Render ``song`` as PIG text (header + one row per note, times with 6 decimals).

    Raises:
        PigFormatError: a note has no finger (PIG needs every note fingered).
    """
    lines = [PIG_HEADER]
    for index, note in enumerate(song.notes):
        if note.finger is None:
            raise PigFormatError(
                f"song {song.name or '(unnamed)'}: note {index} ({pitch_to_name(note.pitch)} at "
                f"{note.onset_s:.3f} s) has no finger; PIG needs every note fingered"
            )
        channel = 0 if note.hand == RIGHT else 1
        lines.append(
            "\t".join(
                [
                    str(index),
                    f"{note.onset_s:.6f}",
                    f"{note.offset_s:.6f}",
                    pitch_to_name(note.pitch),
                    str(note.velocity),
                    "80",
                    str(channel),
                    str(index_to_pig_finger(note.finger)),
                ]
            )
        )
    return "\n".join(lines) + "\n"


def write_pig(song: Song, path: str | os.PathLike[str]) -> None:
    """Write ``song`` as a PIG file at ``path`` atomically; sustain is not representable.

    Raises:
        PigFormatError: a note has no finger, or the file cannot be written.
    """
    text = song_to_pig(song)
    write_text_atomic(text, path, error=PigFormatError)
