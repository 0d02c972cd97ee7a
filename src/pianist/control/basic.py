"""Baseline controllers: random actions, a neutral pose, and replaying recorded actions.

A controller is reset with the environment it will drive, then maps each observation to a
normalised action in [-1, 1]^A, like any policy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np


class Controller(Protocol):
    def reset(self, env: gym.Env, seed: int | None = None) -> None: ...

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray: ...


class RandomController:
    """Uniform random actions in [-1, 1] from a seeded generator."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._shape = _action_shape(env)
        self._rng = np.random.default_rng(seed)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return self._rng.uniform(-1.0, 1.0, self._shape).astype(np.float32)


class ZeroController:
    """Every actuator at the middle of its range (action 0), the pedal up (action -1)."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._action = np.zeros(_action_shape(env), dtype=np.float32)
        self._action[-1] = -1.0

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return self._action.copy()


class NoisyController:
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

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._rng = np.random.default_rng([0 if seed is None else seed, 11])
        self.controller.reset(env, seed)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        action = np.asarray(self.controller.act(observation))
        noise = self.sigma * self._rng.standard_normal(action.shape)
        return np.clip(action + noise, -1.0, 1.0).astype(np.float32)


class ReplayController:
    """Plays back a (T, A) array of actions, for example a saved ``actions.npy``."""

    def __init__(self, actions: np.ndarray | str | Path) -> None:
        if isinstance(actions, str | Path):
            path = Path(actions)
            if not path.is_file():
                raise FileNotFoundError(f"actions file not found: {path}")
            try:
                actions = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError) as exc:
                raise ValueError(f"{path} is not a readable .npy array ({exc})") from None
        self.actions = np.asarray(actions, dtype=np.float32)
        if self.actions.ndim != 2:
            raise ValueError(f"replayed actions must be a (T, A) array, not {self.actions.shape}")

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        expected = _action_shape(env)[0]
        if self.actions.shape[1] != expected:
            raise ValueError(
                f"replayed actions have {self.actions.shape[1]} dimensions, "
                f"the environment expects {expected}"
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


def make_controller(spec: str, **kwargs: Any) -> Controller:
    """A controller from its name: ``planner``, ``mpc[:SPEC]``, ``random``, ``zero`` or
    ``replay:PATH.npy``."""
    if spec == "planner":
        from pianist.control.planner import IKPlanner

        return IKPlanner()
    if spec == "mpc" or spec.startswith("mpc:"):
        from pianist.control.mpc import make_mpc

        # mpc, mpc:PRESET or mpc:PRESET,field=value,... (see pianist.control.mpc.make_mpc)
        return make_mpc(spec.partition(":")[2] or None)
    if spec == "random":
        return RandomController()
    if spec == "zero":
        return ZeroController()
    if spec.startswith("replay:"):
        return ReplayController(spec.removeprefix("replay:"))
    raise ValueError(
        f"unknown controller {spec!r}; use planner, mpc[:PRESET,...], random, zero or "
        "replay:ACTIONS.npy"
    )
