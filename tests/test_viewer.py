"""``pianist view``: the episode in MuJoCo's viewer window, at the pace of the music."""

import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from pianist.control import make_controller
from pianist.eval.session import play
from pianist.media import viewer
from pianist.media.video import CORRECT_KEY_RGBA, DUE_KEY_RGBA, WRONG_KEY_RGBA
from pianist.music import load_song
from pianist.music.transforms import window

SONG = "c-major-chords"  # the shortest debug song (4 s)
SECONDS = 2.0


def _pianist(*args: str, env: dict[str, str], prefix: tuple[str, ...] = ()):
    return subprocess.run(
        [*prefix, sys.executable, "-m", "pianist.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )


def test_view_without_a_display_is_one_line():
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    result = _pianist("view", SONG, env=env)
    assert result.returncode == 1
    assert result.stderr.strip() == f"pianist: error: {viewer.NO_DISPLAY}"


def test_view_plays_the_song_in_real_time_under_xvfb():
    xvfb_run = shutil.which("xvfb-run")
    if xvfb_run is None:
        pytest.fail(
            "xvfb-run is not installed: apt-get install -y --no-install-recommends xvfb xauth "
            "(.ci/run installs it)"
        )
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    args = ("view", SONG, "--physics", "fast", "--seconds", str(SECONDS))
    result = _pianist(*args, env=env, prefix=(xvfb_run, "-a"))
    assert result.returncode == 0, result.stderr[-3000:]
    line = result.stdout.strip().splitlines()[-1]
    found = re.search(
        r"F1 (\d\.\d+) .*\((\d+) steps, (\d+) viewer frames, ([\d.]+) s of music in ([\d.]+) s\)",
        line,
    )
    assert found, line
    f1, steps, frames = float(found[1]), int(found[2]), int(found[3])
    music_s, wall_s = float(found[4]), float(found[5])
    # The same episode as `pianist play` of the same excerpt: the window changes nothing.
    excerpt = window(load_song(SONG, fingering="auto"), 0.0, SECONDS)
    expected = play(excerpt, make_controller("planner"), physics="fast").metrics
    assert steps == expected["steps"] and f1 == pytest.approx(expected["f1"], abs=5e-4)
    # One frame after reset and one per step, paced to the music.
    assert frames == steps + 1
    assert music_s == pytest.approx(steps * 0.05)
    assert wall_s >= 0.95 * music_s


class _StubView:
    """Stands in for the window: counts what it is shown, closes after ``open_for`` steps."""

    shown: list[tuple[np.ndarray, np.ndarray]] = []
    open_for = 10

    def __init__(self, env):
        self.frames = 0

    def label(self, text):
        pass

    def show(self, sounding, due):
        if self.frames > self.open_for:
            return False
        _StubView.shown.append((np.array(sounding), np.array(due)))
        self.frames += 1
        return True

    def close(self):
        pass


def test_closing_the_window_ends_the_episode_scored_so_far(monkeypatch):
    monkeypatch.setattr(viewer, "LiveView", _StubView)
    monkeypatch.setattr(viewer, "check_display", lambda: None)
    _StubView.shown = []
    result, stats = viewer.view(SONG, make_controller("zero"), realtime=False, physics="fast")
    assert stats.closed
    # The step whose frame found the window closed is the last one played.
    assert result.metrics["steps"] == stats.steps == _StubView.open_for + 1
    assert result.episode.num_steps == stats.steps
    # Each step showed the keys that sounded and were due at its end.
    shown = np.array([due for _, due in _StubView.shown[1:]])
    np.testing.assert_array_equal(shown, result.episode.goal_keys[: len(shown)])


def test_keys_are_coloured_as_in_the_video():
    base = np.tile([0.9, 0.9, 0.9, 1.0], (88, 1))
    sounding = np.zeros(88, dtype=bool)
    due = np.zeros(88, dtype=bool)
    sounding[[10, 20]] = True
    due[[10, 30]] = True
    colours = viewer.colour_keys(sounding, due, base)
    np.testing.assert_allclose(colours[10], CORRECT_KEY_RGBA)
    np.testing.assert_allclose(colours[20], WRONG_KEY_RGBA)
    np.testing.assert_allclose(colours[30], DUE_KEY_RGBA)
    np.testing.assert_allclose(colours[0], base[0])
