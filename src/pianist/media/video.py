"""Offscreen rendering of a recorded episode to an MP4 file (H.264 video, optional AAC audio).

MuJoCo picks its OpenGL backend when it is first imported, from the ``MUJOCO_GL`` environment
variable. On a machine without a display set ``MUJOCO_GL=egl`` (GPU or Mesa EGL) or
``MUJOCO_GL=osmesa`` before anything imports ``mujoco``; this module never sets it, because by
the time it runs ``mujoco`` is usually imported already.

The replay does not touch the environment: it renders a copy of the scene's model (recoloured)
with its own ``MjData``, so an environment can go on being used afterwards.
"""

from __future__ import annotations

import copy
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.files import atomic_path
from pianist.media.camera import add_floor, auto_camera_points, frame_points, project, style_model
from pianist.media.errors import MediaError
from pianist.media.falling_notes import draw_strip, step_index, strip_height, strip_layout
from pianist.sim.constants import KEYBOARD_LENGTH_M, WHITE_KEY_HEIGHT_M, WHITE_KEY_LENGTH_M

if TYPE_CHECKING:
    from pianist.eval import Episode
    from pianist.sim.scene import Scene

PEDAL_KEY = -1
NUM_KEYS = 88
#: The default camera: the scene's ``front`` camera moved as close as it can be while seeing
#: both hands at every step and every key the episode asks for or plays (see
#: :mod:`pianist.media.camera`).
AUTO_CAMERA = "auto"
_FRAMED_CAMERA = "front"
#: Samples per pixel of an antialiased video (MuJoCo's own offscreen default).
ANTIALIAS_SAMPLES = 4

# RGBA colours. Keys: green when a sounding key is due, red when it is not, amber for a due key
# that is not sounding (shows what should be played; saturated enough to stand out on a white
# key under the lights).
CORRECT_KEY_RGBA = (0.20, 0.75, 0.30, 1.0)
WRONG_KEY_RGBA = (0.90, 0.15, 0.15, 1.0)
DUE_KEY_RGBA = (1.00, 0.72, 0.10, 1.0)
# Fingertips, thumb..little (the same on both hands), chosen apart from the key colours.
FINGER_RGBA = (
    (0.12, 0.47, 0.71, 1.0),  # thumb: blue
    (1.00, 0.50, 0.05, 1.0),  # index: orange
    (0.58, 0.40, 0.74, 1.0),  # middle: purple
    (0.89, 0.47, 0.76, 1.0),  # ring: pink
    (0.09, 0.75, 0.81, 1.0),  # little: cyan
)


def frame_times(num_steps: int, control_timestep_s: float, fps: float) -> np.ndarray:
    """Times of the video frames of an episode: every 1/fps s from 0 to the end, inclusive.

    Args:
        num_steps: T, the episode's control steps.
        control_timestep_s: seconds per step.
        fps: video frames per second.
    Returns:
        (floor(T * dt * fps) + 1,) times in seconds.
    """
    duration = num_steps * control_timestep_s
    # The epsilon keeps an end time that is a whole number of frames (up to rounding) in.
    count = math.floor(duration * fps + 1e-6) + 1
    return np.arange(count) / fps


def render_episode(
    scene: Any,
    episode: Episode,
    path: str | os.PathLike[str],
    *,
    camera: str = AUTO_CAMERA,
    fps: float = 30,
    size: tuple[int, int] = (480, 640),
    audio: np.ndarray | None = None,
    sample_rate: int = 44100,
    progress: bool = True,
    show_goal: bool = True,
    falling_notes: bool = False,
    antialias: bool = True,
) -> int:
    """Replay ``episode`` in ``scene`` and write it to an MP4 file.

    Frame i shows time i / fps (see :func:`frame_times`): the recorded joint positions
    (``episode.qpos``, one row per control step) are linearly interpolated in between steps.
    Keys sounding at that instant (from ``episode.note_events``) are green when due in that
    control step's goal and red when not; with ``show_goal``, due keys not sounding are
    amber. Each fingertip has its own colour (thumb blue, index orange, middle purple, ring
    pink, little cyan); the hands are a light blue-grey on a light floor. Shadows and
    reflections are off, for speed. A 480x640 frame takes ~35-45 ms to render and encode on a
    2-core CPU with software EGL (the first one ~0.4 s); without ``antialias`` its picture
    renders about 2.5 times as fast (multisampling, at any sample count, is most of the
    software renderer's time), with jagged edges.

    With ``falling_notes`` the lower part of each frame (:func:`strip_height` rows) is the
    falling-notes strip of :mod:`pianist.media.falling_notes` and the picture above it is
    rendered that much shorter, so the frame keeps ``size``.

    Args:
        scene: the :class:`pianist.sim.scene.Scene` the episode was played in (a
            :class:`~pianist.eval.session.PlayResult`'s), or the :class:`pianist.env.PianoEnv`
            or :class:`pianist.env.handle.ControlHandle` that played it (their scene); read,
            never changed.
        episode: a recorded episode with ``qpos`` (as :func:`pianist.eval.run_episode` makes).
        path: the .mp4 file to write, atomically; its folder must exist.
        camera: ``auto`` (the default: both hands and the keys played, from above the
            player's seat, framed on this episode) or a camera name of the model (front,
            closeup, left, right, back, egocentric, topdown).
        fps: video frames per second, > 0.
        size: (height, width) in pixels, both even (H.264 4:2:0) and within the model's
            offscreen buffer (1920x1080).
        audio: None, or (n,) / (n, 2) float samples in [-1, 1] starting at episode time 0,
            e.g. from :func:`pianist.media.synthesize_events`; it is muxed as AAC, cut or padded
            with silence to the video's length.
        sample_rate: Hz of ``audio``.
        progress: show a tqdm progress bar on stderr.
        show_goal: tint due keys that are not sounding.
        falling_notes: draw the falling-notes strip under the picture.
        antialias: smooth edges by multisampling (:data:`ANTIALIAS_SAMPLES` per pixel).
    Returns:
        The number of video frames written.
    Raises:
        MediaError: bad arguments, no OpenGL context, or ffmpeg failing.
    """
    import mujoco

    from pianist.sim.scene import Scene

    scene = scene if isinstance(scene, Scene) else scene.scene
    model_in = scene.model
    height, width, fps = check_video_options(model_in, camera, fps, size, falling_notes)
    qpos = _check_qpos(episode, model_in.nq)
    times = frame_times(episode.num_steps, episode.control_timestep_s, fps)

    model = _recoloured_copy(scene, mujoco)
    # Read when the renderer's context is made: the offscreen buffer's samples per pixel.
    model.vis.quality.offsamples = ANTIALIAS_SAMPLES if antialias else 0
    data = mujoco.MjData(model)
    key_geoms = np.asarray(scene.key_geoms)
    hinge_only = bool(
        np.all(
            (model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
            | (model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE)
        )
    )
    frame_qpos = interpolate_qpos(qpos, times, episode.control_timestep_s, linear=hinge_only)
    frame_keys = key_colours(episode, times, model.geom_rgba[key_geoms], show_goal=show_goal)

    strip_rows = strip_height(height) if falling_notes else 0
    picture = (height - strip_rows, width)
    if camera == AUTO_CAMERA:
        frame_episode(model, data, scene, episode, picture)
        camera = _FRAMED_CAMERA
    layout = None
    if falling_notes:
        span = keyboard_span(model, data, model.camera(camera).id, picture)
        layout = strip_layout(strip_rows, width, span)
    goal_keys = np.asarray(episode.goal_keys, dtype=bool)

    renderer = _make_renderer(mujoco, model, *picture)

    def frames() -> Iterator[np.ndarray]:
        for time_i, qpos_i, keys_i in zip(times, frame_qpos, frame_keys, strict=True):
            data.qpos[:] = qpos_i
            mujoco.mj_kinematics(model, data)
            mujoco.mj_camlight(model, data)  # cameras and lights are not part of kinematics
            model.geom_rgba[key_geoms] = keys_i
            renderer.update_scene(data, camera=camera)
            add_floor(renderer.scene)
            image = renderer.render()
            if layout is not None:
                strip = draw_strip(
                    layout, float(time_i), goal_keys, episode.control_timestep_s, keys_i
                )
                image = np.concatenate([image, strip])
            yield image

    try:
        with tempfile.TemporaryDirectory(prefix="pianist-video-") as workdir:
            audio_path = None
            if audio is not None:
                audio_path = Path(workdir) / "audio.wav"
                _write_track(audio, len(times) / fps, sample_rate, audio_path)
            with atomic_path(path, suffix=".mp4", error=MediaError) as tmp:
                _encode(frames(), tmp, width, height, fps, audio_path, len(times), progress)
    finally:
        renderer.close()
    return len(times)


def check_video_options(
    model: Any, camera: str, fps: float, size: tuple[int, int], falling_notes: bool = False
) -> tuple[int, int, float]:
    """Validate video options before an episode is played, so a typo fails at once.

    Args:
        model: the ``mujoco.MjModel`` that will be rendered.
        camera, fps, size, falling_notes: as in :func:`render_episode` (the strip needs rows
            of its own under a picture of at least 16).
    Returns:
        (height, width, fps) as ints and a float.
    Raises:
        MediaError: an unknown camera, a bad frame rate or size.
    """
    cameras = sorted([AUTO_CAMERA, *(model.camera(i).name for i in range(model.ncam))])
    if camera not in cameras:
        raise MediaError(f"unknown camera {camera!r}; choose from {', '.join(cameras)}")
    height, width = _check_size(size, model)
    if falling_notes and height - strip_height(height) < 16:
        raise MediaError(
            f"a video {height} pixels high has no room for the falling-notes strip under its "
            "picture: give a height of 32 or more"
        )
    return height, width, _check_fps(fps)


def interpolate_qpos(
    qpos: np.ndarray, times: np.ndarray, control_timestep_s: float, *, linear: bool = True
) -> np.ndarray:
    """Joint positions at arbitrary times from one row per control step.

    Args:
        qpos: (T + 1, nq) positions at times 0, dt, ..., T dt.
        times: (F,) seconds; clamped to [0, T dt].
        control_timestep_s: dt.
        linear: interpolate linearly (valid when every joint is a hinge or a slide; quaternions
            of free or ball joints are not); False takes the nearest row.
    Returns:
        (F, nq) positions.
    """
    qpos = np.asarray(qpos, dtype=np.float64)
    last = len(qpos) - 1
    steps = np.clip(np.asarray(times, dtype=np.float64) / control_timestep_s, 0, last)
    if last == 0 or not linear:
        return qpos[np.round(steps).astype(int)]
    lower = np.minimum(steps.astype(int), last - 1)
    weight = (steps - lower)[:, None]
    return (1.0 - weight) * qpos[lower] + weight * qpos[lower + 1]


def key_colours(
    episode: Episode, times: np.ndarray, base_rgba: np.ndarray, *, show_goal: bool = True
) -> np.ndarray:
    """Colour of every key at each frame time.

    A key sounding at time t (replaying ``episode.note_events``) is green when it is due in the
    goal of the control step containing t, red when not; with ``show_goal`` a due key that is
    not sounding is pale yellow; other keys keep ``base_rgba``.

    Args:
        episode: the record (``note_events``, ``goal_keys``, ``control_timestep_s``).
        times: (F,) seconds.
        base_rgba: (88, 4) the keys' own colours.
    Returns:
        (F, 88, 4) float RGBA.
    """
    times = np.asarray(times, dtype=np.float64)
    sounding = _sounding_keys(episode.note_events, times)
    goal_keys = np.asarray(episode.goal_keys, dtype=bool)
    rows = np.clip(step_index(times, episode.control_timestep_s), 0, len(goal_keys) - 1)
    due = goal_keys[rows]
    out = np.repeat(np.asarray(base_rgba, dtype=np.float64)[None], len(times), axis=0)
    if show_goal:
        out[due] = DUE_KEY_RGBA
    out[sounding & due] = CORRECT_KEY_RGBA
    out[sounding & ~due] = WRONG_KEY_RGBA
    return out


# --------------------------------------------------------------------------------- internals


def _check_size(size: Any, model: Any) -> tuple[int, int]:
    try:
        height, width = (int(v) for v in size)
    except (TypeError, ValueError):
        raise MediaError(f"size must be (height, width) in pixels, not {size!r}") from None
    if height < 16 or width < 16 or height % 2 or width % 2:
        raise MediaError(f"video size must be even and at least 16x16 pixels, not {height}x{width}")
    max_w, max_h = model.vis.global_.offwidth, model.vis.global_.offheight
    if width > max_w or height > max_h:
        raise MediaError(
            f"video size {height}x{width} (height x width) exceeds the offscreen buffer "
            f"{max_h}x{max_w}"
        )
    return height, width


def _check_fps(fps: Any) -> float:
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise MediaError(f"fps must be a number, not {fps!r}") from None
    if not math.isfinite(value) or not 0 < value <= 240:
        raise MediaError(f"fps must be in (0, 240], not {fps!r}")
    return value


def _check_qpos(episode: Any, nq: int) -> np.ndarray:
    qpos = episode.qpos
    if qpos is None:
        raise MediaError("the episode has no joint positions (qpos) to replay")
    qpos = np.asarray(qpos, dtype=np.float64)
    if episode.num_steps < 1:
        raise MediaError("the episode has no steps")
    if qpos.shape != (episode.num_steps + 1, nq):
        raise MediaError(
            f"episode qpos has shape {qpos.shape}, expected {(episode.num_steps + 1, nq)} "
            "for this environment"
        )
    return qpos


def frame_episode(
    model: Any, data: Any, scene: Any, episode: Episode, size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Move ``model``'s ``front`` camera to frame the episode (see :mod:`pianist.media.camera`).

    Args:
        model: a render-only model copy (changed in place); data: a scratch ``MjData``.
        scene: the environment's :class:`pianist.sim.scene.Scene` (hands and keys).
        episode: the record (qpos, goal keys, note events).
        size: (height, width) of the picture.
    Returns:
        (pos, xyaxes) of the camera, as :func:`pianist.media.camera.frame_points` gives them.
    """
    import mujoco

    hand_bodies = [
        body
        for hand in scene.hands
        for body in range(model.nbody)
        if model.body(body).name.startswith(model.body(hand.forearm_body).name.split("/")[0] + "/")
        and body != hand.forearm_body
    ]
    events = np.asarray(episode.note_events, dtype=np.float64).reshape(-1, 3)
    played = events[(events[:, 1] >= 0) & (events[:, 2] != 0), 1].astype(int)
    asked = np.flatnonzero(np.asarray(episode.goal_keys, dtype=bool).any(axis=0))
    keys = np.union1d(played, asked)
    qpos = _check_qpos(episode, model.nq)
    points = auto_camera_points(
        model, data, qpos, np.asarray(hand_bodies, dtype=int), np.asarray(scene.key_geoms)[keys]
    )
    cam = model.camera(_FRAMED_CAMERA).id
    fovy = np.radians(model.cam_fovy[cam])
    pos, xyaxes = frame_points(points, fovy_rad=float(fovy), aspect=size[1] / size[0])
    right, up = xyaxes[:3], xyaxes[3:]
    rotation = np.stack([right, up, np.cross(right, up)], axis=1)  # columns: camera x, y, z
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rotation.flatten())
    model.cam_pos[cam] = pos
    model.cam_quat[cam] = quat
    return pos, xyaxes


def keyboard_span(model: Any, data: Any, camera: int, size: tuple[int, int]) -> tuple[float, float]:
    """World y (m) along the keyboard's front edge seen at the picture's left and right edges.

    For a camera whose image rows run along the keyboard (the auto, front, closeup and back
    cameras) the falling notes then line up with the keys above them; for the others it is
    the whole keyboard.
    """
    import mujoco

    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    xmat = data.cam_xmat[camera].reshape(3, 3)
    right, forward = xmat[:, 0], -xmat[:, 2]
    half = KEYBOARD_LENGTH_M / 2
    if abs(right[1]) < 0.9 or abs(forward[1]) > 0.05:
        return (-half, half)
    edge = np.array([[WHITE_KEY_LENGTH_M / 2, y, WHITE_KEY_HEIGHT_M] for y in (-half, half)])
    pixels = project(
        edge,
        data.cam_xpos[camera],
        np.concatenate([xmat[:, 0], xmat[:, 1]]),
        float(np.radians(model.cam_fovy[camera])),
        size,
    )
    (c0, _, d0), (c1, _, d1) = pixels
    if min(d0, d1) <= 0:
        return (-half, half)
    per_px = 2 * half / (c1 - c0)
    return (-half - c0 * per_px, -half + (size[1] - c0) * per_px)


def _recoloured_copy(scene: Scene, mujoco: Any) -> Any:
    """A copy of the model with flat-coloured fingertips, lighter hands, brighter lights and
    sleeping disabled."""
    model = copy.deepcopy(scene.model)
    style_model(model)
    # A fresh MjData has everything awake, but keep kinematics from ever skipping a body.
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    for hand in scene.hands:
        for finger, site in enumerate(hand.fingertip_sites):
            geoms = np.flatnonzero(model.geom_bodyid == model.site_bodyid[site])
            # A geom's material colour overrides its rgba: drop the material.
            model.geom_matid[geoms] = -1
            model.geom_rgba[geoms] = FINGER_RGBA[finger]
    model.geom_matid[np.asarray(scene.key_geoms)] = -1
    return model


def _sounding_keys(events: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(frames, 88) bool: keys down at each frame time, replaying (time, key, on) events."""
    events = np.asarray(events, dtype=np.float64).reshape(-1, 3)
    events = events[events[:, 1] != PEDAL_KEY]
    events = events[np.argsort(events[:, 0], kind="stable")]
    state = np.zeros(NUM_KEYS, dtype=bool)
    out = np.zeros((len(times), NUM_KEYS), dtype=bool)
    cursor = 0
    for i, t in enumerate(times):
        while cursor < len(events) and events[cursor, 0] <= t:
            state[int(events[cursor, 1])] = events[cursor, 2] != 0
            cursor += 1
        out[i] = state
    return out


def _make_renderer(mujoco: Any, model: Any, height: int, width: int) -> Any:
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # MuJoCo raises several types for a missing GL context
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MediaError(
            f"cannot create an offscreen OpenGL context ({reason}); set MUJOCO_GL=egl or "
            "MUJOCO_GL=osmesa before mujoco is imported"
        ) from exc
    # Shadows and reflections multiply the render time wherever a light casts shadows or a
    # material reflects, and add little to a replay. (The current scene has neither, so today
    # this changes nothing measurable; it keeps the cost flat if the stage gains them.)
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
    return renderer


def _write_track(audio: np.ndarray, duration_s: float, sample_rate: int, path: Path) -> None:
    """Write ``audio`` cut or zero-padded to ``duration_s`` as a WAV file."""
    from pianist.media.audio import write_wav

    audio = np.asarray(audio, dtype=np.float32)
    if audio.ndim not in (1, 2) or (audio.ndim == 2 and audio.shape[1] not in (1, 2)):
        raise MediaError(f"audio must have shape (n,) or (n, 2), not {audio.shape}")
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, int | np.integer):
        raise MediaError(f"sample rate must be an integer number of Hz, not {sample_rate!r}")
    n = round(duration_s * sample_rate)
    if len(audio) >= n:
        track = audio[:n]
    else:
        pad = np.zeros((n - len(audio), *audio.shape[1:]), dtype=np.float32)
        track = np.concatenate([audio, pad])
    write_wav(track, path, sample_rate)


def _encode(
    frames: Any,
    path: Path,
    width: int,
    height: int,
    fps: float,
    audio_path: Path | None,
    total: int,
    progress: bool,
) -> None:
    """Encode frames (H.264, yuv420p) and optional audio (AAC) to ``path`` with ffmpeg."""
    import imageio_ffmpeg
    from tqdm import tqdm

    writer = imageio_ffmpeg.write_frames(
        str(path),
        size=(width, height),
        fps=fps,
        codec="libx264",
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        quality=None,
        # The size is checked to be even; 1 stops imageio-ffmpeg from resizing to multiples of 16.
        macro_block_size=1,
        ffmpeg_log_level="error",
        # Constant quality; faststart puts the index first so browsers can start playing early.
        output_params=["-crf", "20", "-preset", "veryfast", "-movflags", "+faststart"],
        audio_path=None if audio_path is None else str(audio_path),
        audio_codec=None if audio_path is None else "aac",
    )
    try:
        writer.send(None)  # start ffmpeg
        for frame in tqdm(frames, total=total, unit="frame", disable=not progress, leave=False):
            writer.send(np.ascontiguousarray(frame))
        writer.close()
    except (OSError, RuntimeError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MediaError(f"ffmpeg failed while writing the video: {reason}") from exc
    finally:
        writer.close()
