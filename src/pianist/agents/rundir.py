"""The layout of a training run directory: its file names, its configuration and its log.

::

    config.json                   the resolved configuration (song, steps, TrainConfig, ...)
    log.jsonl                     one JSON object per line: evaluations, episodes, losses
    checkpoints/latest.json       {"dir": "step_000012345", "step": 12345}
    checkpoints/step_000012345/   one checkpoint (its contents: pianist.agents.checkpoint)
    best/                         the policy with the best evaluation F1 so far, as a run
                                  directory of its own (config.json and checkpoints/)

This module knows where things are and reads and writes the two plain files (config.json,
log.jsonl); :mod:`pianist.agents.checkpoint` writes and reads what a checkpoint holds.
It imports neither JAX nor the policy, so every agents module may use it.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import TracebackType
from typing import Any

from pianist.agents.config import TrainConfig
from pianist.files import write_json_atomic, write_text_atomic

CONFIG = "config.json"
LOG = "log.jsonl"
CHECKPOINTS = "checkpoints"
LATEST = "latest.json"
BEST = "best"


def config_path(run_dir: str | Path) -> Path:
    """``run_dir/config.json``."""
    return Path(run_dir) / CONFIG


def log_path(run_dir: str | Path) -> Path:
    """``run_dir/log.jsonl``."""
    return Path(run_dir) / LOG


def checkpoints_dir(run_dir: str | Path) -> Path:
    """``run_dir/checkpoints``: the checkpoint folders and the pointer to the newest."""
    return Path(run_dir) / CHECKPOINTS


def latest_pointer(run_dir: str | Path) -> Path:
    """``run_dir/checkpoints/latest.json``, naming the newest complete checkpoint."""
    return checkpoints_dir(run_dir) / LATEST


def checkpoint_name(step: int) -> str:
    """The folder name of the checkpoint of ``step``: ``step_`` and 9 digits (sorts by step)."""
    return f"step_{step:09d}"


def best_dir(run_dir: str | Path) -> Path:
    """``run_dir/best``: the best policy so far, itself laid out as a run directory."""
    return Path(run_dir) / BEST


def holds_run(run_dir: str | Path) -> bool:
    """Whether ``run_dir`` holds a run that has checkpointed (and so can be resumed)."""
    return latest_pointer(run_dir).exists()


def read_run_config(run_dir: str | Path) -> dict[str, Any]:
    """``run_dir/config.json`` as a dict (song, steps, config); clear errors when unusable."""
    path = config_path(run_dir)
    if not Path(run_dir).is_dir():
        raise FileNotFoundError(f"run directory not found: {run_dir}")
    if not path.is_file():
        raise FileNotFoundError(f"{run_dir} is not a training run (no config.json)")
    try:
        data = json.loads(path.read_text())
        TrainConfig.from_dict(data["config"])
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"{path} is not a valid run configuration ({exc})") from None
    return data


def write_run_config(run_dir: str | Path, data: dict[str, Any]) -> None:
    """Write ``data`` as ``run_dir/config.json`` (atomically)."""
    write_json_atomic(data, config_path(run_dir))


def truncate_log(run_dir: str | Path, step: int) -> None:
    """Drop log rows written after the checkpoint of ``step`` that a run resumes from."""
    path = log_path(run_dir)
    if not path.exists():
        return
    kept = []
    for line in path.read_text().splitlines():
        try:
            if json.loads(line)["step"] <= step:
                kept.append(line)
        except (json.JSONDecodeError, KeyError, TypeError):
            continue  # a line cut by the crash
    write_text_atomic("\n".join(kept) + "\n" if kept else "", path)


def remove_log(run_dir: str | Path) -> None:
    """Delete the log of a previous run that never checkpointed (a new run starts afresh)."""
    log_path(run_dir).unlink(missing_ok=True)


class RunLog:
    """``log.jsonl`` opened for appending: :meth:`write` adds one row and flushes it.

    Each row is flushed at once so that a crash loses at most the row being written (which
    :func:`truncate_log` then drops). Use it as a context manager, or call :meth:`close`.
    """

    def __init__(self, run_dir: str | Path) -> None:
        self._file = log_path(run_dir).open("a")

    def write(self, row: dict[str, Any]) -> None:
        """Append ``row`` as one JSON line."""
        self._file.write(json.dumps(row) + "\n")
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> RunLog:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
