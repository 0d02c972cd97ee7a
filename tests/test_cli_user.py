"""What a user meets on the command line (issue 56): help without the parser's artefacts,
excerpts, speeds to two significant figures, an unwritable folder refused before playing, and
a sweep that says when seeds cannot change a result."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from pianist.cli import main
from pianist.eval.rollout import realtime_text
from pianist.eval.session import excerpt_of, play
from pianist.music import load_song

COMMANDS = [
    "songs",
    "info",
    "play",
    "report",
    "view",
    "import-pig",
    "train",
    "eval",
    "sweep",
    "dataset build",
    "dataset assemble",
    "dataset info",
    "bc train",
    "bc eval",
]


def _help(command: str) -> str:
    result = subprocess.run(
        [sys.executable, "-m", "pianist.cli", *command.split(), "--help"],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.parametrize("command", COMMANDS)
def test_help_shows_no_parser_artefacts_and_its_description_once(command):
    text = _help(command)
    assert "{None" not in text and "None}" not in text, text
    description = text.split("\n\n")[1].strip()
    assert text.count(description[:60]) == 1, f"{command}: the description is shown twice"


def test_every_option_of_eval_says_what_it_is():
    text = _help("eval")
    seed = next(line for line in text.splitlines() if "--seed" in line and "│" in line)
    assert "Seed of the episode" in seed


def test_help_piped_into_head_ends_quietly():
    command = f"{sys.executable} -m pianist.cli play --help | head -1"
    result = subprocess.run(command, shell=True, capture_output=True, text=True, timeout=60)
    assert result.stdout.startswith("usage: pianist play")
    assert result.stderr == ""


@pytest.mark.parametrize(
    ("factor", "text"),
    [
        (0.0443, "0.044x"),
        (0.5, "0.50x"),
        (1.02, "1.0x"),
        (9.0, "9.0x"),
        (1.54, "1.5x"),
        (9.96, "10x"),
        (11.2, "11x"),
        (0.0012, "0.0012x"),
    ],
)
def test_real_time_factors_have_two_significant_figures(factor, text):
    assert realtime_text(factor) == text


def test_play_an_excerpt_from_the_cli(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["play", "twinkle-twinkle", "--start", "2", "--seconds", "1.5", "--physics", "fast",
         "--no-audio", "--out", str(out)]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["excerpt_start_s"] == 2.0 and metrics["excerpt_seconds"] == pytest.approx(1.5)
    assert metrics["seconds"] == pytest.approx(1.5, abs=0.1)
    assert metrics["steps"] < 40  # the whole song is 160 steps
    assert "x real time" in capsys.readouterr().out


def test_an_excerpt_from_python_is_the_window_of_the_song():
    song = load_song("twinkle-twinkle")
    excerpt = excerpt_of(song, 2.0, 1.5)
    assert excerpt.duration_s == pytest.approx(1.5)
    assert all(0.0 <= n.onset_s < 1.5 for n in excerpt.notes)
    assert {n.pitch for n in excerpt.notes} <= {n.pitch for n in song.notes}
    from pianist.control.registry import build_controller

    result = play(song, build_controller("zero"), physics="fast", start_s=2.0, seconds=1.5)
    assert result.song.duration_s == pytest.approx(1.5)
    assert result.metrics["excerpt_start_s"] == 2.0
    # To the end of the song when no length is given.
    rest = play(song, build_controller("zero"), physics="fast", start_s=song.duration_s - 1.0)
    assert rest.song.duration_s == pytest.approx(1.0, abs=0.06)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--start", "500"], "past the end of twinkle-twinkle"),
        (["--start", "-1"], "start must be >= 0"),
        (["--seconds", "0"], "length must be > 0"),
    ],
)
def test_a_bad_excerpt_is_one_line(tmp_path, capsys, args, message):
    assert main(["play", "twinkle-twinkle", "--out", str(tmp_path / "o"), *args]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_folder_that_cannot_be_written_is_refused_before_playing(capsys):
    # As root, permissions allow /proc; making a folder there fails.
    started = time.perf_counter()
    assert main(["play", "mozart-sonata-k545-allegro", "--out", "/proc/pianist-out"]) == 1
    err = capsys.readouterr().err
    assert "cannot be written in /proc" in err or "is not writable" in err
    assert time.perf_counter() - started < 30  # refused before a 3-minute episode


def test_a_sweep_says_when_seeds_cannot_change_a_deterministic_controller(tmp_path, capsys):
    args = ["sweep", "--songs", "twinkle-twinkle", "--seeds", "0", "1", "--out", str(tmp_path)]
    assert main([*args, "--controllers", "planner", "refine", "--list"]) == 0
    out = capsys.readouterr().out
    assert "note: the seed does not change what planner plays" in out
    assert "refine" not in out.split("note:")[1].splitlines()[0]
    assert main([*args, "--controllers", "random", "--list"]) == 0
    assert "note:" not in capsys.readouterr().out


def test_a_comparison_page_shows_which_run_is_an_excerpt(tmp_path, capsys):
    whole, part = tmp_path / "whole", tmp_path / "part"
    base = ["play", "twinkle-twinkle", "--physics", "fast", "--no-audio"]
    assert main([*base, "--out", str(whole)]) == 0
    assert main([*base, "--start", "1", "--seconds", "2", "--out", str(part)]) == 0
    page = tmp_path / "cmp.html"
    assert main(["report", str(whole), str(part), "--out", str(page)]) == 0
    text = page.read_text()
    row = text.split('data-key="excerpt_start_s"')[1].split("</tr>")[0]
    assert "excerpt from (s)" in row and "<td>-</td>" in row and "<td>1</td>" in row
    capsys.readouterr()


def test_a_sweep_folder_that_cannot_be_made_is_one_line(capsys):
    args = ["sweep", "--songs", "twinkle-twinkle", "--controllers", "zero", "--out", "/proc/x"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "the sweep's folder /proc/x cannot be made" in err and err.count("\n") == 1
