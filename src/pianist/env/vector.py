"""Step N piano environments at once on every core, as a ``gymnasium.vector.VectorEnv``.

The environments are split among worker threads. MuJoCo releases Python's global lock inside
``mj_step``, and a control step is one ``mj_step`` call, so the physics of one thread's
environments runs while another thread does its (short) Python bookkeeping. Every
sub-environment follows the code path of :class:`PianoEnv` and gives bit-identical results.

(``mujoco.rollout`` with native threads was measured first: for rollouts of one control step,
10 substeps, its per-call threading overhead ate the whole gain on this 2-core machine.)
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from pianist.env.config import EnvConfig
from pianist.env.piano_env import PianoEnv
from pianist.music import GoalFrames, Song

StepResult = tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]


class PianoVectorEnv(VectorEnv):
    """N copies of :class:`PianoEnv` on one song, stepped together on ``num_threads`` threads.

    Observations are the single environment's dict with a leading batch axis; ``infos`` hold
    ``reward_terms`` (dict of (N,) arrays), ``active_keys`` (N, 88), ``sustain`` (N,) and
    ``note_events`` (a list of N event arrays). Autoreset follows Gymnasium's next-step mode: the
    step after an episode ends resets that sub-environment and ignores its action.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        song: Song | GoalFrames | str | Path,
        num_envs: int,
        config: EnvConfig | None = None,
        num_threads: int | None = None,
        **options: Any,
    ) -> None:
        """
        Args:
            song: as for :class:`PianoEnv`.
            num_envs: N, the number of sub-environments.
            config / options: as for :class:`PianoEnv`.
            num_threads: worker threads (default: min(N, CPU cores)).
        """
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, not {num_envs}")
        self.envs = [PianoEnv(song, config, **options) for _ in range(num_envs)]
        first = self.envs[0]
        self.num_envs = num_envs
        self.config = first.config
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.num_threads = max(1, min(num_threads or os.cpu_count() or 1, num_envs))
        self._groups = [list(range(k, num_envs, self.num_threads)) for k in range(self.num_threads)]
        self._pool = ThreadPoolExecutor(self.num_threads) if self.num_threads > 1 else None
        self._needs_reset = np.zeros(num_envs, dtype=bool)

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is None or isinstance(seed, int):
            seeds = [None if seed is None else seed + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
        results = [
            env.reset(seed=s, options=options) for env, s in zip(self.envs, seeds, strict=True)
        ]
        self._needs_reset[:] = False
        return _stack([r[0] for r in results]), _stack_infos([r[1] for r in results])

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape:
            raise ValueError(
                f"actions must have shape {self.action_space.shape}, not {actions.shape}"
            )
        results: list[StepResult | None] = [None] * self.num_envs
        for i in np.flatnonzero(~self._needs_reset).tolist():
            self.envs[i].apply_action(actions[i])  # validates in the caller's thread
            results[i] = ()  # type: ignore[assignment]  # marks "stepping"

        def run(group: list[int]) -> None:
            for i in group:
                if results[i] is not None:
                    env = self.envs[i]
                    env.advance_physics()
                    results[i] = env.finish_step()

        if self._pool is None:
            run(self._groups[0])
        else:
            for future in [self._pool.submit(run, g) for g in self._groups]:
                future.result()  # re-raises a worker's exception (e.g. an unstable simulation)

        N = self.num_envs
        rewards = np.zeros(N)
        terminated = np.zeros(N, dtype=bool)
        truncated = np.zeros(N, dtype=bool)
        observations, infos = [], []
        for i, env in enumerate(self.envs):
            result = results[i]
            if result is None:  # its episode ended last step: reset now (next-step autoreset)
                obs, info = env.reset()
                self._needs_reset[i] = False
            else:
                obs, rewards[i], terminated[i], truncated[i], info = result
                self._needs_reset[i] = terminated[i] or truncated[i]
            observations.append(obs)
            infos.append(info)
        return _stack(observations), rewards, terminated, truncated, _stack_infos(infos)

    def close_extras(self, **kwargs: Any) -> None:
        if self._pool is not None:
            self._pool.shutdown()
        for env in self.envs:
            env.close()


def _stack(observations: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {key: np.stack([o[key] for o in observations]) for key in observations[0]}


def _stack_infos(infos: list[dict[str, Any]]) -> dict[str, Any]:
    """Batch the per-environment infos (arrays with a leading N axis)."""
    out: dict[str, Any] = {}
    keys = set().union(*infos)
    for key in ("step", "active_keys", "sustain", "goal_sustain", "goal_keys"):
        if key in keys:
            out[key] = np.stack([np.asarray(info.get(key, 0)) for info in infos])
    terms = [info.get("reward_terms") for info in infos]
    names = next((t for t in terms if t is not None), None)
    if names is not None:
        out["reward_terms"] = {
            name: np.array([t[name] if t is not None else 0.0 for t in terms]) for name in names
        }
    if "note_events" in keys:
        out["note_events"] = [info.get("note_events", ()) for info in infos]
    return out
