"""Running a sweep on Ray: which cells still have to run, scheduling them, retries, the table.

:func:`run_sweep` skips every cell whose folder holds a finished record (a failed cell runs
again), runs the others as Ray tasks of ``cpus_per_cell`` CPUs each, and rebuilds the results
table from the cells' folders at the end (:mod:`pianist.sweep.table`).

- Local (``address=None``): an embedded Ray started with ``workers`` CPUs, no dashboard, its
  workers' output not forwarded, a small object store (cells return a record of a few KiB;
  results go to files), listening on the loopback interface only, without the autoscaler's
  monitor and the log monitor (:func:`_start_local_ray`); stopped at the end.
- Cluster (``address="HOST:PORT"`` of a ``ray start --head``): every node needs this package
  installed and must see ``out`` at the same path (a shared filesystem), since each cell
  writes its own folder there.

A worker that dies (SIGKILL, out of memory, a lost node) makes Ray run its cell again, up to
``max_retries`` times; after that the cell is written as failed with Ray's error. A cell whose
task raises is a failed row at once and is not retried within the run. Ray is imported only
here, inside :func:`run_sweep`.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pianist.files import write_json_atomic
from pianist.sweep.grid import Cell
from pianist.sweep.table import collect_rows, write_tables
from pianist.sweep.tasks import (
    CELLS_DIR,
    OK,
    RUNNING_DIR,
    TASKS,
    SweepOptions,
    execute_cell,
    one_line,
    read_record,
    write_failed,
)

SWEEP_JSON = "sweep.json"
#: The local Ray's shared-memory object store: cells pass records of a few KiB, so the
#: smallest store Ray accepts (75 MiB) with room to spare, not Ray's default of 30% of RAM.
OBJECT_STORE_BYTES = 128 * 1024 * 1024


@dataclass
class SweepReport:
    """What :func:`run_sweep` did.

    Attributes:
        out: the sweep's folder.
        rows: the results table, one row per cell of the grid (``status`` ok, failed or
            missing).
        skipped: cells finished before this run (not run again).
        ran: cells run in this run.
        nodes: the Ray nodes that ran this run's cells.
        wall_s: seconds from the start of Ray to the last cell (0 when nothing ran).
        ray_start_s: of which starting (or joining) Ray took this long ...
        ray_stop_s: ... and stopping (or leaving) it this long: the fixed cost of a sweep.
        files: the table's files.
    """

    out: Path
    rows: list[dict[str, Any]]
    skipped: int
    ran: int
    nodes: set[str] = field(default_factory=set)
    wall_s: float = 0.0
    ray_start_s: float = 0.0
    ray_stop_s: float = 0.0
    files: list[Path] = field(default_factory=list)

    @property
    def failed(self) -> int:
        return sum(row["status"] != OK for row in self.rows)


def check_grid(cells: Sequence[Cell]) -> None:
    """Refuse a grid its tasks cannot run, before anything starts.

    Raises:
        ValueError: an unknown task, a physics preset for a task whose variant decides it, or
            a variant the task refuses (unknown controller spec, preset or run folder).
    """
    for task_name in dict.fromkeys(cell.task for cell in cells):
        if task_name not in TASKS:
            raise ValueError(f"unknown task {task_name!r}; choose from {', '.join(TASKS)}")
        task = TASKS[task_name]
        mine = [cell for cell in cells if cell.task == task_name]
        if not task.takes_physics and any(cell.physics for cell in mine):
            raise ValueError(
                f"a {task_name} cell's physics is its {task.variant}'s: leave out the physics"
            )
        for variant in dict.fromkeys(cell.variant for cell in mine):
            task.check(variant)


def _check_folder(out: Path, cells: Sequence[Cell]) -> None:
    """Refuse to mix tasks in one sweep folder (a cell's id does not hold its task)."""
    try:
        earlier = json.loads((out / SWEEP_JSON).read_text())
    except (OSError, ValueError):
        return
    tasks = {cell.task for cell in cells}
    if isinstance(earlier, dict) and earlier.get("task") not in tasks:
        raise ValueError(
            f"{out} holds a sweep of task {earlier.get('task')!r}; choose another folder"
        )


def _remove_leftovers(out: Path) -> None:
    """Temporary folders of cells whose worker died mid-write, and stale running markers."""
    cells = out / CELLS_DIR
    if cells.is_dir():
        for path in cells.iterdir():
            if path.name.startswith(".") and path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
    shutil.rmtree(out / RUNNING_DIR, ignore_errors=True)


def run_sweep(
    cells: Sequence[Cell],
    out: str | Path,
    *,
    options: SweepOptions | None = None,
    workers: int | None = None,
    address: str | None = None,
    cpus_per_cell: float = 1.0,
    max_retries: int = 3,
    message: Callable[[str], None] | None = None,
) -> SweepReport:
    """Run every unfinished cell of ``cells`` on Ray and write the results table into ``out``.

    Args:
        cells: the grid (:func:`pianist.sweep.grid.expand`); all of one task.
        out: the sweep's folder: ``cells/<id>/`` per cell, ``results.csv``/``.json``,
            ``summary.json``/``.png``, ``sweep.json`` (the grid).
        options: options shared by every cell.
        workers: local Ray's CPUs (default: this machine's cores); must be None with
            ``address``, where the cluster's CPUs decide.
        address: a Ray cluster's address (``HOST:PORT`` of ``ray start --head``); None: a
            local Ray.
        cpus_per_cell: CPUs each cell asks Ray for.
        max_retries: how often Ray runs a cell again whose worker died.
        message: called with one line per finished cell and at the start.
    Returns:
        The report; its rows are the table written.
    Raises:
        ValueError: a bad grid or option or an ``out`` that cannot be made (before Ray
            starts), or cells whose folders the driver cannot see (``out`` not shared by the
            cluster's nodes).
    """
    options = options or SweepOptions()
    out = Path(out)
    say = message or (lambda _line: None)
    if not cells:
        raise ValueError("the grid has no cell")
    if len({cell.task for cell in cells}) != 1:
        raise ValueError("a sweep runs one task")
    if not (math.isfinite(cpus_per_cell) and cpus_per_cell > 0):
        raise ValueError(f"cpus per cell must be a positive number, not {cpus_per_cell}")
    if max_retries < 0:
        raise ValueError(f"max retries must be >= 0, not {max_retries}")
    if address is not None and workers is not None:
        raise ValueError(
            "workers sets the local Ray's CPUs; on a cluster (address) its nodes' CPUs decide"
        )
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if address is None and workers < cpus_per_cell:
        raise ValueError(f"{workers} worker CPUs cannot run a cell of {cpus_per_cell:g} CPUs")
    check_grid(cells)
    if address is not None:
        check_reachable(address)  # before anything is written, and in seconds, not minutes
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(
            f"the sweep's folder {out} cannot be made ({exc.strerror or exc})"
        ) from None
    _check_folder(out, cells)
    write_json_atomic(
        {
            "task": cells[0].task,
            "options": options.as_dict(),
            "cells": [cell.as_dict() for cell in cells],
        },
        out / SWEEP_JSON,
    )
    _remove_leftovers(out)
    pending = [cell for cell in cells if (read_record(out, cell) or {}).get("status") != OK]
    skipped = len(cells) - len(pending)
    report = SweepReport(out, [], skipped, len(pending))
    if skipped:
        say(f"{skipped} of {len(cells)} cells finished earlier: skipped")
    if pending:
        start = time.perf_counter()
        report.nodes = _run_on_ray(
            pending, out, options, workers, address, cpus_per_cell, max_retries, say, report
        )
        report.wall_s = time.perf_counter() - start
    _remove_leftovers(out)
    report.rows = collect_rows(out, cells)
    unseen = [row["id"] for row in report.rows if row["status"] == "missing"]
    report.files = write_tables(out, report.rows)
    if unseen:
        raise ValueError(
            f"{len(unseen)} cells finished but their folders are not in {out} (e.g. "
            f"{unseen[0]}): on a cluster, --out must be a folder every node sees at the same path"
        )
    return report


def check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Refuse a cluster address that no server answers at: Ray itself retries a closed port
    for many minutes. ``auto`` (Ray finds the cluster) is left to Ray.

    Raises:
        ValueError: not ``HOST:PORT`` (or ``ray://HOST:PORT``), or nothing listens there.
    """
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"a Ray cluster's address is HOST:PORT, not {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ValueError(
            f"cannot reach a Ray cluster at {address}: {reason} (is `ray start --head` "
            "running there, on that port?)"
        ) from None


_LOCAL_RAY_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}
_QUIET: dict[str, Any] = {"log_to_driver": False, "logging_level": logging.ERROR}


def _start_ray(workers: int, address: str | None) -> tuple[Any, Callable[[], None]]:
    """Start a local Ray of ``workers`` CPUs (``address`` None) or join the cluster at
    ``address``: the ``ray`` module and the function that stops (or leaves) it."""
    if address is None:
        # A local sweep needs no network: Ray then binds its services to the loopback
        # interface (as it does on macOS) instead of the machine's address, and reports
        # nothing home. Ray reads these when imported, and its processes inherit them when
        # they start; this process's environment is restored afterwards.
        added = [key for key in _LOCAL_RAY_ENV if key not in os.environ]
        os.environ.update({key: _LOCAL_RAY_ENV[key] for key in added})
        try:
            import ray

            try:
                return ray, _start_local_ray(ray, workers)
            except (ImportError, AttributeError, TypeError):
                # A Ray whose internal classes differ from those of the Rays this was
                # written for (2.5x-2.6x): its public start, with the two extra processes.
                ray.init(
                    num_cpus=workers,
                    include_dashboard=False,
                    object_store_memory=OBJECT_STORE_BYTES,
                    _system_config={"worker_niceness": 0},
                    **_QUIET,
                )
                return ray, ray.shutdown
        finally:
            for key in added:
                del os.environ[key]
    import ray

    try:
        ray.init(address=address, **_QUIET)
    except (ConnectionError, RuntimeError) as exc:
        raise ValueError(
            f"cannot connect to the Ray cluster at {address}: {one_line(exc)[:300]} (a cluster "
            "started with token authentication needs RAY_AUTH_MODE=token and its token here)"
        ) from None
    return ray, ray.shutdown


def _start_local_ray(ray: Any, workers: int) -> Callable[[], None]:
    """Start a Ray node of our own for this sweep and connect to it; the function that stops
    exactly that node.

    ``ray.init(num_cpus=...)`` would start, besides what tasks need, the autoscaler's monitor
    (nothing to scale on one machine; on ``ray.shutdown`` its SIGTERM handler tries to report
    to the GCS, stopped before it, and outlasts the whole 1 s grace period) and the log
    monitor (it forwards workers' output to the driver, which ``log_to_driver=False`` turns
    off): two Python processes starting next to the others on a small machine and 1 s of
    the stop. ``ray.init`` has no switch for either, so the node is started as ``ray.init``
    starts it (``ray._private`` classes: ``Node`` with the same ``RayParams``, the same token
    authentication) without those two, and the driver joins it by its address. Tasks,
    retries of a dead worker's task and Ray's memory monitor (in the raylet) are unchanged.
    """
    from ray._private.node import Node
    from ray._private.parameter import RayParams

    # What ray.init(logging_level=ERROR) does first: Ray's own messages while starting
    # (the token authentication notice, ...) stay out of the sweep's output.
    logging.getLogger("ray").setLevel(logging.ERROR)
    system_config: dict[str, Any] = {
        # Cells are the work this command was asked for: its workers run at the command's
        # own priority (Ray's default lowers them by 15, which starves them whenever
        # anything else runs; `nice pianist sweep` still applies).
        "worker_niceness": 0,
    }
    _token_auth_as_ray_init(system_config)
    params = RayParams(
        num_cpus=workers,
        object_store_memory=OBJECT_STORE_BYTES,
        include_dashboard=False,
        # As ray.init: the API server (started even without a dashboard) takes the first
        # free port from 8265 on instead of failing when another Ray holds 8265.
        dashboard_port=None,
        no_monitor=True,
        include_log_monitor=False,  # type: ignore[arg-type]  # a bool, annotated str by Ray
        _system_config=system_config,
    )
    # As ray.init: a reaper (or the kernel's parent-death signal) stops the node's
    # processes if this process dies without stopping them.
    node = Node(params, head=True, shutdown_at_exit=False, spawn_reaper=True)

    def stop() -> None:
        try:
            ray.shutdown()  # the driver leaves; a node it joined by address is not its to stop
        finally:
            # What ray.shutdown does to a node it started: the raylet first (it stops its
            # workers and agents), each process given a grace period before SIGKILL.
            node.kill_all_processes(check_alive=False, allow_graceful=True)

    try:
        ray.init(address=node.address, **_QUIET)
    except BaseException:
        node.kill_all_processes(check_alive=False, allow_graceful=True)
        raise
    return stop


def _token_auth_as_ray_init(system_config: dict[str, Any]) -> None:
    """Token authentication as ``ray.init`` sets it up for a new local Ray: on unless
    ``RAY_AUTH_MODE`` says otherwise, with the user's token (made if missing). Rays before
    token authentication have neither function."""
    try:
        from ray._private.authentication.authentication_token_setup import (
            enable_token_auth_by_default,
            ensure_token_if_auth_enabled,
        )
    except ImportError:
        return
    enable_token_auth_by_default()
    ensure_token_if_auth_enabled(system_config, create_token_if_missing=True)


def _run_on_ray(
    cells: Sequence[Cell],
    out: Path,
    options: SweepOptions,
    workers: int,
    address: str | None,
    cpus_per_cell: float,
    max_retries: int,
    say: Callable[[str], None],
    report: SweepReport,
) -> set[str]:
    """Run ``cells`` as Ray tasks; the ids of the nodes that ran them (Ray's start and stop
    times go into ``report``)."""
    started = time.perf_counter()
    ray, stop = _start_ray(workers, address)
    report.ray_start_s = time.perf_counter() - started
    nodes: set[str] = set()
    try:
        if address is not None:
            cpus = ray.cluster_resources().get("CPU", 0.0)
            if cpus < cpus_per_cell:
                raise ValueError(
                    f"the cluster at {address} has {cpus:g} CPUs: a cell needs {cpus_per_cell:g}"
                )
        remote = ray.remote(
            num_cpus=cpus_per_cell,
            max_retries=max_retries,
            retry_exceptions=False,
            # One cell per node first: a cluster's nodes share the work from the start.
            scheduling_strategy="SPREAD",
        )(execute_cell)
        where = "local Ray" if address is None else f"Ray cluster {address}"
        say(f"running {len(cells)} cells on the {where} ({cpus_per_cell:g} CPU each)")
        options_data = options.as_dict()
        refs = {remote.remote(cell.as_dict(), options_data, str(out)): cell for cell in cells}
        done = 0
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1)
            cell = refs.pop(ready[0])
            try:
                record = ray.get(ready[0])
            except ray.exceptions.RayError as exc:
                # The worker died more often than max_retries (or the node was lost).
                record = read_record(out, cell) or write_failed(
                    out, cell, one_line(exc)[:500], retries=max_retries
                )
            done += 1
            if record.get("node"):
                nodes.add(record["node"])
            say(f"[{done}/{len(cells)}] {cell.id}: {_outcome(record)}")
    finally:
        stopping = time.perf_counter()
        stop()
        report.ray_stop_s = time.perf_counter() - stopping
    return nodes


def _outcome(record: dict[str, Any]) -> str:
    if record.get("status") != OK:
        return f"failed: {record.get('error')}"
    f1 = (record.get("metrics") or {}).get("f1")
    seconds = record.get("cell_seconds")
    score = f"F1 {f1:.3f}" if isinstance(f1, int | float) else "ok"
    return f"{score} ({seconds:.1f} s)" if isinstance(seconds, int | float) else score
