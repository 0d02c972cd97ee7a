"""Baseline controllers (random actions, a neutral pose, noise added to another controller,
replaying recorded actions) and :func:`make_controller`, a controller from its name."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from pianist.control.base import BaseController, Controller
from pianist.env.handle import control_handle

if TYPE_CHECKING:
    from pianist.music import Song


class RandomController(BaseController):
    """Uniform random actions in [-1, 1] from a seeded generator."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._shape = _action_shape(env)
        self._rng = np.random.default_rng(seed)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return self._rng.uniform(-1.0, 1.0, self._shape).astype(np.float32)


class ZeroController(BaseController):
    """Every actuator at the middle of its range (action 0), the pedal up (action -1)."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._action = np.zeros(_action_shape(env), dtype=np.float32)
        self._action[-1] = -1.0

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return self._action.copy()


class NoisyController(BaseController):
    """Another controller's actions plus Gaussian noise of std ``sigma`` (action units), clipped
    to [-1, 1]; the noise generator is seeded from ``reset``'s seed.

    One deterministic episode's F1 is a chaotic function of the actions (contacts): the mean F1
    over a few episodes with small noise (std 0.005) is the comparison a lucky episode cannot
    win.
    """

    def __init__(self, controller: Controller, sigma: float) -> None:
        if sigma < 0:
            raise ValueError(f"noise std must be >= 0, not {sigma}")
        self.controller, self.sigma = controller, sigma

    # What the wrapped controller declares is declared for it (its plan and settings are
    # not: the noise changes what was played).

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        return self.controller.env_options(song)

    def wrap_env(self, env: gym.Env) -> gym.Env:
        return self.controller.wrap_env(env)

    def stats(self) -> dict[str, float]:
        return dict(self.controller.stats())

    def close(self) -> None:
        self.controller.close()

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._rng = np.random.default_rng([0 if seed is None else seed, 11])
        self.controller.reset(env, seed)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        action = np.asarray(self.controller.act(observation))
        noise = self.sigma * self._rng.standard_normal(action.shape)
        return np.clip(action + noise, -1.0, 1.0).astype(np.float32)


class ReplayController(BaseController):
    """Plays back a (T, A) array of actions, for example a saved ``actions.npy``.

    Actions only replay in the scene they were recorded in: a file written by ``pianist play``
    has a ``metrics.json`` beside it whose ``env_options`` (forearm slides, physics, lead-in)
    this controller then declares as the environment it needs.
    """

    def __init__(self, actions: np.ndarray | str | Path) -> None:
        self.recorded_env_options: dict[str, Any] = {}
        if isinstance(actions, str | Path):
            path = Path(actions)
            if not path.is_file():
                raise FileNotFoundError(f"actions file not found: {path}")
            try:
                actions = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError):
                raise ValueError(
                    f"{path} is not a .npy array of actions (as `pianist play` writes to "
                    "actions.npy)"
                ) from None
            self.recorded_env_options = _recorded_env_options(path.with_name("metrics.json"))
        self.actions = np.asarray(actions, dtype=np.float32)
        if self.actions.ndim != 2:
            raise ValueError(f"replayed actions must be a (T, A) array, not {self.actions.shape}")

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        """The environment the actions were recorded in (empty when not known)."""
        return dict(self.recorded_env_options)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        expected = _action_shape(env)[0]
        if self.actions.shape[1] != expected:
            raise ValueError(
                f"replayed actions have {self.actions.shape[1]} dimensions, "
                f"the environment expects {expected}"
            )
        steps = control_handle(env).num_steps
        if len(self.actions) != steps:
            raise ValueError(
                f"the replayed actions are {len(self.actions)} steps, this episode has {steps}: "
                "replay them on the song (and lead-in) they were recorded with"
            )
        self._t = 0

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        if self._t >= len(self.actions):
            raise ValueError(f"the replayed actions ran out after {len(self.actions)} steps")
        action = self.actions[self._t]
        self._t += 1
        return action


def _action_shape(env: gym.Env) -> tuple[int, ...]:
    """The shape of ``env``'s actions (a Box, as a PianoEnv's)."""
    shape = env.action_space.shape
    assert shape is not None, f"{env.action_space} has no shape"
    return shape


def _recorded_env_options(metrics_path: Path) -> dict[str, Any]:
    """``env_options`` of the metrics.json written beside recorded actions ({} if none)."""
    if not metrics_path.is_file():
        return {}
    try:
        options = json.loads(metrics_path.read_text()).get("env_options", {})
    except (OSError, json.JSONDecodeError, AttributeError) as exc:
        raise ValueError(f"{metrics_path} beside the actions is unreadable ({exc})") from None
    if not isinstance(options, dict):
        raise ValueError(f"{metrics_path}: env_options must be a mapping")
    # JSON has lists where the options take tuples (forearm_dofs).
    return {k: tuple(v) if isinstance(v, list) else v for k, v in options.items()}


def make_controller(spec: str) -> Controller:
    """The controller a spec string names (:func:`pianist.control.registry.build_controller`:
    ``planner``, ``refine[:FIELD=VALUE,...]``, ``search[:refine,FIELD=VALUE,...]``,
    ``mpc[:PRESET,...]``, ``random``, ``zero``, ``replay:PATH.npy`` and the learned kinds)."""
    from pianist.control.registry import build_controller

    return build_controller(spec)
