"""The ``pianist`` command: list songs, describe a song, play it and score the performance.

Heavy modules (MuJoCo, Gymnasium) are imported inside the subcommands so ``--help`` is instant.
Every expected failure ends with one readable line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import os
import sys
import warnings
from typing import Annotated, Any

import tyro

from pianist.cli.bc import BC
from pianist.cli.common import CliError
from pianist.cli.dataset import Dataset
from pianist.cli.play import Play
from pianist.cli.report import Report
from pianist.cli.songs import ImportPig, Info, Songs
from pianist.cli.sweep import Sweep
from pianist.cli.train import Eval, Train
from pianist.cli.view import View

__all__ = ["CliError", "main"]


Command = (
    Annotated[Songs, tyro.conf.subcommand("songs")]
    | Annotated[Info, tyro.conf.subcommand("info")]
    | Annotated[Play, tyro.conf.subcommand("play")]
    | Annotated[Report, tyro.conf.subcommand("report")]
    | Annotated[View, tyro.conf.subcommand("view")]
    | Annotated[ImportPig, tyro.conf.subcommand("import-pig")]
    | Annotated[Train, tyro.conf.subcommand("train")]
    | Annotated[Eval, tyro.conf.subcommand("eval")]
    | Annotated[Sweep, tyro.conf.subcommand("sweep")]
    | Annotated[Dataset, tyro.conf.subcommand("dataset")]
    | Annotated[BC, tyro.conf.subcommand("bc")]
)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pianist`` console script; returns the exit status."""
    try:
        command = tyro.cli(Command, args=argv, prog="pianist", description=__doc__.splitlines()[0])
    except BrokenPipeError:  # `pianist play --help | head`: the reader has gone
        return _reader_gone()
    try:
        with warnings.catch_warnings():  # restores the library's warning display afterwards
            warnings.showwarning = _show_warning
            command.run()
    except KeyboardInterrupt:
        sys.stderr.write("pianist: interrupted\n")
        return 130
    except BrokenPipeError:
        return _reader_gone()
    except Exception as exc:  # noqa: BLE001 - turned into one line below, or re-raised
        message = _expected_error(exc)
        if message is None:
            raise
        sys.stderr.write(f"pianist: error: {message}\n")
        return 1
    return 0


def _reader_gone() -> int:
    """The reader of the output has gone (`pianist songs | head`): nothing to say, and the
    interpreter must not fail again flushing stdout at exit."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 1


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: Any = None,
    line: str | None = None,
) -> None:
    """Show a warning raised during a command as one line (no file path or source line): the
    warnings are about the user's input (e.g. a known-broken PIG piece), not about code."""
    sys.stderr.write(f"pianist: warning: {' '.join(str(message).split())}\n")


def _expected_error(exc: Exception) -> str | None:
    """One line for failures caused by input or environment, None for bugs."""
    from pianist.env import SimulationUnstableError
    from pianist.media import MediaError
    from pianist.music import MusicError

    expected = CliError | MusicError | MediaError | SimulationUnstableError | FileNotFoundError
    if isinstance(exc, expected):
        return " ".join(str(exc).split())
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc)
    if isinstance(exc, ValueError):
        return " ".join(str(exc).split())
    return None
