"""What every subcommand shares: the one-line error, the song argument, the seed check."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import tyro


class CliError(Exception):
    """A failure the user can fix; printed as one line."""


# The song positional as --help shows it (tyro would show its type, STR).
SongArg = Annotated[str, tyro.conf.arg(metavar="SONG")]


def require_jax() -> None:
    import importlib.util

    if importlib.util.find_spec("jax") is None:
        raise CliError("training needs JAX: pip install 'pianist[rl]' (jax, flax, optax)")


def check_seed(seed: int, flag: str = "--seed") -> None:
    """Refuse a negative seed before anything is built (Gymnasium takes seeds >= 0)."""
    if seed < 0:
        raise CliError(f"{flag} must be >= 0, not {seed}")


def prepare_dir(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"cannot create output directory {path}: {exc.strerror}") from None
    probe = path / ".pianist-write-test"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise CliError(f"output directory {path} is not writable: {exc.strerror}") from None


def out(text: str) -> None:
    sys.stdout.write(text + "\n")
