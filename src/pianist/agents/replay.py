"""Replay buffer in NumPy with preallocated arrays; each observation is stored once.

Slot i holds an observation and, once the step from it is known, that step's action, reward
and discount; its next observation is slot i + 1 (circularly). A slot whose successor belongs
to another episode, or has not been written yet, is not sampled. Pages of the big arrays are
only touched as they fill, so a 1M-step capacity costs memory as the run goes.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np


class Batch(NamedTuple):
    """Transitions: obs (B, D), action (B, A), reward (B,), discount (B,), next_obs (B, D).

    ``discount`` is 0 where the episode terminated and 1 otherwise (also at a truncation); the
    agent multiplies it by its own discount factor.
    """

    obs: Any
    action: Any
    reward: Any
    discount: Any
    next_obs: Any


class ReplayBuffer:
    """Transitions of dimension obs (D,), action (A,), float32, up to ``capacity`` steps."""

    def __init__(self, obs_dim: int, action_dim: int, capacity: int) -> None:
        if capacity < 2:
            raise ValueError(f"replay capacity must be >= 2, not {capacity}")
        self.capacity = capacity
        self.obs = np.zeros((capacity, obs_dim), np.float32)
        self.action = np.zeros((capacity, action_dim), np.float32)
        self.reward = np.zeros(capacity, np.float32)
        self.discount = np.zeros(capacity, np.float32)
        self.has_next = np.zeros(capacity, bool)
        self.size = 0  # slots written at least once
        self.cursor = -1  # slot of the current observation, -1 before the first episode
        self.transitions = 0  # sampleable slots

    def start_episode(self, obs: np.ndarray) -> None:
        """Record the first observation of an episode."""
        self._write_obs((self.cursor + 1) % self.capacity, obs)

    def add(self, action: np.ndarray, reward: float, discount: float, next_obs: np.ndarray) -> None:
        """Record the step from the current observation; ``discount`` 0 at a termination."""
        if self.cursor < 0:
            raise RuntimeError("call start_episode before add")
        i = self.cursor
        self.action[i] = action
        self.reward[i] = reward
        self.discount[i] = discount
        self._write_obs((i + 1) % self.capacity, next_obs)
        self.has_next[i] = True
        self.transitions += 1

    def _write_obs(self, i: int, obs: np.ndarray) -> None:
        if self.has_next[i]:  # overwriting the oldest transition
            self.has_next[i] = False
            self.transitions -= 1
        self.obs[i] = obs
        self.cursor = i
        self.size = max(self.size, i + 1)

    def sample(self, rng: np.random.Generator, batch_size: int, num_batches: int = 1) -> Batch:
        """``num_batches`` batches of uniformly drawn transitions, fields shaped (K, B, ...)."""
        if self.transitions == 0:
            raise RuntimeError("the replay buffer holds no transitions yet")
        n = num_batches * batch_size
        index = rng.integers(0, self.size, n)
        bad = ~self.has_next[index]
        while bad.any():  # rejection: a small fraction of slots ends an episode
            index[bad] = rng.integers(0, self.size, int(bad.sum()))
            bad = ~self.has_next[index]
        nxt = (index + 1) % self.capacity
        shape = (num_batches, batch_size)
        return Batch(
            obs=self.obs[index].reshape(*shape, -1),
            action=self.action[index].reshape(*shape, -1),
            reward=self.reward[index].reshape(shape),
            discount=self.discount[index].reshape(shape),
            next_obs=self.obs[nxt].reshape(*shape, -1),
        )

    # ----------------------------------------------------------------------------- files

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The filled part of the buffer and its counters, for ``np.savez``."""
        n = self.size
        return {
            "obs": self.obs[:n],
            "action": self.action[:n],
            "reward": self.reward[:n],
            "discount": self.discount[:n],
            "has_next": self.has_next[:n],
            "counters": np.array([self.size, self.cursor, self.transitions, self.capacity]),
        }

    def load_arrays(self, arrays: dict[str, np.ndarray] | np.lib.npyio.NpzFile) -> None:
        """Inverse of :meth:`state_arrays` (into a buffer of the same dimensions)."""
        size, cursor, transitions, capacity = (int(v) for v in arrays["counters"])
        if capacity != self.capacity or arrays["obs"].shape[1:] != self.obs.shape[1:]:
            raise ValueError(
                f"replay buffer shapes differ: saved capacity {capacity} obs "
                f"{arrays['obs'].shape[1:]}, expected {self.capacity} {self.obs.shape[1:]}"
            )
        for name in ("obs", "action", "reward", "discount", "has_next"):
            getattr(self, name)[:size] = arrays[name]
        self.size, self.cursor, self.transitions = size, cursor, transitions
