"""Checkpoints of a training run: agent state, replay buffer, counters and RNG states.

A checkpoint (where it lives: :mod:`pianist.agents.rundir`) is a folder holding::

    agent.npz    every leaf of the agent state (for resuming)
    policy.npz   the actor's layers, readable without JAX
    replay.npz   the replay buffer (for resuming)
    state.json   the loop's counters and RNG states, and the step

A run's ``best/`` folder is a run directory of its own (config.json, checkpoints/ holding only
policy.npz and state.json with the evaluation): it plays and evaluates like any run
(``pianist eval RUN/best SONG``) but cannot be resumed.

A checkpoint directory is written under a temporary name and renamed when complete, then
``latest.json`` is replaced atomically: a crash at any point leaves the previous checkpoint
usable.
"""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from pianist.agents import rundir
from pianist.agents.config import TrainConfig
from pianist.files import atomic_dir, write_json_atomic

_LOAD_ERRORS = (ValueError, OSError, EOFError, KeyError, zipfile.BadZipFile)


def save_checkpoint(
    run_dir: Path,
    step: int,
    agent_leaves: list[np.ndarray] | None,
    actor_layers: list[tuple[np.ndarray, np.ndarray]],
    replay_arrays: dict[str, np.ndarray] | None,
    state: dict[str, Any],
    keep: int = 2,
) -> Path:
    """Write checkpoint ``step`` atomically, point ``latest.json`` at it, keep ``keep``.

    ``agent_leaves`` and ``replay_arrays`` None: a policy-only checkpoint (not resumable).
    """
    root = rundir.checkpoints_dir(run_dir)
    root.mkdir(parents=True, exist_ok=True)
    name = rundir.checkpoint_name(step)
    # A checkpoint of this step left by a run that crashed after it is replaced whole.
    with atomic_dir(root / name) as tmp:
        # allow_pickle=False: plain arrays only, as _load_npz reads them back.
        if agent_leaves is not None:
            leaves = {f"leaf_{i:04d}": a for i, a in enumerate(agent_leaves)}
            np.savez(tmp / "agent.npz", allow_pickle=False, **leaves)
        layers = {f"w{i}": w for i, (w, _) in enumerate(actor_layers)}
        layers.update({f"b{i}": b for i, (_, b) in enumerate(actor_layers)})
        np.savez(tmp / "policy.npz", allow_pickle=False, **layers)
        if replay_arrays is not None:
            np.savez(tmp / "replay.npz", allow_pickle=False, **replay_arrays)
        (tmp / "state.json").write_text(json.dumps({**state, "step": step}, indent=1) + "\n")
    final = root / name
    write_json_atomic({"dir": name, "step": step}, rundir.latest_pointer(run_dir))
    older = sorted(p for p in root.glob("step_*") if p.is_dir() and p.name != name)
    for old in older[: max(0, len(older) - (keep - 1))]:
        shutil.rmtree(old, ignore_errors=True)
    for stale in root.glob(".step_*"):  # temporary folders of a crashed save
        shutil.rmtree(stale, ignore_errors=True)
    return final


def save_best(
    run_dir: Path,
    step: int,
    actor_layers: list[tuple[np.ndarray, np.ndarray]],
    evaluation: dict[str, Any],
) -> Path:
    """Keep the actor of step ``step`` as ``run_dir/best`` (see the module docstring).

    ``evaluation``: the metrics that made it the best (stored in its state.json).
    """
    best = rundir.best_dir(run_dir)
    best.mkdir(exist_ok=True)
    rundir.write_run_config(best, json.loads(rundir.config_path(run_dir).read_text()))
    return save_checkpoint(best, step, None, actor_layers, None, {"eval": evaluation}, keep=1)


def best_evaluation(run_dir: str | Path) -> dict[str, Any] | None:
    """The evaluation stored with ``run_dir/best`` (None if the run has kept no best yet)."""
    best = rundir.best_dir(run_dir)
    if not rundir.latest_pointer(best).is_file():
        return None
    return {**load_state(latest_checkpoint(best))["eval"]}


def latest_checkpoint(run_dir: str | Path) -> Path:
    """The directory of the newest complete checkpoint of ``run_dir``."""
    pointer = rundir.latest_pointer(run_dir)
    if not pointer.is_file():
        raise FileNotFoundError(f"no checkpoint in {run_dir} (missing {pointer})")
    try:
        name = json.loads(pointer.read_text())["dir"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"{pointer} is corrupt ({exc})") from None
    path = pointer.parent / str(name)
    if not path.is_dir():
        raise FileNotFoundError(f"checkpoint directory {path} named by {pointer} is missing")
    return path


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint file missing: {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except _LOAD_ERRORS as exc:
        raise ValueError(
            f"checkpoint file {path} is corrupt ({type(exc).__name__}: {exc})"
        ) from None


def load_state(checkpoint: Path) -> dict[str, Any]:
    path = checkpoint / "state.json"
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint file missing: {path}")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"checkpoint file {path} is corrupt ({exc})") from None


def load_agent_leaves(checkpoint: Path, template: list[np.ndarray]) -> list[np.ndarray]:
    """The saved agent leaves, checked against the shapes and dtypes of ``template``."""
    data = _load_npz(checkpoint / "agent.npz")
    if len(data) != len(template):
        raise ValueError(
            f"checkpoint {checkpoint} holds {len(data)} agent arrays, "
            f"this agent has {len(template)}"
        )
    leaves = [data[f"leaf_{i:04d}"] for i in range(len(template))]
    for i, (saved, want) in enumerate(zip(leaves, template, strict=True)):
        if saved.shape != np.shape(want) or saved.dtype != np.asarray(want).dtype:
            raise ValueError(
                f"checkpoint {checkpoint}: agent array {i} is {saved.dtype}{saved.shape}, "
                f"expected {np.asarray(want).dtype}{np.shape(want)} (another configuration?)"
            )
    return leaves


def load_replay_arrays(checkpoint: Path) -> dict[str, np.ndarray]:
    return _load_npz(checkpoint / "replay.npz")


def load_policy(
    run_dir: str | Path,
) -> tuple[TrainConfig, list[tuple[np.ndarray, np.ndarray]], int]:
    """(config, actor layers [(W, b), ...], step) of the newest checkpoint of a run."""
    config = TrainConfig.from_dict(rundir.read_run_config(run_dir)["config"])
    checkpoint = latest_checkpoint(run_dir)
    data = _load_npz(checkpoint / "policy.npz")
    n = len(data) // 2
    try:
        layers = [(data[f"w{i}"], data[f"b{i}"]) for i in range(n)]
    except KeyError as exc:
        raise ValueError(f"{checkpoint / 'policy.npz'} is corrupt (missing {exc})") from None
    return config, layers, int(load_state(checkpoint)["step"])
