"""The controller interface: what an episode needs of a controller, and the optional parts
that :mod:`pianist.eval.session` uses when a controller has them.

A controller is reset with the environment it will drive, then maps each observation to a
normalised action in [-1, 1]^A, like any policy. Controllers that plan read the simulator
through :func:`pianist.env.handle.control_handle`, and declare the environment they need
with ``env_options``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import gymnasium as gym
import numpy as np

if TYPE_CHECKING:
    from pianist.music import Song


class Controller(Protocol):
    """What :func:`pianist.eval.run_episode` needs of a controller."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        """Prepare for an episode of ``env``, called right after ``env.reset(seed=seed)``."""
        ...

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """The (A,) action in [-1, 1] for this step's observation."""
        ...


class BaseController:
    """The optional parts of a controller, with their defaults; the package's controllers
    derive from it and :mod:`pianist.eval.session` calls them on any controller that has them.
    """

    def env_options(self, song: Song) -> dict[str, Any]:
        """:class:`pianist.env.PianoEnv` options this controller needs to play ``song``; they
        override the user's (a conflicting explicit choice is refused). None by default."""
        return {}

    def stats(self) -> dict[str, float]:
        """Timing or counters since ``reset``, for metrics.json (none by default)."""
        return {}

    def plan_arrays(self) -> dict[str, np.ndarray]:
        """What the controller planned for the episode, as arrays over its steps (for plots
        and learners; none by default)."""
        return {}

    def options_dict(self) -> dict[str, Any]:
        """The controller's settings as plain values, for metrics.json (none by default)."""
        return {}

    def close(self) -> None:
        """Release threads or other resources (nothing by default)."""
