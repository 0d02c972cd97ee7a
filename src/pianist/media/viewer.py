"""Watching a song being played: MuJoCo's interactive viewer, at the pace of the music.

:func:`view` plays one episode exactly as :func:`pianist.eval.session.play` does (the same
environment, controller and metrics; it *is* ``play``), with the environment wrapped so that
after every step the viewer window shows the new state and the episode waits for the wall
clock: step t is shown at (t + 1) dt seconds after the start, unless the controller is slower
than real time. The keys are coloured as in the video (:func:`pianist.media.video.key_colours`):
green when sounding and due, red when sounding and not due, amber when due and silent. Closing
the window ends the episode there; it is scored over the steps played.

The viewer needs a display: an X server (``DISPLAY``), e.g. ``xvfb-run -a pianist view ...``
without a screen. MuJoCo's viewer opens its window with GLFW (the ``glfw`` package ships the
library) and draws with OpenGL (Debian: libgl1, libglx-mesa0, libgl1-mesa-dri).
"""

from __future__ import annotations

import os
import sys
import threading
import time
import warnings
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from pianist.media.errors import MediaError

NO_DISPLAY = "pianist view needs a display (set DISPLAY, or run under xvfb-run)"
#: The scene camera the window starts from (a free camera placed where it is).
START_CAMERA = "front"
# Seconds to wait for the viewer's thread to tear down its window after closing it: exiting
# the interpreter while it still runs crashes in the GL driver.
_CLOSE_TIMEOUT_S = 10.0


def check_display() -> None:
    """Refuse to start without a display a window can be opened on.

    Raises:
        MediaError: no ``DISPLAY`` (Linux), or GLFW cannot open it; one line.
    """
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise MediaError(NO_DISPLAY)
    import glfw

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # glfw warns as well as returning False
        ok = glfw.init()
        # The viewer's own thread initialises GLFW again; leave it as we found it.
        if ok:
            glfw.terminate()
    if not ok:
        shown = os.environ.get("DISPLAY", "")
        raise MediaError(f"{NO_DISPLAY}: cannot open display {shown!r}")


@dataclass
class ViewStats:
    """What the window showed.

    Attributes:
        frames: viewer syncs (one after reset, one per step shown).
        steps: steps played.
        wall_s: seconds from the first step to the last one shown.
        closed: the window was closed before the song ended.
    """

    frames: int = 0
    steps: int = 0
    wall_s: float = 0.0
    closed: bool = False


class LiveView:
    """A viewer window showing a piano environment's state, its keys coloured.

    The window shows a render-only copy of the scene (styled as the video is), so the
    environment's own model and state are never touched.
    """

    def __init__(self, env: gym.Env, *, show_ui: bool = False) -> None:
        import mujoco
        import mujoco.viewer

        from pianist.env.handle import control_handle
        from pianist.media.video import _recoloured_copy

        self._mujoco = mujoco
        self._handle = control_handle(env)
        self.model = _recoloured_copy(self._handle.scene, mujoco)
        self.data = mujoco.MjData(self.model)
        self._key_geoms = np.asarray(self._handle.scene.key_geoms)
        self._base_rgba = self.model.geom_rgba[self._key_geoms].copy()
        self._copy_state()
        before = set(threading.enumerate())
        self._viewer = mujoco.viewer.launch_passive(
            self.model, self.data, show_left_ui=show_ui, show_right_ui=show_ui
        )
        self._threads = [t for t in threading.enumerate() if t not in before]
        self._place_camera()
        self.frames = 0

    def is_running(self) -> bool:
        return bool(self._viewer.is_running())

    def label(self, text: str) -> None:
        """Write ``text`` in the window's top-left corner (it waits for the window's next
        frame: once per episode, not per step)."""
        self._viewer.set_texts((None, None, text, ""))

    def show(self, sounding: np.ndarray, due: np.ndarray) -> bool:
        """Show the environment's current state with ``sounding`` and ``due`` keys, (88,) bool
        each; returns whether the window is still open."""
        if not self._viewer.is_running():
            return False
        with self._viewer.lock():
            self._copy_state()
            self.model.geom_rgba[self._key_geoms] = colour_keys(sounding, due, self._base_rgba)
        self._viewer.sync()
        self.frames += 1
        return True

    def close(self) -> None:
        """Close the window and wait for the viewer's thread to finish with it."""
        self._viewer.close()
        for thread in self._threads:
            thread.join(_CLOSE_TIMEOUT_S)

    def _copy_state(self) -> None:
        mujoco = self._mujoco
        self.data.qpos[:] = self._handle.data.qpos
        self.data.time = self._handle.data.time
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    def _place_camera(self) -> None:
        """Start from the scene's front camera, as a free camera the user can move."""
        model, data = self.model, self.data
        try:
            camera = model.camera(START_CAMERA).id
        except KeyError:
            return
        position = data.cam_xpos[camera]
        forward = -data.cam_xmat[camera].reshape(3, 3)[:, 2]  # cameras look along -z
        if forward[2] >= 0:
            return
        # Orbit the point where the line of sight meets the keys' height.
        key_z = float(data.site_xpos[np.asarray(self._handle.scene.key_sites)][:, 2].mean())
        distance = (key_z - position[2]) / forward[2]
        with self._viewer.lock():
            cam = self._viewer.cam
            cam.lookat[:] = position + distance * forward
            cam.distance = float(distance)
            cam.azimuth = float(np.degrees(np.arctan2(forward[1], forward[0])))
            cam.elevation = float(np.degrees(np.arcsin(forward[2])))


def colour_keys(sounding: np.ndarray, due: np.ndarray, base_rgba: np.ndarray) -> np.ndarray:
    """(88, 4) RGBA of the keys for one instant, by the video's rule
    (:func:`pianist.media.video.key_colours`): sounding and due green, sounding and not due red,
    due and silent amber, others ``base_rgba`` (88, 4)."""
    from pianist.media.video import CORRECT_KEY_RGBA, DUE_KEY_RGBA, WRONG_KEY_RGBA

    sounding = np.asarray(sounding, dtype=bool)
    due = np.asarray(due, dtype=bool)
    out = np.array(base_rgba, dtype=np.float64, copy=True)
    out[due] = DUE_KEY_RGBA
    out[sounding & due] = CORRECT_KEY_RGBA
    out[sounding & ~due] = WRONG_KEY_RGBA
    return out


class _Paced(gym.Wrapper):
    """Shows every step in the window and holds it until its wall-clock time; a closed window
    truncates the episode."""

    def __init__(self, env: gym.Env, stats: ViewStats, realtime: bool, label: str) -> None:
        super().__init__(env)
        self._stats = stats
        self._realtime = realtime
        self._label = label
        self._view: LiveView | None = None
        self._start = 0.0

    def reset(self, **kwargs: Any) -> Any:
        observation, info = self.env.reset(**kwargs)
        if self._view is None:
            self._view = LiveView(self.env)
            if self._label:
                self._view.label(self._label)
        self._view.show(info["active_keys"], np.zeros_like(info["active_keys"]))
        self._stats.frames = self._view.frames
        self._stats.steps = 0
        self._start = time.perf_counter()
        return observation, info

    def step(self, action: Any) -> Any:
        from pianist.env.handle import control_handle

        if self._view is None:
            raise RuntimeError("step before reset")
        observation, reward, terminated, truncated, info = self.env.step(action)
        self._stats.steps += 1
        dt = control_handle(self.env).control_timestep_s
        if self._realtime:
            wait = self._start + self._stats.steps * dt - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
        if not self._view.show(info["active_keys"], info["goal_keys"]):
            self._stats.closed = True
            truncated = True
        self._stats.frames = self._view.frames
        self._stats.wall_s = time.perf_counter() - self._start
        return observation, reward, terminated, truncated, info

    def close_view(self) -> None:
        if self._view is not None:
            self._view.close()
            self._view = None


class _Watched:
    """``controller`` as it is, but for the environment it plays in, which it wraps in a
    :class:`_Paced` window (over its own ``wrap_env``). Everything else
    :func:`pianist.eval.session.play` asks of a controller is the controller's."""

    def __init__(self, controller: Any, stats: ViewStats, realtime: bool, label: str) -> None:
        self._controller = controller
        self._stats = stats
        self._realtime = realtime
        self._label = label
        self.paced: _Paced | None = None

    def wrap_env(self, env: gym.Env) -> gym.Env:
        inner = self._controller.wrap_env(env)
        self.paced = _Paced(inner, self._stats, self._realtime, self._label)
        return self.paced

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._controller.reset(env, seed=seed)

    def act(self, observation: Any) -> Any:
        return self._controller.act(observation)

    # The rest of what play() asks of a controller is the controller's own.

    def env_options(self, song: Any = None) -> dict[str, Any]:
        return self._controller.env_options(song)

    def stats(self) -> dict[str, float]:
        return self._controller.stats()

    def options_dict(self) -> dict[str, Any]:
        return self._controller.options_dict()

    def plan_arrays(self) -> dict[str, np.ndarray]:
        return self._controller.plan_arrays()

    def close(self) -> None:
        self._controller.close()


def view(
    song: Any,
    controller: Any,
    *,
    realtime: bool = True,
    **play_options: Any,
) -> tuple[Any, ViewStats]:
    """Play ``song`` with ``controller`` in a viewer window (see the module docstring).

    Args:
        song: a Song, a built-in song name or a song file.
        controller: any controller.
        realtime: wait for the wall clock after each step (False: as fast as it plays).
        play_options: :func:`pianist.eval.session.play`'s keyword options (physics, fingering,
            seed, initial_buffer_s, env_options).
    Returns:
        The :class:`pianist.eval.session.PlayResult` (metrics over the steps played) and
        :class:`ViewStats`.
    Raises:
        MediaError: no display.
    """
    from pianist.eval.session import play, resolve_env_options
    from pianist.music import Song, load_song

    check_display()
    if not isinstance(song, Song):
        song = load_song(song, fingering=play_options.get("fingering", "auto"))
    # Refused options name the controller itself, not the window around it.
    env_options = play_options.get("env_options") or {}
    resolve_env_options(controller, song, physics=play_options.get("physics"), **env_options)
    stats = ViewStats()
    watched = _Watched(controller, stats, realtime, song.name)
    try:
        result = play(song, watched, **play_options)
    finally:
        if watched.paced is not None:
            watched.paced.close_view()
    return result, stats
