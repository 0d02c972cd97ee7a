"""MP4 rendering of a recorded episode: frame count, audio stream, key colours, errors."""

from __future__ import annotations

import os

# MuJoCo reads MUJOCO_GL when it is first imported; headless rendering needs EGL (or OSMesa).
os.environ.setdefault("MUJOCO_GL", "egl")

import dataclasses
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pianist.eval import Episode, run_episode
from pianist.media import MediaError, frame_times, interpolate_qpos, key_colours, render_episode
from pianist.media.video import CORRECT_KEY_RGBA, DUE_KEY_RGBA, WRONG_KEY_RGBA
from pianist.music import Note, Song

C4_KEY = 60 - 21
FPS = 10
SIZE = (120, 160)


class _HoldStill:
    """Every actuator mid-range, pedal up: a deterministic episode without pianist.control."""

    def reset(self, env, seed=None) -> None:
        self._action = np.zeros(env.action_space.shape, dtype=np.float32)
        self._action[-1] = -1.0

    def act(self, observation) -> np.ndarray:
        return self._action


def _tiny_song() -> Song:
    return Song(notes=(Note(60, 0.0, 0.4), Note(64, 0.1, 0.5)), name="tiny")


@pytest.fixture(scope="module")
def env_and_episode():
    from pianist.env import PianoEnv

    env = PianoEnv(_tiny_song(), physics="fast")
    return env, run_episode(env, _HoldStill(), seed=0)


def _hand_episode(steps: int = 4, dt: float = 0.05) -> Episode:
    goal = np.zeros((steps, 88), dtype=bool)
    goal[:, C4_KEY] = True
    return Episode(
        actions=np.zeros((steps, 1)),
        active_keys=np.zeros((steps, 88), dtype=bool),
        sustain=np.zeros(steps, dtype=bool),
        goal_keys=goal,
        goal_sustain=np.zeros(steps, dtype=bool),
        rewards=np.zeros(steps),
        reward_terms={},
        # C4 (due) down from 0.02 s to 0.12 s; key 50 (not due) down from 0.12 s on.
        note_events=np.array(
            [[0.02, C4_KEY, 1.0], [0.12, C4_KEY, 0.0], [0.12, 50, 1.0], [0.11, -1, 1.0]]
        ),
        control_timestep_s=dt,
        end_time_s=steps * dt,
    )


# ------------------------------------------------------------------ pure helpers (no OpenGL)


def test_frame_times_cover_the_episode_inclusive() -> None:
    np.testing.assert_allclose(frame_times(11, 0.05, 10), np.arange(6) / 10)
    assert len(frame_times(100, 0.05, 30)) == 151  # 5 s at 30 fps, both ends
    assert len(frame_times(3, 0.05, 30)) == 5  # 0.15 s -> frames at 0 .. 0.133 s


def test_interpolate_qpos_is_linear_between_steps() -> None:
    qpos = np.array([[0.0, 10.0], [1.0, 20.0], [3.0, 40.0]])
    out = interpolate_qpos(qpos, np.array([0.0, 0.025, 0.05, 0.075, 0.1, 0.2]), 0.05)
    np.testing.assert_allclose(
        out, [[0, 10], [0.5, 15], [1, 20], [2, 30], [3, 40], [3, 40]], atol=1e-12
    )
    nearest = interpolate_qpos(qpos, np.array([0.02, 0.03]), 0.05, linear=False)
    np.testing.assert_allclose(nearest, [[0, 10], [1, 20]])


def test_key_colours_follow_events_and_goal() -> None:
    ep = _hand_episode()
    base = np.tile([0.9, 0.9, 0.9, 1.0], (88, 1))
    times = np.array([0.0, 0.05, 0.15])
    colours = key_colours(ep, times, base)
    assert colours.shape == (3, 88, 4)
    np.testing.assert_allclose(colours[0, C4_KEY], DUE_KEY_RGBA)  # due, not down yet
    np.testing.assert_allclose(colours[1, C4_KEY], CORRECT_KEY_RGBA)
    np.testing.assert_allclose(colours[2, C4_KEY], DUE_KEY_RGBA)  # released
    np.testing.assert_allclose(colours[2, 50], WRONG_KEY_RGBA)
    np.testing.assert_allclose(colours[1, 50], base[50])
    plain = key_colours(ep, times, base, show_goal=False)
    np.testing.assert_allclose(plain[0, C4_KEY], base[C4_KEY])


# ------------------------------------------------------------------ argument errors


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"camera": "ceiling"}, "unknown camera 'ceiling'; choose from back, closeup"),
        ({"size": (121, 160)}, "even"),
        ({"size": (1200, 1600)}, "offscreen buffer"),
        ({"size": "big"}, "size"),
        ({"fps": 0}, "fps"),
        ({"fps": float("nan")}, "fps"),
    ],
)
def test_bad_arguments_raise(env_and_episode, tmp_path, kwargs, match) -> None:
    env, ep = env_and_episode
    path = tmp_path / "x.mp4"
    with pytest.raises(MediaError, match=match):
        render_episode(env, ep, path, progress=False, **kwargs)
    assert not path.exists()


def test_episode_without_qpos_raises(env_and_episode, tmp_path) -> None:
    env, ep = env_and_episode
    with pytest.raises(MediaError, match="qpos"):
        render_episode(env, dataclasses.replace(ep, qpos=None), tmp_path / "x.mp4")
    with pytest.raises(MediaError, match="qpos"):
        render_episode(env, dataclasses.replace(ep, qpos=ep.qpos[:, :5]), tmp_path / "x.mp4")


# ------------------------------------------------------------------ rendering

# MUJOCO_GL only counts if it is set before mujoco is first imported, and in a full pytest run
# other test modules import it first. So the rendering runs in a fresh interpreter.
_RENDER_SCRIPT = textwrap.dedent(
    """
    import dataclasses, json, os, sys
    os.environ.setdefault("MUJOCO_GL", "egl")
    import numpy as np
    from pianist.env import PianoEnv
    from pianist.eval import run_episode
    from pianist.media import render_episode
    from pianist.music import Note, Song
    sys.path.insert(0, os.path.dirname(sys.argv[2]))
    from test_media_video import _HoldStill, _tiny_song, C4_KEY, FPS, SIZE

    out = sys.argv[1]
    env = PianoEnv(_tiny_song(), physics="fast")
    ep = run_episode(env, _HoldStill(), seed=0)
    steps, dt = ep.num_steps, ep.control_timestep_s
    rate = 16000
    t = np.arange(round(steps * dt * rate)) / rate
    audio = 0.3 * np.sin(2 * np.pi * 440 * t)
    kw = dict(camera="closeup", fps=FPS, size=SIZE, progress=False)
    counts = {"full": render_episode(env, ep, f"{out}/full.mp4", audio=audio,
                                     sample_rate=rate, **kw)}
    # Same motion, only the colour of C4 differs: down throughout, due or not.
    down = np.array([[0.0, C4_KEY, 1.0]])
    due = np.zeros_like(ep.goal_keys)
    due[:, C4_KEY] = True
    variants = {
        "plain": dataclasses.replace(ep, note_events=np.zeros((0, 3))),
        "green": dataclasses.replace(ep, note_events=down, goal_keys=due),
        "red": dataclasses.replace(ep, note_events=down, goal_keys=np.zeros_like(due)),
    }
    for name, variant in variants.items():
        counts[name] = render_episode(env, variant, f"{out}/{name}.mp4", show_goal=False, **kw)
    json.dump({"counts": counts, "steps": steps, "dt": dt}, open(f"{out}/result.json", "w"))
    """
)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("video")
    env = {**os.environ}
    env.setdefault("MUJOCO_GL", "egl")
    proc = subprocess.run(
        [sys.executable, "-c", _RENDER_SCRIPT, str(out), __file__],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, json.loads((out / "result.json").read_text())


def _ffmpeg_info(path: Path) -> str:
    import imageio_ffmpeg

    proc = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)],
        capture_output=True,
        text=True,
    )
    return proc.stderr


def _frames(path: Path) -> np.ndarray:
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    return np.stack([np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]).astype(
        np.int16
    )


def test_video_has_expected_frames_and_audio(rendered) -> None:
    import imageio_ffmpeg

    out, result = rendered
    expected = len(frame_times(result["steps"], result["dt"], FPS))
    assert result["counts"]["full"] == expected
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out / "full.mp4"))
    assert frames == expected
    info = _ffmpeg_info(out / "full.mp4")
    assert "Video: h264" in info and "yuv420p" in info and f"{SIZE[1]}x{SIZE[0]}" in info
    assert "Audio: aac" in info
    assert "Audio:" not in _ffmpeg_info(out / "plain.mp4")
    assert not list(out.glob(".*.mp4*"))  # no temporary file left behind


def test_pressed_key_is_coloured(rendered) -> None:
    out, _ = rendered
    plain = _frames(out / "plain.mp4")
    for name, channel in (("green", 1), ("red", 0)):
        frames = _frames(out / f"{name}.mp4")
        assert frames.shape == plain.shape
        # Pixels that changed clearly: the visible part of the C4 key.
        changed = np.abs(frames - plain).sum(axis=-1) > 90
        assert changed.sum() > 20, name
        mean = frames[changed].mean(axis=0)
        others = [c for c in range(3) if c != channel]
        assert mean[channel] > mean[others].max() + 60, (name, mean)
