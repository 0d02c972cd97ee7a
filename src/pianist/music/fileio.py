"""File checks shared by the MIDI and PIG readers (atomic writes: :mod:`pianist.files`)."""

from __future__ import annotations

from pathlib import Path

from pianist.music.errors import MusicError


def require_file(path: Path, error: type[MusicError], kind: str) -> int:
    """Raise ``error`` unless ``path`` is an existing, non-empty regular file; return its size.

    ``kind`` (e.g. "MIDI file") only words the message.
    """
    if not path.exists():
        raise error(f"{path}: {kind} not found")
    if path.is_dir():
        raise error(f"{path}: is a directory, not a {kind}")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise error(f"{path}: cannot read {kind} ({exc.strerror or exc})") from exc
    if size == 0:
        raise error(f"{path}: {kind} is empty (0 bytes)")
    return size


#: Suffixes of the song files a folder of songs holds: MIDI, PIG fingering files (.txt),
#: MusicXML scores (not plain .xml, which a folder may hold for other things: MuJoCo models),
#: Humdrum, ABC and MEI scores.
SONG_FILE_SUFFIXES = (".mid", ".midi", ".txt", ".musicxml", ".mxl", ".krn", ".abc", ".mei")


def song_files(folder: Path) -> list[Path]:
    """The song files (MIDI, PIG or scores, :data:`SONG_FILE_SUFFIXES`) directly in
    ``folder``, sorted by name."""
    return sorted(
        p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in SONG_FILE_SUFFIXES
    )
