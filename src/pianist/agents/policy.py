"""Acting with a trained actor in NumPy (no JAX needed), and the ``policy:DIR`` controller."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from pianist.agents.config import TrainConfig
from pianist.agents.envs import AgentEnv, Featurizer, song_hands
from pianist.control.base import BaseController

_SQRT_2_OVER_PI = np.float32(np.sqrt(2.0 / np.pi))


def _gelu(x: np.ndarray) -> np.ndarray:
    # The tanh approximation, as flax's nn.gelu computes it.
    return 0.5 * x * (1.0 + np.tanh(_SQRT_2_OVER_PI * (x + np.float32(0.044715) * x**3)))


_ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "gelu": _gelu,
    "relu": lambda x: np.maximum(x, 0),
    "tanh": np.tanh,
}


class NumpyActor:
    """The tanh-Gaussian actor's forward pass on float32 NumPy arrays.

    ``weights``: [(W (in, out), b (out,)), ...] for the hidden layers, then the mean and the
    log-std heads (:func:`pianist.agents.sac.actor_weights`).
    """

    def __init__(
        self,
        weights: list[tuple[np.ndarray, np.ndarray]],
        activation: str,
        log_std_min: float,
        log_std_max: float,
    ) -> None:
        if len(weights) < 3:
            raise ValueError(f"an actor needs at least 3 layers, got {len(weights)}")
        self.weights = weights
        self.activation = _ACTIVATIONS[activation]
        self.log_std_range = (log_std_min, log_std_max)
        self.obs_dim = weights[0][0].shape[0]
        self.action_dim = weights[-1][0].shape[1]

    def distribution(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """obs (D,) or (B, D) -> pre-tanh mean and log std, (A,) or (B, A)."""
        x = obs
        for w, b in self.weights[:-2]:
            x = self.activation(x @ w + b)
        (wm, bm), (ws, bs) = self.weights[-2:]
        return x @ wm + bm, np.clip(x @ ws + bs, *self.log_std_range)

    def mean_action(self, obs: np.ndarray) -> np.ndarray:
        """The deterministic action tanh(mean) used for evaluation."""
        return np.tanh(self.distribution(obs)[0])

    def sample(self, obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """An exploration action tanh(mean + std * N(0, 1)) drawn from ``rng``."""
        mean, log_std = self.distribution(obs)
        noise = rng.standard_normal(mean.shape, dtype=np.float32)
        return np.tanh(mean + np.exp(log_std) * noise)


class PolicyController(BaseController):
    """A trained policy as a controller: ``reset(env, seed)``, ``act(observation)``.

    The environment must be the one the policy was trained on: build it with
    :meth:`make_env`. Actions are deterministic (the actor's mean).
    """

    def __init__(self, run_dir: str | Path, physics: str | None = None) -> None:
        """``physics``: play in this physics preset ("faithful" or "fast"), everything else
        of its task unchanged; None: the one its run evaluated in (``eval_physics``, which
        chose the kept best policy), else the one it was trained in."""
        from pianist.agents.checkpoint import load_policy
        from pianist.sim.scene import PHYSICS_PRESETS

        if physics is not None and physics not in PHYSICS_PRESETS:
            raise ValueError(
                f"unknown physics {physics!r}; use one of {', '.join(PHYSICS_PRESETS)}"
            )
        self.run_dir: Path | None = Path(run_dir)
        self.config, weights, self.step = load_policy(self.run_dir)
        self.physics = physics or self.config.eval_physics
        a = self.config.agent
        self.actor = NumpyActor(weights, a.activation, a.log_std_min, a.log_std_max)
        self._features: Featurizer | None = None

    @classmethod
    def from_actor(cls, config: TrainConfig, actor: NumpyActor) -> PolicyController:
        """A controller around an actor held in memory (used for evaluation during training)."""
        self = cls.__new__(cls)
        self.run_dir, self.config, self.actor, self.step = None, config, actor, -1
        self.physics = None
        self._features = None
        return self

    def make_env(self, song: Any) -> gym.Env:
        """The environment of the training task, for ``song`` (a name, a file, a Song; a
        file's missing fingers estimated, as in training): what
        :func:`pianist.eval.session.make_env` builds from :meth:`env_options` and
        :meth:`wrap_env`."""
        from pianist.eval.session import make_env
        from pianist.music import load_song

        return make_env(load_song(song, fingering="auto"), self)

    def env_options(self, song: Any = None) -> dict[str, Any]:
        """The :class:`pianist.env.PianoEnv` options :meth:`make_env` uses for ``song``: the
        whole task it was trained on (physics, hands, lookahead, action space, lead-in), in
        the ``physics`` given at construction if any."""
        options = self.config.task.env_options(song_hands(song))
        if self.physics is not None:
            options["physics"] = self.physics
        return options

    def wrap_env(self, env: gym.Env) -> AgentEnv:
        """The environment as the policy observes it (its task's extra observation entries)."""
        return AgentEnv(env, self.config.task)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        if not isinstance(env, AgentEnv):
            raise ValueError(
                "a trained policy needs the environment of its task: "
                "build it with PolicyController.make_env(song)"
            )
        features = Featurizer(env, self.config.task)
        if features.obs_dim != self.actor.obs_dim or features.action_dim != self.actor.action_dim:
            raise ValueError(
                f"the policy reads {self.actor.obs_dim} observation and writes "
                f"{self.actor.action_dim} action values, this environment has "
                f"{features.obs_dim} and {features.action_dim}"
            )
        features.reset(env, seed)
        self._features = features

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        if self._features is None:
            raise RuntimeError("call reset(env, seed) first")
        x = self._features(observation)
        return self._features.env_action(self.actor.mean_action(x).astype(np.float32))
