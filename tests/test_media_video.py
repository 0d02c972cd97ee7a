"""MP4 rendering of a recorded episode: frame count, audio stream, key colours, errors, the
auto camera's framing, the stage's contrast and the falling-notes strip."""

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

from pianist.control.base import BaseController
from pianist.eval import Episode, run_episode
from pianist.media import MediaError, frame_times, interpolate_qpos, key_colours, render_episode
from pianist.media.camera import frame_points, project
from pianist.media.falling_notes import (
    BACKGROUND_RGB,
    WHITE_NOTE_RGB,
    draw_strip,
    strip_height,
    strip_layout,
)
from pianist.media.video import CORRECT_KEY_RGBA, DUE_KEY_RGBA, WRONG_KEY_RGBA
from pianist.music import Note, Song

C4_KEY = 60 - 21
FPS = 10
SIZE = (120, 160)


class _HoldStill(BaseController):
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


def test_frame_points_sees_every_point_and_is_tight() -> None:
    rng = np.random.default_rng(0)
    points = rng.uniform([-0.1, -0.45, 0.0], [0.25, 0.3, 0.15], size=(300, 3))
    fovy, size, margin = np.radians(45.0), (336, 640), 0.05
    pos, xyaxes = frame_points(points, fovy_rad=fovy, aspect=size[1] / size[0], margin=margin)
    pixels = project(points, pos, xyaxes, fovy, size)
    assert np.all(pixels[:, 2] > 0)
    # Offsets from the centre as fractions of the half-frame: within 1 - margin ...
    x = np.abs(pixels[:, 0] - size[1] / 2) / (size[1] / 2)
    y = np.abs(pixels[:, 1] - size[0] / 2) / (size[0] / 2)
    assert x.max() <= 1 - margin + 1e-9 and y.max() <= 1 - margin + 1e-9
    # ... and the closest such camera: some point touches the margin.
    assert max(x.max(), y.max()) == pytest.approx(1 - margin, abs=1e-9)
    # Low keys (-y) appear on the left, as the player sees them.
    low, high = project(np.array([[0, -0.3, 0], [0, 0.3, 0]]), pos, xyaxes, fovy, size)[:, 0]
    assert low < high


def test_falling_note_reaches_the_hit_line_at_its_onset_frame() -> None:
    dt, fps = 0.05, 30
    goal = np.zeros((40, 88), dtype=bool)
    goal[6:12, C4_KEY] = True  # due from 0.30 s (frame 9) to 0.60 s (frame 18)
    layout = strip_layout(64, 320, (-0.3, 0.3))
    column = int(np.flatnonzero(layout.column_key == C4_KEY).mean())
    keys = np.tile([0.9, 0.9, 0.9, 1.0], (88, 1))
    times = frame_times(40, dt, fps)
    hit = layout.hit_row

    def strip(frame: int) -> np.ndarray:
        return draw_strip(layout, float(times[frame]), goal, dt, keys)

    assert strip(9)[hit, column].tolist() == list(WHITE_NOTE_RGB)
    assert strip(17)[hit, column].tolist() == list(WHITE_NOTE_RGB)
    for frame in (8, 18):  # one frame before the onset, and at the offset
        assert strip(frame)[hit, column].tolist() == list(BACKGROUND_RGB), frame
    # Before it arrives the note is on its way, just above the hit line.
    lit = np.flatnonzero((strip(8)[: hit + 1, column] == WHITE_NOTE_RGB).all(axis=1))
    assert lit.size and hit - lit.max() <= layout.px_per_s / fps + 1
    # Columns of other keys stay empty.
    other = int(np.flatnonzero(layout.column_key == C4_KEY + 2).mean())
    assert strip(9)[hit, other].tolist() == list(BACKGROUND_RGB)


def test_falling_notes_keyboard_repeats_the_key_colours() -> None:
    layout = strip_layout(64, 320, (-0.3, 0.3))
    keys = np.tile([0.9, 0.9, 0.9, 1.0], (88, 1))
    keys[C4_KEY] = CORRECT_KEY_RGBA
    keys[C4_KEY + 1] = WRONG_KEY_RGBA  # C#4, a black key
    out = draw_strip(layout, 0.0, np.zeros((5, 88), bool), 0.05, keys)
    assert out.shape == (64, 320, 3) and out.dtype == np.uint8
    top, end = layout.keyboard_rows
    c4 = int(np.flatnonzero(layout.column_white_key == C4_KEY).mean())
    cs4 = int(np.flatnonzero(layout.column_key == C4_KEY + 1).mean())
    green = np.round(np.array(CORRECT_KEY_RGBA[:3]) * 255)
    red = np.round(np.array(WRONG_KEY_RGBA[:3]) * 255)
    np.testing.assert_array_equal(out[end - 1, c4], green)  # lower part: the white key
    np.testing.assert_array_equal(out[top, cs4], red)  # upper part: the black key over it
    assert strip_height(480) % 2 == 0 and strip_height(480) < 480 // 2


# ------------------------------------------------------------------ argument errors


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"camera": "ceiling"}, "unknown camera 'ceiling'; choose from auto, back, closeup"),
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


# The auto camera and the stage, measured on MuJoCo's own rendering of a random episode (hands
# anywhere): camera pose as MuJoCo computes it, segmentation to find the hands' pixels.
_STAGE_SCRIPT = textwrap.dedent(
    """
    import json, os, sys
    os.environ.setdefault("MUJOCO_GL", "egl")
    import mujoco
    import numpy as np
    from pianist.control import RandomController
    from pianist.env import PianoEnv
    from pianist.eval import run_episode
    from pianist.media.camera import add_floor, project
    from pianist.media.falling_notes import strip_height, strip_layout
    from pianist.media.video import _recoloured_copy, frame_episode, render_episode
    from pianist.music import Note, Song

    out = sys.argv[1]
    song = Song(notes=(Note(48, 0.0, 0.3), Note(72, 0.2, 0.6)), name="wide")
    env = PianoEnv(song, physics="fast")
    ep = run_episode(env, RandomController(), seed=3)
    height, width = size = (240, 320)
    model = _recoloured_copy(env.scene, mujoco)
    data = mujoco.MjData(model)
    frame_episode(model, data, env.scene, ep, size)
    cam = model.camera("front").id
    result = {"inside": {}, "pixels": {}}
    hand_bodies = {}
    for hand in env.scene.hands:
        prefix = model.body(hand.forearm_body).name.split("/")[0] + "/"
        hand_bodies[hand.side] = [b for b in range(model.nbody)
                                  if model.body(b).name.startswith(prefix)
                                  and b != hand.forearm_body]
    inside = {side: [] for side in hand_bodies}
    for row in ep.qpos:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        xmat = data.cam_xmat[cam].reshape(3, 3)
        xyaxes = np.concatenate([xmat[:, 0], xmat[:, 1]])
        fovy = np.radians(model.cam_fovy[cam])
        for side, bodies in hand_bodies.items():
            px = project(data.xpos[bodies], data.cam_xpos[cam], xyaxes, fovy, size)
            inside[side].append(bool(np.all((px[:, 2] > 0) & (px[:, 0] >= 0) & (px[:, 0] <= width)
                                            & (px[:, 1] >= 0) & (px[:, 1] <= height))))
    result["inside"] = {side: all(v) for side, v in inside.items()}

    data.qpos[:] = ep.qpos[-1]
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    renderer = mujoco.Renderer(model, height=height, width=width)
    renderer.update_scene(data, camera="front")
    add_floor(renderer.scene)
    rgb = renderer.render().astype(float)
    renderer.enable_segmentation_rendering()
    renderer.update_scene(data, camera="front")  # no floor: its pixels read as no geom
    seg = renderer.render()
    renderer.close()
    luminance = rgb @ np.array([0.299, 0.587, 0.114])
    geom_ids = seg[..., 0]
    is_geom = (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)) & (geom_ids >= 0)
    body_of = np.where(is_geom, model.geom_bodyid[np.maximum(geom_ids, 0)], -1)
    fingertips = {int(model.site_bodyid[s]) for h in env.scene.hands for s in h.fingertip_sites}
    hand_mask = np.zeros(seg.shape[:2], bool)
    for side, bodies in hand_bodies.items():
        mask = np.isin(body_of, [b for b in bodies if b not in fingertips])
        result["pixels"][side] = int(mask.sum())
        hand_mask |= mask
    background = ~is_geom  # the floor (a scene-only geom) and anything beyond it
    result["hand_luminance"] = float(luminance[hand_mask].mean())
    result["background_luminance"] = float(luminance[background].mean())
    result["background_pixels"] = int(background.sum())

    counts = {}
    variants = {"notes": dict(falling_notes=True), "auto": {}, "jagged": dict(antialias=False)}
    for name, kw in variants.items():
        counts[name] = render_episode(env, ep, f"{out}/{name}.mp4", size=size, fps=10,
                                      progress=False, **kw)
    result["counts"] = counts
    strip = strip_height(height)
    layout = strip_layout(strip, width, (-0.5, 0.5))
    result["hit_line_row"] = height - strip + layout.hit_row + 1
    result["strip_rows"] = strip
    json.dump(result, open(f"{out}/stage.json", "w"))
    """
)


@pytest.fixture(scope="module")
def stage(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("stage")
    env = {**os.environ}
    env.setdefault("MUJOCO_GL", "egl")
    proc = subprocess.run(
        [sys.executable, "-c", _STAGE_SCRIPT, str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, json.loads((out / "stage.json").read_text())


def test_auto_camera_sees_both_hands_at_every_step(stage) -> None:
    _, result = stage
    assert result["inside"] == {"right": True, "left": True}
    # MuJoCo's own rendering agrees: both hands cover a good part of the picture.
    for side in ("right", "left"):
        assert result["pixels"][side] > 0.01 * 240 * 320, result["pixels"]


def test_hands_stand_out_from_the_background(stage) -> None:
    _, result = stage
    assert result["background_pixels"] > 0.05 * 240 * 320
    # Luminance 0..255: the old stage had dark grey hands (about 55-65) on black (0).
    assert result["background_luminance"] - result["hand_luminance"] > 60, result
    assert result["hand_luminance"] > 70, result  # the hands' shapes are lit, not black


def test_a_video_without_antialiasing_is_the_same_picture_with_harder_edges(stage) -> None:
    out, result = stage
    assert result["counts"]["jagged"] == result["counts"]["auto"]
    smooth, jagged = _frames(out / "auto.mp4"), _frames(out / "jagged.mp4")
    assert smooth.shape == jagged.shape
    difference = np.abs(smooth - jagged).max(axis=-1)
    # The same scene from the same camera: most pixels are the same (the encodings of one
    # picture would be identical), and a few percent, along the edges, differ clearly.
    assert np.median(difference) <= 1
    assert 0.002 < np.mean(difference > 40) < 0.1, np.mean(difference > 40)


def test_falling_notes_keep_the_frame_size(stage) -> None:
    out, result = stage
    assert result["counts"]["notes"] == result["counts"]["auto"]
    for name in ("notes", "auto"):
        assert "320x240" in _ffmpeg_info(out / f"{name}.mp4"), name
    notes, plain = _frames(out / "notes.mp4"), _frames(out / "auto.mp4")
    assert notes.shape == plain.shape == (result["counts"]["notes"], 240, 320, 3)
    # The hit line runs across the strip in every frame; the picture above it is rendered.
    assert notes[:, result["hit_line_row"]].mean() > 200
    assert notes[:, : 240 - result["strip_rows"]].std() > 20
