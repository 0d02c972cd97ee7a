"""Test-wide settings."""

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

# Offscreen rendering on a machine without a display; mujoco reads this at its first import.
os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture(autouse=True, scope="session")
def _scratch_working_directory(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Run every test in a scratch working directory, so that files written relative to it
    (MuJoCo's MUJOCO_LOG.TXT on any simulation warning, a command's default ``out/``) never
    land in the checkout. Tests use absolute paths (``tmp_path``, ``__file__``); the command
    line runs as ``python -m pianist.cli`` from the installed package."""
    scratch = tmp_path_factory.mktemp("cwd")
    before = Path.cwd()
    os.chdir(scratch)
    try:
        yield scratch
    finally:
        os.chdir(before)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, config: pytest.Config):
    """Say that the slow end-to-end tests were left out, and how to run them: with pytest-xdist
    the deselection happens in the workers, and the summary line would not show it."""
    if config.getoption("markexpr") != "not slow":
        return
    slow = sum(
        path.read_text().count("@pytest.mark.slow")
        for path in Path(__file__).parent.glob("test_*.py")
    )
    terminalreporter.write_line(
        f"{slow} slow end-to-end tests were left out (-m 'not slow'): run them with "
        "`python -m pytest -m slow` (.ci/run does)"
    )
