"""What one cell of a sweep runs: the tasks, and :func:`execute_cell`, the Ray task's body.

A task turns a :class:`~pianist.sweep.grid.Cell` into files in a folder and a dict of metrics:

- ``play``: the cell's song with its controller spec (``planner``, ``mpc:tenth``, ``zero``,
  ``policy:RUN_DIR``, ...) through :func:`pianist.eval.session.play`, written by
  :func:`pianist.media.results.write_result` (metrics.json, performance.mid, actions.npy,
  pianoroll.png, and the audio with ``audio=True``);
- ``train``: :func:`pianist.agents.train` with the cell's preset and seed, the run kept in
  ``run/`` (a worker killed mid-run resumes from the run's newest checkpoint); the preset
  ``practice`` runs :func:`pianist.agents.practice.practise` instead (one worker, the
  default passes, ``minutes`` as its budget);
- ``eval``: a trained run's policy (the variant is its folder) played as ``pianist eval`` does;
- ``dataset``: one demonstration episode of the cell's song with its controller, recorded by
  :func:`pianist.data.record.record_episode` into ``episode/`` (every seed but the grid's
  first adds action noise, as ``pianist dataset build`` does for episodes after the first);
  :func:`pianist.sweep.datasets.assemble_sweep` writes a sweep's episodes as one Minari
  dataset (``pianist dataset assemble``).

A new task is one more :class:`Task` in :data:`TASKS`.

Every cell's folder appears whole (:func:`pianist.files.atomic_dir`) with ``cell.json``, its
record, written last: a folder that exists is a finished cell. An exception in the task is a
finished, failed cell (its record holds the one-line error); only a worker that dies (killed,
out of memory) leaves no folder, and Ray runs the cell again.
"""

from __future__ import annotations

import os
import platform
import shutil
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from pianist.agents.config import DEFAULT_PRESET
from pianist.agents.config import PRACTICE_PRESET as PRACTICE
from pianist.files import atomic_dir, write_json_atomic
from pianist.sweep.grid import Cell

if TYPE_CHECKING:
    from pianist.eval.session import Fingering

#: The record of a finished cell, written last into its folder.
CELL_RECORD = "cell.json"
#: Folders of a sweep's output directory.
CELLS_DIR = "cells"
RUNNING_DIR = "running"
WORK_DIR = "work"
TRAIN_RUN = "run"

OK = "ok"
FAILED = "failed"


@dataclass(frozen=True)
class SweepOptions:
    """Options every cell of a sweep shares (each task reads the ones that apply to it)."""

    fingering: str = "auto"
    """play/eval: how songs are fingered (:func:`pianist.music.load_song`)."""
    initial_buffer_s: float = 0.0
    """play: seconds of silence before the song."""
    audio: bool = False
    """play: also write performance.wav and score.wav."""
    steps: int = 1_000_000
    """train: total environment steps of each run."""
    minutes: float | None = None
    """train: wall-clock budget of each run."""
    noise: float = 0.02
    """dataset: std of the action noise of every seed but ``clean_seed`` (0: none)."""
    clean_seed: int = 0
    """dataset: the seed recorded without noise (the grid's first)."""
    extra: dict[str, Any] = field(default_factory=dict)
    """Options of tasks added later."""

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Task:
    """One kind of cell.

    Attributes:
        name: the task's name on the command line.
        variant: what the variant of its cells is (for messages and the table's header).
        default_variant: the variant of a grid that names none.
        takes_physics: whether a physics preset applies (else the variant decides it).
        check: raises ValueError for a variant the task cannot run (cheap, before Ray starts).
        run: ``run(cell, options, folder, work) -> metrics``: runs the cell, writes its files
            into ``folder`` (an empty folder that becomes the cell's) and returns its metrics;
            ``work`` is a folder of its own that outlives a killed worker (for checkpoints).
    """

    name: str
    variant: str
    default_variant: str
    takes_physics: bool
    check: Callable[[str], None]
    run: Callable[[Cell, SweepOptions, Path, Path], dict[str, Any]]


def _check_controller(spec: str) -> None:
    from pianist.control.registry import build_controller

    build_controller(spec)


def _run_play(cell: Cell, options: SweepOptions, folder: Path, work: Path) -> dict[str, Any]:
    from pianist.control.registry import build_controller
    from pianist.eval.session import play
    from pianist.media.results import MediaOptions, write_result

    result = play(
        cell.song,
        build_controller(cell.variant),
        physics=cell.physics,
        fingering=cast("Fingering", options.fingering),
        initial_buffer_s=options.initial_buffer_s,
        seed=cell.seed,
    )
    title = f"{cell.song} ({cell.variant}, {result.metrics['physics']} physics, seed {cell.seed})"
    extra = {"song": cell.song, "controller": cell.variant}
    media = MediaOptions(audio=options.audio)
    write_result(result, folder, media, title=title, extra_metrics=extra)
    return {**result.metrics, **extra}


def _check_preset(preset: str) -> None:
    from pianist.agents import PRESETS

    if preset not in PRESETS and preset != PRACTICE:
        choices = ", ".join([*PRESETS, PRACTICE])
        raise ValueError(f"unknown preset {preset!r}; choose from {choices}")


def _run_train(cell: Cell, options: SweepOptions, folder: Path, work: Path) -> dict[str, Any]:
    from pianist.agents import get_preset, train
    from pianist.agents.rundir import holds_run

    if cell.variant == PRACTICE:
        return _run_practice(cell, options, folder, work)
    # The run trains in ``work``, outside the cell's temporary folder, so that a killed
    # worker's retry resumes from its newest checkpoint; it moves into the cell's folder once
    # finished.
    resume = holds_run(work)
    config = None if resume else get_preset(cell.variant, seed=cell.seed)
    budget_s = None if options.minutes is None else 60.0 * options.minutes
    result = train(
        None if resume else cell.song,
        config,
        options.steps,
        work,
        resume=resume,
        progress=False,
        stop_after_s=budget_s,
    )
    os.replace(work, folder / TRAIN_RUN)
    metrics: dict[str, Any] = {**result.last_eval, "step": result.step}
    metrics["wall_seconds"] = result.wall_s
    if result.resumed_from is not None:
        metrics["resumed_from"] = result.resumed_from
    if result.best_eval:
        metrics["best_f1"] = result.best_eval["f1"]
        metrics["best_step"] = result.best_eval["step"]
    return metrics


def _run_practice(cell: Cell, options: SweepOptions, folder: Path, work: Path) -> dict[str, Any]:
    """A ``practice`` train cell: :func:`pianist.agents.practice.practise` on one core (the
    cell's seed seeds the look-ahead), saved after every pass in ``work`` so that a killed
    worker's retry goes on from its last pass."""
    from pianist.agents.practice import TABLE, PracticeConfig, load_practice, practise_in
    from pianist.music import load_song

    work.mkdir(parents=True, exist_ok=True)
    start = None
    config = PracticeConfig(seed=cell.seed)
    if (work / TABLE).is_file():
        _, config, start = load_practice(work)
    song = load_song(cell.song, fingering=cast("Fingering", options.fingering))
    budget_s = None if options.minutes is None else 60.0 * options.minutes
    started = time.perf_counter()
    result = practise_in(work, song, cell.song, config, start=start, stop_after_s=budget_s)
    os.replace(work, folder / TRAIN_RUN)
    return {
        "f1": result.f1,
        "best_f1": result.f1,
        "best_pass": result.pass_index,
        "passes": result.history[-1]["pass"],
        "planner_f1": result.history[0]["f1"],
        "wall_seconds": time.perf_counter() - started,
    }


def _check_run(run_dir: str) -> None:
    from pianist.agents.practice import is_practice_run
    from pianist.agents.rundir import holds_run

    if not holds_run(run_dir) and not is_practice_run(run_dir):
        raise ValueError(f"{run_dir} holds no training run (config.json and checkpoints/)")


def _run_eval(cell: Cell, options: SweepOptions, folder: Path, work: Path) -> dict[str, Any]:
    from pianist.agents.specs import load_run
    from pianist.eval.session import play
    from pianist.media.results import MediaOptions, write_result

    controller, described = load_run(cell.variant)
    fingering = cast("Fingering", options.fingering)
    result = play(cell.song, controller, fingering=fingering, seed=cell.seed)
    extra: dict[str, Any] = {"song": cell.song, "run": cell.variant, **described}
    write_result(result, folder, MediaOptions(audio=False), extra_metrics=extra)
    return {**result.metrics, **extra}


#: The folder of a dataset cell that holds its recorded episode.
EPISODE_DIR = "episode"


def _run_dataset(cell: Cell, options: SweepOptions, folder: Path, work: Path) -> dict[str, Any]:
    from pianist.data.record import read_episode, record_episode

    noise = 0.0 if cell.seed == options.clean_seed else options.noise
    record_episode(
        cell.song,
        cell.variant,
        cell.seed,
        cell.physics,
        folder / EPISODE_DIR,
        noise=noise,
        fingering=options.fingering,
    )
    facts = read_episode(folder / EPISODE_DIR).metadata
    keep = ("precision", "recall", "f1", "sustain_f1", "steps", "physics")
    return {k: facts[k] for k in keep if k in facts} | {"noise": noise, "controller": cell.variant}


#: The tasks a sweep can run, by name.
TASKS: dict[str, Task] = {
    "play": Task("play", "controller", "planner", True, _check_controller, _run_play),
    "train": Task("train", "preset", DEFAULT_PRESET, False, _check_preset, _run_train),
    "eval": Task("eval", "run", "", False, _check_run, _run_eval),
    "dataset": Task("dataset", "controller", "planner", True, _check_controller, _run_dataset),
}


def cell_dir(out: str | Path, cell: Cell) -> Path:
    """``out/cells/<cell id>``: the cell's folder."""
    return Path(out) / CELLS_DIR / cell.id


def read_record(out: str | Path, cell: Cell) -> dict[str, Any] | None:
    """The record of ``cell`` if it has finished (its folder and ``cell.json`` exist), else
    None. A record that cannot be read counts as not finished."""
    import json

    try:
        record = json.loads((cell_dir(out, cell) / CELL_RECORD).read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("status") in (OK, FAILED) else None


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and message, whitespace collapsed."""
    message = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {message}" if message else type(exc).__name__


def write_failed(out: str | Path, cell: Cell, error: str, **details: Any) -> dict[str, Any]:
    """Write ``cell``'s folder as failed with ``error`` (e.g. when its worker died too often);
    returns the record."""
    record = _record(cell, FAILED, {}, error=error, **details)
    with atomic_dir(cell_dir(out, cell)) as tmp:
        write_json_atomic(record, tmp / CELL_RECORD)
    return record


def _record(
    cell: Cell, status: str, metrics: dict[str, Any], error: str | None = None, **details: Any
) -> dict[str, Any]:
    return {
        **cell.as_dict(),
        "status": status,
        "error": error,
        "metrics": metrics,
        "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        **details,
    }


def execute_cell(
    cell_data: dict[str, Any], options_data: dict[str, Any], out: str
) -> dict[str, Any]:
    """Run one cell into ``out/cells/<id>`` unless it has finished already; its record.

    The body of the sweep's Ray task (plain dicts in and out, so any node can run it). An
    exception in the task becomes a failed record; the folder appears whole with its
    ``cell.json`` written last.
    """
    cell = Cell.from_dict(cell_data)
    options = SweepOptions(**options_data)
    done = read_record(out, cell)
    if done is not None and done["status"] == OK:
        return done  # finished by an earlier attempt whose worker died before returning
    where = _where()
    running = Path(out) / RUNNING_DIR / f"{cell.id}.json"
    running.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic({**cell.as_dict(), **where, "started_at": time.time()}, running)
    start = time.perf_counter()
    with atomic_dir(cell_dir(out, cell)) as tmp:
        try:
            work = Path(out) / WORK_DIR / cell.id
            metrics = TASKS[cell.task].run(cell, options, tmp, work)
            status, error, trace = OK, None, None
        except Exception as exc:  # noqa: BLE001 - a failed cell is a row, not a failed sweep
            metrics, status, error = {}, FAILED, one_line(exc)
            trace = traceback.format_exc()
            for path in tmp.iterdir():  # half-written files of the failed run
                shutil.rmtree(path) if path.is_dir() else path.unlink()
        details = {**where, "cell_seconds": round(time.perf_counter() - start, 3)}
        if trace is not None:
            details["traceback"] = trace
        record = _record(cell, status, metrics, error=error, **details)
        write_json_atomic(record, tmp / CELL_RECORD)  # last: the folder is complete
    running.unlink(missing_ok=True)
    return record


def _where() -> dict[str, Any]:
    """Which worker runs this: host, process id and, under Ray, the node's id."""
    node = None
    try:
        import ray

        if ray.is_initialized():
            node = ray.get_runtime_context().get_node_id()
    except ImportError:
        pass
    return {"host": platform.node(), "pid": os.getpid(), "node": node}
