"""Playing a song with a controller: the one path the CLI, evaluation and benchmarks share.

:func:`make_env` builds the environment a controller plays in (the one place where a
controller's declared environment options are applied); :func:`play` loads the song (or an
excerpt of it), builds that environment once, plays one episode and collects the metrics
into a :class:`PlayResult`, data only. Writing a result's files is
:func:`pianist.media.results.write_result`; :func:`pianist.media.results.play_to_folder` does
both, as ``pianist play`` does.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import gymnasium as gym
import numpy as np

from pianist.control.base import Controller
from pianist.env import PianoEnv
from pianist.env.handle import control_handle
from pianist.eval.episode import Episode
from pianist.eval.errors import f1_lost_by_kind, note_errors
from pianist.eval.rollout import run_episode
from pianist.music import GoalFrames, Song, load_song
from pianist.music.transforms import window

if TYPE_CHECKING:
    from pianist.sim.scene import Scene

Fingering = Literal["auto", "file", "robot", "none"]


@dataclass
class PlayResult:
    """One played episode and what it was played with: data only, no live environment.

    Attributes:
        song: the song as played (its fingering resolved).
        episode: the episode record (actions, keys, events, qpos over its T steps).
        metrics: the episode's metrics, the controller's own statistics and settings, the
            options below, ``wall_seconds`` and ``realtime_factor`` (simulated / wall time).
        goal: the goal frames the episode was scored against.
        scene: the compiled scene it was played in (its model and index arrays, read only:
            for replaying the episode in a video or reading key angles).
        reward_weights: the reward terms' weights.
        observation_space, action_space: the environment's own spaces (inside any wrapper
            of the controller's).
        env_options: the :class:`PianoEnv` options used, the controller's included.
    """

    song: Song
    episode: Episode
    metrics: dict[str, Any]
    goal: GoalFrames
    scene: Scene
    reward_weights: dict[str, float]
    observation_space: gym.Space
    action_space: gym.Space
    env_options: dict[str, Any] = field(default_factory=dict)


def resolve_env_options(controller: Controller, song: Song, **options: Any) -> dict[str, Any]:
    """The user's environment ``options`` with the controller's declared ones applied.

    Options given as None are left to the environment's defaults. A declared option wins over
    a default; a different explicit choice is refused.

    Raises:
        ValueError: an explicit option contradicts what the controller needs.
    """
    chosen = {k: v for k, v in options.items() if v is not None}
    declared = dict(controller.env_options(song))
    for key, value in declared.items():
        if key in chosen and _normalise(chosen[key]) != _normalise(value):
            name = type(controller).__name__
            raise ValueError(
                f"this controller ({name}) plays with {key}={value!r} (its own), not "
                f"{key}={chosen[key]!r}: leave out that choice"
            )
    return {**chosen, **declared}


def make_env(song: Song | str | Path, controller: Controller, **options: Any) -> gym.Env:
    """The environment ``controller`` plays ``song`` in.

    Args:
        song: a Song (or a name or file, loaded with its own fingering).
        controller: any controller; its ``env_options(song)`` are applied over ``options`` and
            its ``wrap_env(env)``, if it has one, wraps the result (a trained policy observes
            its task's extra entries).
        options: :class:`PianoEnv` keyword options; None values mean the default.
    """
    if not isinstance(song, Song):
        song = load_song(song)
    return _build_env(song, controller, resolve_env_options(controller, song, **options))


def _build_env(
    song: Song, controller: Controller, resolved: dict[str, Any], recorder: bool = False
) -> gym.Env:
    """The environment for already resolved options, wrapped as the controller asks (and,
    with ``recorder``, in an :class:`ObservationRecorder` first, inside the controller's
    wrapper)."""
    env: gym.Env = PianoEnv(song, **resolved)
    if recorder:
        env = ObservationRecorder(env)
    return controller.wrap_env(env)


def play(
    song: Song | str | Path,
    controller: Controller,
    *,
    physics: str | None = None,
    fingering: Fingering = "auto",
    initial_buffer_s: float = 0.0,
    seed: int | None = 0,
    env_options: dict[str, Any] | None = None,
    progress: bool = False,
    record_observations: bool = False,
    check_scene: Callable[[Scene], None] | None = None,
    start_s: float = 0.0,
    seconds: float | None = None,
) -> PlayResult:
    """Play ``song`` once with ``controller`` and score it.

    Args:
        song: a built-in song name, a MIDI or PIG file, or a Song.
        controller: any controller (``reset(env, seed)``, ``act(observation)``).
        physics: "faithful" or "fast"; None: the controller's own, else faithful.
        fingering: how a song given by name or file is fingered
            (:func:`pianist.music.load_song`).
        initial_buffer_s: seconds of silence before the song (>= 0).
        seed: the episode's seed (environment and controller).
        env_options: further :class:`PianoEnv` options.
        progress: show a progress bar on stderr.
        record_observations: also keep the environment's own observations (before any wrapper
            of the controller) in ``episode.extra["observations"]``: name -> (T + 1, ...)
            array, the reset's first; and each step's end flags, ``extra["terminations"]`` and
            ``extra["truncations"]``, (T,) bool (for demonstration datasets; off by default).
        check_scene: called with the scene once the environment is built, before the episode
            (to refuse media options the scene cannot render before a long episode).
        start_s, seconds: play only the excerpt of the song from ``start_s`` for ``seconds``
            (None: to its end), from a silent start (the hands at rest, the notes already
            sounding at ``start_s`` struck again); its metrics and files are the excerpt's,
            and metrics.json records ``excerpt_start_s`` and ``excerpt_seconds``.
    Raises:
        ValueError: a negative lead-in or seed, an excerpt outside the song, or options the
            controller cannot play with.
        MusicError: the song cannot be loaded.
    """
    if not (math.isfinite(initial_buffer_s) and initial_buffer_s >= 0):
        raise ValueError(f"initial_buffer_s must be >= 0 seconds, not {initial_buffer_s}")
    if seed is not None and seed < 0:
        raise ValueError(f"the seed must be >= 0, not {seed}")
    if not isinstance(song, Song):
        song = load_song(song, fingering=fingering)
    excerpt = start_s != 0.0 or seconds is not None
    if excerpt:
        song = excerpt_of(song, start_s, seconds)
    options: dict[str, Any] = {"physics": physics, **(env_options or {})}
    if initial_buffer_s:
        options["initial_buffer_s"] = initial_buffer_s
    if fingering == "none":
        # Without labels the fingering reward matches fingertips to keys (facts section 3).
        options.setdefault("fingering_reward", "optimal")
    resolved = resolve_env_options(controller, song, **options)
    env = _build_env(song, controller, resolved, recorder=record_observations)
    handle = control_handle(env)
    resolved.setdefault("physics", handle.config.scene.physics)
    if check_scene is not None:
        check_scene(handle.scene)

    start = time.perf_counter()
    try:
        episode = run_episode(env, controller, seed=seed, progress=progress)
        wall = time.perf_counter() - start
        metrics: dict[str, Any] = episode.metrics()
        metrics.update(note_errors(episode.active_keys, episode.goal_keys))
        # Planning controllers report their own timing and settings.
        metrics.update(controller.stats())
        settings = controller.options_dict()
        if settings:
            metrics["controller_options"] = settings
        episode.extra.update(controller.plan_arrays())
        metrics.update(f1_lost_by_kind(episode.active_keys, episode.goal_keys, episode.extra))
        if record_observations:
            recorder = _find_recorder(env)
            episode.extra["observations"] = recorder.stacked()
            episode.extra["terminations"] = np.array(recorder.terminations, dtype=bool)
            episode.extra["truncations"] = np.array(recorder.truncations, dtype=bool)
    finally:
        controller.close()
    metrics.update(
        song=song.name,
        fingering=fingering,
        physics=resolved["physics"],
        seed=seed,
        env_options={k: _normalise(v) for k, v in resolved.items()},
        wall_seconds=wall,
        realtime_factor=metrics["seconds"] / wall if wall > 0 else float("inf"),
    )
    if excerpt:
        metrics.update(excerpt_start_s=start_s, excerpt_seconds=round(song.duration_s, 6))
    result = PlayResult(
        song=song,
        episode=episode,
        metrics=metrics,
        goal=handle.goal,
        scene=handle.scene,
        reward_weights=handle.config.rewards.as_dict(),
        observation_space=handle.observation_space,
        action_space=handle.action_space,
        env_options=resolved,
    )
    env.close()
    return result


def excerpt_of(song: Song, start_s: float, seconds: float | None) -> Song:
    """The part of ``song`` from ``start_s`` for ``seconds`` (None: to its end), shifted to
    start at 0 s (:func:`pianist.music.transforms.window`).

    Raises:
        ValueError: a negative or non-finite start, a length that is not > 0, or a start at
            or past the song's end (the message gives its length).
    """
    if not (math.isfinite(start_s) and start_s >= 0):
        raise ValueError(f"the excerpt's start must be >= 0 seconds, not {start_s}")
    if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"the excerpt's length must be > 0 seconds, not {seconds}")
    if start_s >= song.duration_s:
        raise ValueError(
            f"the excerpt starts at {start_s:g} s, past the end of {song.name} "
            f"({song.duration_s:.2f} s long)"
        )
    end = song.duration_s if seconds is None else min(start_s + seconds, song.duration_s)
    return window(song, start_s, end)


class ObservationRecorder(gym.Wrapper):
    """Keeps every observation the wrapped environment returns (reset's and each step's) and
    each step's terminated and truncated flags."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.observations: list[dict[str, np.ndarray]] = []
        self.terminations: list[bool] = []
        self.truncations: list[bool] = []

    def reset(self, **kwargs: Any) -> Any:
        observation, info = self.env.reset(**kwargs)
        self.observations = [_copy(observation)]
        self.terminations, self.truncations = [], []
        return observation, info

    def step(self, action: Any) -> Any:
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.observations.append(_copy(observation))
        self.terminations.append(bool(terminated))
        self.truncations.append(bool(truncated))
        return observation, reward, terminated, truncated, info

    def stacked(self) -> dict[str, np.ndarray]:
        """name -> (T + 1, ...) array of the episode's observations."""
        names = self.observations[0].keys()
        return {name: np.stack([obs[name] for obs in self.observations]) for name in names}


def _copy(observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A copy: wrappers outside the recorder (a policy's task entries) add to the dict."""
    return {name: np.array(value) for name, value in observation.items()}


def _find_recorder(env: gym.Env) -> ObservationRecorder:
    while not isinstance(env, ObservationRecorder):
        env = env.env  # type: ignore[attr-defined]  # a wrapper: the recorder is inside it
    return env


def _normalise(value: Any) -> Any:
    """Tuples as lists, so options compare and serialise the same from Python and JSON."""
    return list(value) if isinstance(value, tuple) else value
