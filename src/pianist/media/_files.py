"""Atomic file output shared by the media writers."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from pianist.media.errors import MediaError


@contextmanager
def atomic_output(path: str | os.PathLike[str], suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    The temporary name keeps ``suffix`` because tools such as ffmpeg pick the container format
    from the extension. On any error the temporary file is removed and ``path`` is untouched.

    Raises:
        MediaError: the folder does not exist or is not writable, or the rename fails.
    """
    path = Path(path)
    try:
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    except OSError as exc:
        raise MediaError(f"cannot write {path}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        try:
            # mkstemp makes the file private (0600); give it a normal new file's permissions.
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        except OSError as exc:
            raise MediaError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)  # nothing left to remove after a successful rename
