"""File helpers shared by the MIDI and PIG readers/writers: existence checks, atomic writes."""

from __future__ import annotations

import os
import tempfile
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


def write_atomic(path: Path, data: bytes, error: type[MusicError], kind: str) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same directory and ``os.replace``.

    A crash or a full disk mid-write therefore never leaves a half-written file at ``path``.
    OS failures are raised as ``error`` with a one-line message.
    """
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp_name = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise error(f"{path}: cannot write {kind} ({exc.strerror or exc})") from exc
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        # mkstemp makes the file private (0600); give it the usual permissions of a new file
        # (or keep those of the file being replaced).
        mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
        os.chmod(tmp_name, mode)
        os.replace(tmp_name, path)
    except OSError as exc:
        Path(tmp_name).unlink(missing_ok=True)
        raise error(f"{path}: cannot write {kind} ({exc.strerror or exc})") from exc
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise
