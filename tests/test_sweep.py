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
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from pianist.cli import main
from pianist.music import list_songs
from pianist.sweep import Cell, SweepOptions, cell_id, expand, run_sweep, songs_of
from pianist.sweep.table import RESULTS_CSV, RESULTS_JSON, SUMMARY_JSON, SUMMARY_PNG, collect_rows
from pianist.sweep.tasks import CELL_RECORD, CELLS_DIR, RUNNING_DIR, execute_cell

SONG = "c-major-chords"
RAY = Path(sys.executable).parent / "ray"
SWEEP = [sys.executable, "-m", "pianist.cli", "sweep"]
# Ray's variables this test process may hold after a local sweep: the subprocesses below
# choose their own.
_RAY_ENV_DROP = ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "RAY_ADDRESS")


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in _RAY_ENV_DROP}
    return {**env, "RAY_USAGE_STATS_ENABLED": "0", **extra}


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / RESULTS_CSV, newline="") as f:
        return list(csv.DictReader(f))


# --- the grid (no Ray) ---------------------------------------------------------------------


def test_grid_expands_song_by_song_then_variant_physics_seed(tmp_path):
    folder = tmp_path / "midi"
    folder.mkdir()
    for name in ("b.mid", "a.MIDI", "notes.txt"):
        (folder / name).write_bytes(b"")
    songs = songs_of(["debug"], ["twinkle-twinkle", "extra-song"], [folder])
    debug = list_songs("debug")
    # Suites first, then the list, then the folder's MIDI files sorted; each song once.
    files = [str(folder / "a.MIDI"), str(folder / "b.mid")]
    assert [s for s, _ in songs] == [*debug, "extra-song", *files]
    assert [suite for _, suite in songs] == ["debug"] * len(debug) + ["songs", "midi", "midi"]

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
    with pytest.raises(ValueError, match="no MIDI file"):
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


def test_list_prints_the_cells_without_running_them(tmp_path, capsys):
    out = tmp_path / "sweep"
    args = ["sweep", "--songs", SONG, "--controllers", "zero", "random", "--seeds", "0", "1"]
    assert main([*args, "--physics", "fast", "--out", str(out), "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[:2] == [f"{SONG}.zero.fast.s0  to run", f"{SONG}.zero.fast.s1  to run"]
    assert lines[-1] == f"4 cells -> {out}"
    assert not (out / CELLS_DIR).exists()


# --- sweeps on a local Ray -----------------------------------------------------------------


def test_play_sweep_writes_a_row_per_cell_reports_a_failed_cell_and_skips_finished_cells(
    tmp_path,
):
    out = tmp_path / "sweep"
    songs = [(SONG, "debug"), ("no-such-song", "songs")]
    cells = expand("play", songs, ["zero", "random"], ["fast"], [0])
    lines: list[str] = []
    report = run_sweep(cells, out, workers=2, message=lines.append)
    assert report.ran == 4 and report.skipped == 0 and report.failed == 2

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


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _stop(node: subprocess.Popen) -> None:
    """Stop one `ray start --block` node: SIGTERM drains and stops its processes; if that
    hangs, kill its process group (only the processes this node started)."""
    if node.poll() is None:
        node.send_signal(signal.SIGTERM)
        try:
            node.wait(timeout=40)
            return
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(node.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    node.wait(timeout=10)


def test_two_ray_nodes_on_this_machine_run_one_sweep(tmp_path):
    """A head on 127.0.0.2 and a second node joined to it (each 1 CPU, its own temp folder,
    token authentication with a token of this test) run one sweep given --address."""
    port = _free_port()
    env = _env(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(16))
    common = ["--num-cpus=1", "--object-store-memory=100000000", "--disable-usage-stats", "--block"]
    nodes: list[subprocess.Popen] = []
    # Ray's socket paths must stay under 108 bytes: a short temp folder, not pytest's.
    ray_tmp = Path(tempfile.mkdtemp(prefix="pianist-ray-"))

    def start(args: list[str], name: str) -> None:
        (ray_tmp / name).mkdir()
        log = open(tmp_path / f"{name}.log", "w")  # noqa: SIM115 - closed with the test's tmp
        nodes.append(
            subprocess.Popen(
                [str(RAY), "start", *args, f"--temp-dir={ray_tmp / name}", *common],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        )

    address = f"127.0.0.2:{port}"
    out = tmp_path / "sweep"
    try:
        head = ["--head", f"--port={port}", "--node-ip-address=127.0.0.2"]
        start([*head, "--include-dashboard=false"], "head")
        _wait_for_port("127.0.0.2", port, nodes[0], tmp_path / "head.log")
        start([f"--address={address}"], "node2")
        status = subprocess.run(
            [sys.executable, "-c", _WAIT_FOR_NODES, address],
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert status.returncode == 0, status.stderr[-2000:]
        command = [*SWEEP, "--songs", SONG, "--physics", "fast"]
        command += ["--controllers", "zero", "random", "--seeds", "0", "1"]
        done = subprocess.run(
            [*command, "--address", address, "--out", str(out)],
            env=env,
            capture_output=True,
            text=True,
            timeout=150,
        )
        assert done.returncode == 0, done.stderr[-2000:]
    finally:
        for node in reversed(nodes):
            _stop(node)
        shutil.rmtree(ray_tmp, ignore_errors=True)
    rows = _rows(out)
    assert len(rows) == 4 and all(row["status"] == "ok" for row in rows), rows
    assert len({row["node"] for row in rows}) == 2  # both nodes ran cells
    assert "Ray cluster 127.0.0.2" in done.stdout


_WAIT_FOR_NODES = """
import logging, sys, time
import ray
ray.init(address=sys.argv[1], log_to_driver=False, logging_level=logging.ERROR)
deadline = time.monotonic() + 45
while sum(n["Alive"] for n in ray.nodes()) < 2:
    assert time.monotonic() < deadline, ray.nodes()
    time.sleep(0.2)
"""


def _wait_for_port(host: str, port: int, node: subprocess.Popen, log: Path) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        assert node.poll() is None, log.read_text()[-2000:]
        try:
            with socket.create_connection((host, port), timeout=1):
                return
        except OSError:
            time.sleep(0.2)
    raise AssertionError(f"the head did not listen on {host}:{port}: {log.read_text()[-2000:]}")


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
    assert metrics["f1"] == row["f1"] and metrics["physics"] == "fast"
