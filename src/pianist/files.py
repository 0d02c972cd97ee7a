"""Atomic file output: every file and folder the package writes appears whole or not at all.

A result is written under a temporary name in the destination folder (the same filesystem, so
the final ``os.replace`` is atomic) and renamed onto its path once complete. A crash, a full
disk or an exception mid-write leaves the previous file (or nothing) at the path, never half
of a new one, and removes the temporary.

This module imports nothing of the package: every subpackage may use it.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

ErrorFactory = Callable[[str], Exception]


class FileWriteError(OSError):
    """A result could not be written (missing or read-only folder, full disk, ...)."""


def _default_error(message: str) -> Exception:
    return FileWriteError(message)


def _new_file_mode(path: Path) -> int:
    """The mode a replaced file keeps, else an ordinary new file's (0666 less the umask)."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        return 0o666 & ~_umask()


@contextmanager
def atomic_path(
    path: str | os.PathLike[str], *, suffix: str = ".tmp", error: ErrorFactory = _default_error
) -> Iterator[Path]:
    """Yield a temporary file path beside ``path``; rename it onto ``path`` on success.

    The temporary name ends in ``suffix`` because some writers (ffmpeg, matplotlib) choose the
    format from the extension. On any exception the temporary is removed and ``path`` is left
    as it was.

    Raises:
        ``error(message)`` (default :class:`FileWriteError`) when the folder is missing or not
        writable, or the rename fails.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=suffix)
    except OSError as exc:
        raise error(f"cannot write {path}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        try:
            # mkstemp makes the file private (0600); results are ordinary files.
            os.chmod(tmp, _new_file_mode(path))
            os.replace(tmp, path)
        except OSError as exc:
            raise error(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)  # nothing is left to remove after a successful rename


def write_bytes_atomic(
    data: bytes, path: str | os.PathLike[str], *, error: ErrorFactory = _default_error
) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path, error=error) as tmp:
        try:
            tmp.write_bytes(data)
        except OSError as exc:
            raise error(f"cannot write {path}: {exc.strerror or exc}") from None


def write_text_atomic(
    text: str, path: str | os.PathLike[str], *, error: ErrorFactory = _default_error
) -> None:
    """Write ``text`` as UTF-8 to ``path`` atomically."""
    write_bytes_atomic(text.encode("utf-8"), path, error=error)


def write_json_atomic(data: Any, path: str | os.PathLike[str]) -> None:
    """Write ``data`` as indented JSON (one trailing newline) to ``path`` atomically."""
    write_bytes_atomic(json.dumps(data, indent=2).encode() + b"\n", path)


def save_npy_atomic(array: np.ndarray, path: str | os.PathLike[str]) -> None:
    """``np.save`` ``array`` to ``path`` atomically (no pickles: plain arrays only)."""
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(array), allow_pickle=False)
    write_bytes_atomic(buffer.getvalue(), path)


@contextmanager
def atomic_dir(
    path: str | os.PathLike[str], *, error: ErrorFactory = _default_error
) -> Iterator[Path]:
    """Yield a temporary folder beside ``path``; on success swap it in as ``path`` whole.

    An existing ``path`` is replaced only once the new folder is complete: it is first moved
    aside, the new one renamed in, then the old one removed, so ``path`` never holds a mix of
    two writes. On any exception the temporary folder is removed and ``path`` is untouched.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=folder, prefix=f".{path.name}."))
    except OSError as exc:
        raise error(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(dir=folder, prefix=f".{path.name}.old."))
            os.replace(path, old / path.name)
        try:
            os.replace(tmp, path)
        except OSError as exc:
            if old is not None:  # put the previous folder back
                os.replace(old / path.name, path)
            raise error(f"cannot write {path}: {exc.strerror or exc}") from None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # gone already after a successful swap


def check_replaceable_dir(
    path: str | os.PathLike[str],
    own: Collection[str],
    *,
    error: ErrorFactory = _default_error,
    advice: str = "choose a new or empty folder",
) -> None:
    """Refuse a folder that :func:`atomic_dir` would replace and lose more than its own files
    with: ``path`` a file, or a folder holding any name not in ``own`` (an earlier result's
    files). A missing or empty ``path`` is fine.

    Raises:
        ``error(message)``: one line naming the problem, ending with ``advice``.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise error(f"{path} is a file, not a folder")
    if path.is_dir():
        foreign = sorted(p.name for p in path.iterdir() if p.name not in own)
        if foreign:
            more = ", ..." if len(foreign) > 3 else ""
            raise error(f"{path} holds other files ({', '.join(foreign[:3])}{more}); {advice}")


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask
