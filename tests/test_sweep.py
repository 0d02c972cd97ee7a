"""Sweeps on Ray: the grid, cell ids, the results table, resume, failed cells, a killed worker,
two Ray nodes, train and eval cells.

Cells play the shortest debug song (c-major-chords, 4 s) with the zero or random controller
on the fast physics, so a cell takes a second or two; most of each test is Ray starting.
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pianist.cli import main
from pianist.music import list_songs
from pianist.sweep import Cell, SweepOptions, cell_id, expand, run_sweep, songs_of
from pianist.sweep.cluster import local_cluster
from pianist.sweep.table import RESULTS_CSV, RESULTS_JSON, SUMMARY_JSON, SUMMARY_PNG, collect_rows
from pianist.sweep.tasks import CELL_RECORD, CELLS_DIR, RUNNING_DIR, execute_cell

# Local Ray clusters: one worker of pytest-xdist runs them all, one at a time (two at once
# would share this machine's Ray ports and session folders).
pytestmark = pytest.mark.xdist_group("ray")

SONG = "c-major-chords"
SWEEP = [sys.executable, "-m", "pianist.cli", "sweep"]


def _env() -> dict[str, str]:
    """This environment without RAY_ADDRESS, which would send a sweep to another Ray."""
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    return {**env, "RAY_USAGE_STATS_ENABLED": "0"}


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / RESULTS_CSV, newline="") as f:
        return list(csv.DictReader(f))


def _descendants(pid: int) -> set[int]:
    """The processes under ``pid``, from Linux's /proc."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            # "pid (command) state ppid ...": the command may hold spaces and parentheses.
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(stat.parent.name))
    found: set[int] = set()
    todo = [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def _running(pids: set[int], wait_s: float = 5.0) -> set[int]:
    """Which of ``pids`` still run (zombies do not) after up to ``wait_s`` seconds."""
    deadline = time.monotonic() + wait_s
    while True:
        alive = set()
        for pid in pids:
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                continue
            if state != "Z":
                alive.add(pid)
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


# --- the grid (no Ray) ---------------------------------------------------------------------


def test_grid_expands_song_by_song_then_variant_physics_seed(tmp_path):
    folder = tmp_path / "midi"
    folder.mkdir()
    for name in ("b.mid", "a.MIDI", "c.txt", "d.mxl", "e.musicxml", "model.xml", "notes.md"):
        (folder / name).write_bytes(b"")
    songs = songs_of(["debug"], ["twinkle-twinkle", "extra-song"], [folder])
    debug = list_songs("debug")
    # Suites first, then the list, then the folder's song files (MIDI, PIG, MusicXML but not
    # plain .xml) sorted; each once.
    files = [str(folder / n) for n in ("a.MIDI", "b.mid", "c.txt", "d.mxl", "e.musicxml")]
    assert [s for s, _ in songs] == [*debug, "extra-song", *files]
    assert [suite for _, suite in songs] == ["debug"] * len(debug) + ["songs"] + ["midi"] * 5

    cells = expand("play", songs[:2], ["planner", "zero"], ["faithful", "fast"], [0, 1, 2])
    assert len(cells) == 2 * 2 * 2 * 3
    assert cells[0] == Cell("play", debug[0], "debug", "planner", "faithful", 0)
    assert cells[1] == Cell("play", debug[0], "debug", "planner", "faithful", 1)
    assert cells[3] == Cell("play", debug[0], "debug", "planner", "fast", 0)
    assert cells[6] == Cell("play", debug[0], "debug", "zero", "faithful", 0)
    assert cells[12].song == debug[1]
    # Repeated values count once.
    assert len(expand("play", songs[:1], ["zero", "zero"], [None], [0, 0, 1])) == 2
    with pytest.raises(ValueError, match="at least one seed"):
        expand("play", songs, ["zero"], [None], [])
    with pytest.raises(ValueError, match="no song file"):
        songs_of(folders=[tmp_path])
    with pytest.raises(ValueError, match="unknown suite"):
        songs_of(["no-such-suite"])
    with pytest.raises(ValueError, match="no song"):
        songs_of()


def test_cell_ids_are_stable_readable_and_safe_as_file_names():
    plain = Cell("play", "twinkle-twinkle", "debug", "planner", "fast", 3)
    assert cell_id(plain) == "twinkle-twinkle.planner.fast.s3"
    assert cell_id(Cell("play", SONG, "debug", "zero", None, 0)) == f"{SONG}.zero.default.s0"
    # Specs and paths lose characters: a hash of the exact spelling keeps cells apart.
    a = Cell("play", "midi/x y.mid", "songs", "mpc:paper,num_samples=20", None, 0)
    b = Cell("play", "midi/x-y.mid", "songs", "mpc:paper,num_samples=20", None, 0)
    c = Cell("play", "midi/x y.mid", "songs", "mpc:paper,num_samples=21", None, 0)
    ids = [cell_id(cell) for cell in (a, b, c)]
    assert len(set(ids)) == 3
    for name in ids:
        assert re.fullmatch(r"[A-Za-z0-9._-]+", name) and len(name) <= 140
        assert not name.startswith(".")
    assert ids[0].startswith("midi-x-y.mpc-paper-num_samples-20.default.s0-")
    # Stable: the same cell gives the same id in another process.
    code = (
        "from pianist.sweep import Cell, cell_id; "
        "print(cell_id(Cell('play', 'midi/x y.mid', 'songs', 'mpc:paper,num_samples=20', None, 0)))"
    )
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert other.stdout.strip() == ids[0]


def test_cli_refuses_a_bad_grid_in_one_line_before_ray_starts(tmp_path, capsys):
    cases = [
        (["--task", "play", "--presets", "fast"], "--presets applies to --task train"),
        (["--task", "eval"], "--task eval needs --runs"),
        (["--task", "train", "--physics", "fast"], "--physics applies to --task play"),
        (["--controllers", "no-such-controller"], "no-such-controller"),
        (["--task", "train", "--presets", "no-such-preset"], "unknown preset"),
        (["--address", "127.0.0.1:1", "--workers", "2"], "workers sets the local Ray"),
        (["--workers", "1", "--cpus-per-cell", "2"], "cannot run a cell of 2 CPUs"),
    ]
    for args, message in cases:
        out = tmp_path / "sweep"
        status = main(["sweep", "--songs", SONG, "--out", str(out), *args])
        err = capsys.readouterr().err
        assert status == 1, args
        assert message in err and len(err.strip().splitlines()) == 1, (args, err)
        assert not (out / CELLS_DIR).exists()


def test_ray_is_imported_only_when_a_sweep_runs():
    code = "import sys, pianist.cli, pianist.sweep; print('ray' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_a_sweep_folder_holds_one_task(tmp_path):
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "sweep.json").write_text(json.dumps({"task": "train", "cells": []}))
    cells = expand("play", [(SONG, "debug")], ["zero"], [None], [0])
    with pytest.raises(ValueError, match="holds a sweep of task 'train'"):
        run_sweep(cells, out, workers=1)


def test_list_prints_the_cells_without_running_them(tmp_path, capsys):
    out = tmp_path / "sweep"
    args = ["sweep", "--songs", SONG, "--controllers", "zero", "random", "--seeds", "0", "1"]
    assert main([*args, "--physics", "fast", "--out", str(out), "--list"]) == 0
    note, *lines = capsys.readouterr().out.splitlines()
    assert note.startswith("note: the seed does not change what zero plays")  # random does
    assert lines[:2] == [f"{SONG}.zero.fast.s0  to run", f"{SONG}.zero.fast.s1  to run"]
    assert lines[-1] == f"4 cells -> {out}"
    assert not (out / CELLS_DIR).exists()


# --- sweeps on a local Ray -----------------------------------------------------------------


def test_a_ray_whose_internals_differ_falls_back_to_its_public_start(monkeypatch, tmp_path):
    import pianist.sweep.runner as runner

    def other_ray(ray, workers):
        raise TypeError("__init__() got an unexpected keyword argument 'include_log_monitor'")

    monkeypatch.setattr(runner, "_start_local_ray", other_ray)
    cells = expand("play", [(SONG, "debug")], ["zero"], ["fast"], [0])
    report = run_sweep(cells, tmp_path / "out", workers=1, message=lambda line: None)
    assert report.ran == 1 and report.failed == 0 and report.ray_start_s > 0
    import ray

    assert not ray.is_initialized()  # stopped at the end as before


@pytest.mark.slow
def test_play_sweep_writes_a_row_per_cell_reports_a_failed_cell_and_skips_finished_cells(
    tmp_path,
):
    out = tmp_path / "sweep"
    songs = [(SONG, "debug"), ("no-such-song", "songs")]
    cells = expand("play", songs, ["zero", "random"], ["fast"], [0])
    lines: list[str] = []
    ray_processes: set[int] = set()
    # Processes an earlier test left behind (a Ray stopped by ray.shutdown lets its agents
    # linger a while) are not this sweep's.
    before = _descendants(os.getpid())

    def message(line: str) -> None:
        lines.append(line)
        if line.startswith("running ") and not ray_processes:  # the local Ray is up
            ray_processes.update(_descendants(os.getpid()) - before)

    report = run_sweep(cells, out, workers=2, message=message)
    assert report.ran == 4 and report.skipped == 0 and report.failed == 2
    assert "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER" not in os.environ  # set for the local Ray only
    # Ray's start and stop are timed apart from the cells: the fixed cost of a sweep.
    assert 0 < report.ray_start_s and 0 < report.ray_stop_s
    assert report.ray_start_s + report.ray_stop_s < report.wall_s
    # Every process of the local Ray (its services, agents and workers) is gone at the end.
    if Path("/proc/self/stat").exists():
        assert len(ray_processes) >= 3 and not _running(ray_processes)

    rows = _rows(out)
    assert [row["id"] for row in rows] == [cell.id for cell in cells]
    ok = [row for row in rows if row["status"] == "ok"]
    failed = [row for row in rows if row["status"] == "failed"]
    assert [row["song"] for row in ok] == [SONG, SONG]
    for row in ok:
        assert 0.0 <= float(row["f1"]) <= 1.0 and row["error"] == ""
        assert int(row["steps"]) == 81 and row["physics"] == "fast"
        folder = out / CELLS_DIR / row["id"]
        assert {"metrics.json", "actions.npy", "performance.mid", "pianoroll.png"} <= {
            p.name for p in folder.iterdir()
        }
        metrics = json.loads((folder / "metrics.json").read_text())
        assert metrics["f1"] == pytest.approx(float(row["f1"]))
    # A failing cell is a row with its one-line error; the others ran.
    assert [row["song"] for row in failed] == ["no-such-song"] * 2
    for row in failed:
        assert row["error"].startswith("UnknownSongError: unknown song 'no-such-song'")
        assert "\n" not in row["error"] and row["f1"] == ""
    assert any("failed: UnknownSongError" in line for line in lines)
    # The JSON table holds the same rows; the summary has one group per suite and variant.
    assert [r["id"] for r in json.loads((out / RESULTS_JSON).read_text())] == [c.id for c in cells]
    summary = json.loads((out / SUMMARY_JSON).read_text())
    by_key = {(g["suite"], g["variant"]): g for g in summary}
    assert by_key[("debug", "zero")]["ok"] == 1 and by_key[("songs", "random")]["failed"] == 1
    assert by_key[("songs", "random")]["songs"][0]["failed"] is True
    assert by_key[("debug", "zero")]["songs"][0]["failed"] is False
    zero = [float(r["f1"]) for r in ok if r["variant"] == "zero"]
    assert by_key[("debug", "zero")]["mean_f1"] == pytest.approx(sum(zero) / len(zero))
    assert (out / SUMMARY_PNG).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / RUNNING_DIR).exists()

    # A rerun skips the finished cells (their folders untouched) and runs the failed ones.
    records = {row["id"]: (out / CELLS_DIR / row["id"] / CELL_RECORD) for row in ok}
    before = {name: (path.stat().st_mtime_ns, path.read_text()) for name, path in records.items()}
    report = run_sweep(cells, out, workers=2, message=lines.append)
    assert report.skipped == 2 and report.ran == 2
    assert {n: (p.stat().st_mtime_ns, p.read_text()) for n, p in records.items()} == before
    again = _rows(out)
    assert [row["id"] for row in again] == [cell.id for cell in cells]  # one row per cell
    assert [row for row in again if row["status"] == "ok"] == ok
    assert any(line == "2 of 4 cells finished earlier: skipped" for line in lines)


@pytest.mark.slow
def test_a_worker_killed_mid_cell_is_retried_and_no_row_is_lost_or_doubled(tmp_path):
    """SIGKILL the worker of the first cell that starts (its pid is in running/<id>.json)."""
    out = tmp_path / "sweep"
    command = [*SWEEP, "--songs", SONG, "--physics", "fast"]
    command += ["--controllers", "zero", "random", "--seeds", "0", "1", "--workers", "2"]
    process = subprocess.Popen(
        [*command, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    killed = None
    try:
        deadline = time.monotonic() + 90
        while killed is None and time.monotonic() < deadline and process.poll() is None:
            for marker in (out / RUNNING_DIR).glob("*.json"):
                try:
                    running = json.loads(marker.read_text())
                except (OSError, ValueError):
                    continue
                os.kill(running["pid"], signal.SIGKILL)
                killed = running
                break
            time.sleep(0.02)
        stdout, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert killed is not None, "no cell started"
    assert process.returncode == 0, stderr
    rows = _rows(out)
    ids = [row["id"] for row in rows]
    assert len(ids) == 4 and len(set(ids)) == 4
    assert all(row["status"] == "ok" for row in rows), rows
    again = next(row for row in rows if row["id"] == killed["id"])
    assert int(again["pid"]) != killed["pid"]  # run again by another worker
    assert sorted(p.name for p in (out / CELLS_DIR).iterdir()) == sorted(ids)  # no leftovers
    assert "4 cells: 4 ok, 0 failed" in stdout


@pytest.mark.slow
def test_two_ray_nodes_on_this_machine_run_one_sweep(tmp_path):
    """A head and a second node joined to it (1 CPU each, their own temporary folders and
    token) run one sweep given --address; cells are spread over both."""
    out = tmp_path / "sweep"
    command = [*SWEEP, "--songs", SONG, "--physics", "fast"]
    command += ["--controllers", "zero", "random", "--seeds", "0", "1"]
    with local_cluster(num_nodes=2, cpus_per_node=1) as cluster:
        done = subprocess.run(
            [*command, "--address", cluster.address, "--out", str(out)],
            env=cluster.env,
            capture_output=True,
            text=True,
            timeout=150,
        )
    assert done.returncode == 0, done.stderr[-2000:]
    rows = _rows(out)
    assert len(rows) == 4 and all(row["status"] == "ok" for row in rows), rows
    assert len({row["node"] for row in rows}) == 2  # both nodes ran cells
    assert f"Ray cluster {cluster.address}" in done.stdout
    # Every process of the cluster is gone (its head's port no longer answers).
    host, port = cluster.address.split(":")
    with pytest.raises(OSError):
        socket.create_connection((host, int(port)), timeout=1).close()


def test_train_and_eval_cells(tmp_path):
    """The train and eval tasks, run as a Ray worker runs a cell (the runner is tested above
    with play cells), to keep JAX's start-up out of a Ray worker here."""
    out = tmp_path / "train"
    (cell,) = expand("train", [(SONG, "debug")], ["fast-small"], [None], [3])
    record = execute_cell(cell.as_dict(), SweepOptions(steps=100).as_dict(), str(out))
    assert record["status"] == "ok", record["error"]
    (row,) = collect_rows(out, [cell])
    assert row["step"] == 100 and 0.0 <= row["f1"] <= 1.0
    run = out / CELLS_DIR / cell.id / "run"
    config = json.loads((run / "config.json").read_text())
    assert config["config"]["seed"] == 3 and config["config"]["preset"] == "fast-small"
    assert not (out / "work" / cell.id).exists()  # moved into the cell's folder
    # A finished cell is not run again.
    assert execute_cell(cell.as_dict(), SweepOptions(steps=100).as_dict(), str(out)) == record

    out = tmp_path / "eval"
    (cell,) = expand("eval", [(SONG, "debug")], [str(run)], [None], [0])
    record = execute_cell(cell.as_dict(), SweepOptions().as_dict(), str(out))
    assert record["status"] == "ok", record["error"]
    (row,) = collect_rows(out, [cell])
    assert row["preset"] == "fast-small" and row["checkpoint_step"] == 100
    metrics = json.loads((out / CELLS_DIR / cell.id / "metrics.json").read_text())
    # Trained on the fast physics, played on the one its evaluations chose it in.
    assert metrics["f1"] == row["f1"] and metrics["physics"] == "faithful"


def test_practice_train_and_eval_cells(tmp_path):
    """A train cell of the practice preset keeps its table in run/, and an eval cell plays it
    back with the F1 the practice reached."""
    out = tmp_path / "train"
    (cell,) = expand("train", [(SONG, "debug")], ["practice"], [None], [0])
    # A budget this short stops after the planner's own pass, pass 0.
    options = SweepOptions(minutes=1e-4).as_dict()
    record = execute_cell(cell.as_dict(), options, str(out))
    assert record["status"] == "ok", record["error"]
    (row,) = collect_rows(out, [cell])
    assert row["passes"] == 0 and row["best_f1"] == row["planner_f1"]
    run = out / CELLS_DIR / cell.id / "run"
    assert json.loads((run / "config.json").read_text())["kind"] == "practice"

    out = tmp_path / "eval"
    (cell,) = expand("eval", [(SONG, "debug")], [str(run)], [None], [0])
    record = execute_cell(cell.as_dict(), SweepOptions().as_dict(), str(out))
    assert record["status"] == "ok", record["error"]
    (evaluated,) = collect_rows(out, [cell])
    assert evaluated["preset"] == "practice" and evaluated["f1"] == row["best_f1"]


def test_dataset_cells_assemble_into_one_minari_dataset(tmp_path, monkeypatch, capsys):
    """The dataset task, run as a Ray worker runs a cell: one episode per seed, the first
    noiseless; the finished cells then make one Minari dataset with `pianist dataset
    assemble`, the same arrays as the cells recorded."""
    import minari

    from pianist.data.record import read_episode
    from pianist.sweep.tasks import EPISODE_DIR

    out = tmp_path / "sweep"
    cells = expand("dataset", [(SONG, "debug")], ["planner"], ["fast"], [0, 1])
    options = SweepOptions(noise=0.05, clean_seed=0).as_dict()
    for cell in cells:
        record = execute_cell(cell.as_dict(), options, str(out))
        assert record["status"] == "ok", record["error"]
    rows = collect_rows(out, cells)
    assert [row["noise"] for row in rows] == [0.0, 0.05]
    assert all(0.5 < row["f1"] <= 1.0 for row in rows)

    root = tmp_path / "datasets"
    code = main(
        ["dataset", "assemble", str(out), "--out", "pianist/sweep-test-v0", "--root", str(root)]
    )
    assert code == 0, capsys.readouterr().err
    assert "2 episodes" in capsys.readouterr().out
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    dataset = minari.load_dataset("pianist/sweep-test-v0")
    assert dataset.total_episodes == 2
    metas = list(dataset.storage.get_episode_metadata([0, 1]))
    assert [(m["seed"], m["noise"]) for m in metas] == [(0, 0.0), (1, 0.05)]
    for i, cell in enumerate(cells):
        recorded = read_episode(out / CELLS_DIR / cell.id / EPISODE_DIR)
        np.testing.assert_array_equal(dataset[i].actions, recorded.actions)

    # Assembling again into the same id, or from a folder without dataset cells, is refused.
    for args in (
        [str(out), "--out", "pianist/sweep-test-v0"],
        [str(tmp_path / "empty"), "--out", "pianist/other-v0"],
    ):
        assert main(["dataset", "assemble", *args, "--root", str(root)]) == 1
        err = capsys.readouterr().err
        assert err.startswith("pianist: error:") and err.count("\n") == 1


def test_dataset_sweep_takes_controllers_not_presets(tmp_path, capsys):
    args = ["sweep", "--task", "dataset", "--songs", SONG, "--presets", "fast-small"]
    assert main([*args, "--out", str(tmp_path / "s")]) == 1
    assert "--presets applies to --task train" in capsys.readouterr().err
    args = ["sweep", "--task", "dataset", "--songs", SONG, "--noise", "-1", "--list"]
    assert main([*args, "--out", str(tmp_path / "s")]) == 1
    assert "--noise must be a std >= 0" in capsys.readouterr().err


def test_an_address_where_nothing_listens_fails_in_seconds_before_anything_is_written(
    tmp_path, capsys
):
    with socket.socket() as probe:  # a port that was free a moment ago: nothing listens
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    out = tmp_path / "sweep"
    for address, message in ((f"127.0.0.1:{port}", "cannot reach"), ("nohost", "HOST:PORT")):
        start = time.perf_counter()
        assert main(["sweep", "--songs", SONG, "--address", address, "--out", str(out)]) == 1
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert time.perf_counter() - start < 10 and not out.exists()


def test_a_sweep_with_failed_cells_exits_1_after_its_table(tmp_path, capsys, monkeypatch):
    import pianist.sweep
    from pianist.sweep.runner import SweepReport

    rows = [{"status": "ok"}, {"status": "failed"}]
    report = SweepReport(tmp_path, rows, skipped=0, ran=2)
    monkeypatch.setattr(pianist.sweep, "run_sweep", lambda *args, **kwargs: report)
    assert main(["sweep", "--songs", SONG, "--out", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    assert "2 cells: 1 ok, 1 failed" in captured.out
    assert "1 of 2 cells failed" in captured.err and len(captured.err.strip().splitlines()) == 1
