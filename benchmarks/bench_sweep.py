"""Sweeps on Ray: 1 against 2 workers, a worker killed mid-sweep, two Ray nodes.

Three measurements, each a `play` sweep with the planner (``--controller``) on the debug
suites (``--suites``, default ``debug,robopianist-debug``: 12 songs), physics ``--physics``
(default: the controller's own, faithful for the planner), seed 0:

- scaling: the same sweep, into a fresh folder each, with a local Ray of 1 and of 2 workers,
  ``--repeats`` times each in alternating order (1, 2, 2, 1, ...: the very first sweep also
  warms the disk caches); the time is the whole :func:`pianist.sweep.run_sweep` call (Ray's
  start and stop included), the median run per worker count is reported, and the target is
  2 workers <= 0.6x the time of 1;
- kill: the sweep run as ``pianist sweep`` in a subprocess with 2 workers; the worker of the
  first cell that starts is sent SIGKILL (its pid is in ``running/<cell>.json``); the table
  must end with every cell once, all ok;
- cluster: a head and a second node on this machine (1 CPU each,
  :func:`pianist.sweep.cluster.local_cluster`) run the sweep given ``--address``; how many
  nodes ran cells, and the time.

F1 of every run must agree across the three (the planner is deterministic). The machine's load
average before each run is printed: other processes on the cores skew the scaling ratio.

Run: ``python benchmarks/bench_sweep.py [--suites debug,robopianist-debug] [--controller planner]
[--physics default|faithful|fast] [--skip kill,cluster] [--json docs/results/sweep.json]``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pianist.sweep import expand, run_sweep, songs_of
from pianist.sweep.cluster import local_cluster
from pianist.sweep.table import RESULTS_CSV
from pianist.sweep.tasks import RUNNING_DIR


def _load() -> float:
    return os.getloadavg()[0]


def _f1_by_cell(out: Path) -> dict[str, float]:
    with open(out / RESULTS_CSV, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {row["id"]: float(row["f1"]) if row["f1"] else float("nan") for row in rows}


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / RESULTS_CSV, newline="") as handle:
        return list(csv.DictReader(handle))


def scaling(cells, root: Path, workers: int, repeat: int = 0) -> dict:
    load = _load()
    out = root / f"workers{workers}-{repeat}"
    start = time.perf_counter()
    report = run_sweep(cells, out, workers=workers)
    wall = time.perf_counter() - start
    cell_s = sum(float(row.get("cell_seconds") or 0.0) for row in report.rows)
    return {
        "workers": workers,
        "wall_s": wall,
        "cells": len(report.rows),
        "failed": report.failed,
        "sum_cell_s": cell_s,
        "ray_start_s": report.ray_start_s,
        "ray_stop_s": report.ray_stop_s,
        "load_before": load,
        "f1": _f1_by_cell(out),
    }


def _without_ray(run: dict) -> float:
    """A scaling run's wall time less Ray's start and stop (s)."""
    return run["wall_s"] - run["ray_start_s"] - run["ray_stop_s"]


def _median_run(runs: list[dict]) -> dict:
    """The run of median wall time (the lower middle one of an even count)."""
    ordered = sorted(runs, key=lambda run: run["wall_s"])
    return ordered[(len(ordered) - 1) // 2]


def _command(args, out: Path) -> list[str]:
    command = [sys.executable, "-m", "pianist.cli", "sweep", "--suite", *args.suites.split(",")]
    command += ["--controllers", args.controller, "--out", str(out)]
    if args.physics != "default":
        command += ["--physics", args.physics]
    return command


def kill(args, root: Path) -> dict:
    load = _load()
    out = root / "kill"
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    start = time.perf_counter()
    process = subprocess.Popen(
        [*_command(args, out), "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    killed = None
    while killed is None and process.poll() is None:
        for marker in (out / RUNNING_DIR).glob("*.json"):
            try:
                running = json.loads(marker.read_text())
            except (OSError, ValueError):
                continue
            os.kill(running["pid"], signal.SIGKILL)
            killed = running
            break
        time.sleep(0.02)
    _, stderr = process.communicate(timeout=1800)
    wall = time.perf_counter() - start
    if process.returncode != 0:
        raise SystemExit(f"the sweep with a killed worker failed: {stderr[-2000:]}")
    rows = _rows(out)
    ids = [row["id"] for row in rows]
    again = next(row for row in rows if row["id"] == killed["id"]) if killed else None
    return {
        "wall_s": wall,
        "cells": len(rows),
        "distinct_cells": len(set(ids)),
        "ok": sum(row["status"] == "ok" for row in rows),
        "killed_cell": killed["id"] if killed else None,
        "killed_pid": killed["pid"] if killed else None,
        "rerun_pid": int(again["pid"]) if again else None,
        "load_before": load,
        "f1": _f1_by_cell(out),
    }


def cluster(args, root: Path) -> dict:
    load = _load()
    out = root / "cluster"
    with local_cluster(num_nodes=2, cpus_per_node=1) as nodes:
        start = time.perf_counter()
        done = subprocess.run(
            [*_command(args, out), "--address", nodes.address],
            env=nodes.env,
            capture_output=True,
            text=True,
            timeout=1800,
        )
        wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"the sweep on two nodes failed: {done.stderr[-2000:]}")
    rows = _rows(out)
    return {
        "wall_s": wall,
        "cells": len(rows),
        "ok": sum(row["status"] == "ok" for row in rows),
        "nodes_used": len({row["node"] for row in rows}),
        "cells_per_node": sorted(
            (sum(row["node"] == node for row in rows) for node in {row["node"] for row in rows}),
            reverse=True,
        ),
        "load_before": load,
        "f1": _f1_by_cell(out),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", default="debug,robopianist-debug")
    parser.add_argument("--controller", default="planner")
    parser.add_argument("--physics", default="default", choices=("default", "faithful", "fast"))
    parser.add_argument("--skip", default="", help="comma-separated: kill, cluster")
    parser.add_argument(
        "--repeats", type=int, default=3, help="scaling runs per worker count (order alternated)"
    )
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    physics = None if args.physics == "default" else args.physics
    cells = expand("play", songs_of(args.suites.split(",")), [args.controller], [physics], [0])
    results: dict = {
        "suites": args.suites,
        "controller": args.controller,
        "physics": args.physics,
        "cells": len(cells),
        "cpu_count": os.cpu_count(),
    }
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        root = Path(tmp)
        # 1, 2, then 2, 1, ...: the first sweep of all also warms the disk caches.
        runs: dict[int, list[dict]] = {1: [], 2: []}
        for r in range(max(1, args.repeats)):
            for workers in (1, 2) if r % 2 == 0 else (2, 1):
                runs[workers].append(scaling(cells, root, workers, r))
        one, two = (_median_run(runs[w]) for w in (1, 2))
        results["scaling"] = {
            "1": one,
            "2": two,
            "repeats": len(runs[1]),
            "walls_s": {str(w): [run["wall_s"] for run in runs[w]] for w in runs},
            "ratio": two["wall_s"] / one["wall_s"],
            # The same without Ray's start and stop, which cost the same for 1 and 2 workers.
            "ratio_without_ray_start_stop": _without_ray(two) / _without_ray(one),
        }
        print(f"{len(cells)} cells: {args.controller} on {args.suites} ({args.physics} physics)")
        print(f"{'run':22s} {'wall s':>8s} {'cells':>6s} {'ok':>4s} {'load':>6s}  notes")
        for run in (one, two):
            ok = run["cells"] - run["failed"]
            print(
                f"{'local, ' + str(run['workers']) + ' worker(s)':22s} {run['wall_s']:8.1f} "
                f"{run['cells']:6d} {ok:4d} {run['load_before']:6.2f}  "
                f"sum of cell times {run['sum_cell_s']:.1f} s"
            )
        ratio = results["scaling"]["ratio"]
        walls = "; ".join(
            f"{w}: " + ", ".join(f"{x:.1f}" for x in results["scaling"]["walls_s"][w])
            for w in ("1", "2")
        )
        print(f"{'':22s} walls by worker count ({walls}); the median runs above")
        print(f"{'':22s} 2 workers / 1 worker = {ratio:.2f} (target <= 0.6)")
        fixed = "; ".join(
            f"{run['workers']}: start {run['ray_start_s']:.1f} s, stop {run['ray_stop_s']:.1f} s"
            for run in (one, two)
        )
        print(
            f"{'':22s} Ray's start and stop ({fixed}); without them "
            f"{results['scaling']['ratio_without_ray_start_stop']:.2f}"
        )
        reference = one["f1"]
        if "kill" not in skip:
            k = kill(args, root)
            results["kill"] = k
            complete = k["cells"] == k["distinct_cells"] == len(cells) == k["ok"]
            print(
                f"{'local, 2, one killed':22s} {k['wall_s']:8.1f} {k['cells']:6d} {k['ok']:4d} "
                f"{k['load_before']:6.2f}  SIGKILL pid {k['killed_pid']} in {k['killed_cell']}, "
                f"rerun by pid {k['rerun_pid']}; table complete, no duplicate: {complete}"
            )
        if "cluster" not in skip:
            c = cluster(args, root)
            results["cluster"] = c
            print(
                f"{'2 Ray nodes x 1 CPU':22s} {c['wall_s']:8.1f} {c['cells']:6d} {c['ok']:4d} "
                f"{c['load_before']:6.2f}  nodes used {c['nodes_used']}, cells per node "
                f"{c['cells_per_node']}"
            )
        for name in ("kill", "cluster"):
            if name in results:
                same = results[name]["f1"] == reference
                results[name]["same_f1_as_local"] = same
                print(f"F1 of every cell in '{name}' equal to the local run's: {same}")
        results["scaling"]["2"]["same_f1_as_local"] = two["f1"] == reference
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=2)
            handle.write("\n")


if __name__ == "__main__":
    main()
