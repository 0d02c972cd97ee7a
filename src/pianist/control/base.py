"""The controller contract: what an episode asks of a controller, and what a controller may
declare.

A controller is reset with the environment it will drive, then maps each observation to a
normalised action in [-1, 1]^A, like any policy. Controllers that plan read the simulator
through :func:`pianist.env.handle.control_handle`. Besides ``reset`` and ``act``, a controller
may declare the environment it needs (``env_options``, ``wrap_env``) and report what it did
(``stats``, ``options_dict``, ``plan_arrays``); :class:`BaseController` gives every one of
those its default, and :mod:`pianist.eval.session` calls them on every controller.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import gymnasium as gym
    import numpy as np

    from pianist.music import Song


class Controller(Protocol):
    """What :func:`pianist.eval.session.play` and :func:`pianist.eval.run_episode` need of a
    controller; derive from :class:`BaseController` for the defaults of all but ``reset``
    and ``act``."""

    def env_options(self, song: Song | None) -> dict[str, Any]:
        """:class:`pianist.env.PianoEnv` options this controller needs to play ``song``; they
        override the user's (a conflicting explicit choice is refused)."""
        ...

    def wrap_env(self, env: gym.Env) -> gym.Env:
        """The environment as this controller observes it (a wrapper around ``env``, or
        ``env`` itself)."""
        ...

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        """Prepare for an episode of ``env``, called right after ``env.reset(seed=seed)``."""
        ...

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """The (A,) action in [-1, 1] for this step's observation."""
        ...

    def stats(self) -> dict[str, float]:
        """Timing or counters since ``reset``, for metrics.json."""
        ...

    def options_dict(self) -> dict[str, Any]:
        """The controller's settings as plain values, for metrics.json."""
        ...

    def plan_arrays(self) -> dict[str, np.ndarray]:
        """What the controller planned for the episode, as arrays over its steps (for plots
        and learners)."""
        ...

    def close(self) -> None:
        """Release threads or other resources."""
        ...


class BaseController:
    """The defaults of :class:`Controller`'s declarations: no environment options, no
    wrapper, no statistics, settings, plan or resources. A subclass writes ``reset`` and
    ``act`` and overrides what it has."""

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        """None by default."""
        return {}

    def wrap_env(self, env: gym.Env) -> gym.Env:
        """``env`` itself by default."""
        return env

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        raise NotImplementedError

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        raise NotImplementedError

    def stats(self) -> dict[str, float]:
        """None by default."""
        return {}

    def options_dict(self) -> dict[str, Any]:
        """None by default."""
        return {}

    def plan_arrays(self) -> dict[str, np.ndarray]:
        """None by default."""
        return {}

    def close(self) -> None:
        """Nothing to release by default."""
