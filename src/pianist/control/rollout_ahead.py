"""Look-aheads of many open-loop action sequences at once, in MuJoCo's own threads.

The refiner (:mod:`pianist.control.refine`) scores perturbations of the planner's actions by
simulating each a few control steps ahead. Stepped through a fork of the environment with
the planner acting at every step, a look-ahead step costs its physics plus the planner's
Python (the finger targets and inverse kinematics, more than the physics: K545 with the
default refiner, 15 s of ``mj_step`` and 18 s of planner in 41 s). Here the candidates are
open-loop instead: each replays the actions the planner took in the unperturbed look-ahead
plus its own offset, and all of them are simulated in one :func:`mujoco.rollout.rollout`
call, on ``nthread`` threads, with no Python between the substeps.

Inputs: the episode's state (an :class:`~pianist.env.piano_env.EnvState` snapshot), (N, H, A)
normalised actions. Outputs, after each of the H control steps of each of the N sequences:
(N, H, 88) key angles (rad) and (N, H, S, 3) positions (m) of chosen sites.

What the environment does between steps that the rollout does not: waking the keys that fell
asleep held down (the fast preset's sleeping islands, :meth:`PianoEnv.apply_action`), and the
pedal (no physics). Without sleeping islands a rollout's states are the environment's own,
bit for bit (a test checks it); with them, a key a finger has just left may stay down for
the look-ahead's few steps, which only costs that look-ahead.
"""

from __future__ import annotations

import weakref

import mujoco
import numpy as np
from mujoco import rollout

from pianist.env.piano_env import action_to_ctrl

#: The state a rollout starts from: everything :func:`mujoco.mj_step` reads.
_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


class RolloutAhead:
    """Batched open-loop look-aheads of one model (see the module docstring).

    Args:
        model: the environment's model (read only).
        substeps: physics steps per control step.
        key_qpos: (88,) qpos addresses of the keys' hinges.
        sites: (S,) site ids whose positions are returned (the fingertips).
        nthread: threads of the rollout pool (0: the calling thread only).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        substeps: int,
        key_qpos: np.ndarray,
        sites: np.ndarray,
        nthread: int = 2,
    ) -> None:
        self.model = model
        self.substeps = substeps
        self.key_qpos = np.asarray(key_qpos)
        self.sites = np.asarray(sites)
        self.nthread = nthread
        self._datas = [mujoco.MjData(model) for _ in range(max(nthread, 1))]
        self._scratch = mujoco.MjData(model)  # for the sites' positions of returned states
        self._pool = rollout.Rollout(nthread=nthread)
        # The pool's threads end with this object (or at exit), never left running.
        weakref.finalize(self, self._pool.close)
        self._state = np.empty(mujoco.mj_stateSize(model, _STATE))
        # Where qpos sits in a full-physics state vector: after the time.
        self._qpos = slice(1, 1 + model.nq)

    def run(self, start: mujoco.MjData, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Simulate ``actions`` (N, H, A) from the state in ``start``, each sequence on its own.

        Args:
            start: simulator data holding the state to start from (not changed).
            actions: normalised actions in [-1, 1], sustain last (ignored: no physics).

        Returns:
            (N, H, 88) key angles in rad and (N, H, S, 3) site positions in m, after each
            control step.
        """
        ctrl = action_to_ctrl(actions[..., :-1], self.model.actuator_ctrlrange)  # (N, H, nu)
        return self.run_ctrl(start, ctrl)

    def run_ctrl(self, start: mujoco.MjData, ctrl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`run` from actuator commands ``ctrl`` (N, H, nu) instead of actions (each
        within its actuator's range)."""
        m = self.model
        N, H, _ = ctrl.shape
        states = self._states(start, ctrl)
        ends = states[:, self.substeps - 1 :: self.substeps]  # (N, H, nstate)
        qpos = ends[..., self._qpos]
        keys = qpos[..., self.key_qpos]
        sites = np.empty((N, H, self.sites.size, 3))
        scratch = self._scratch
        for n in range(N if self.sites.size else 0):
            for h in range(H):
                scratch.qpos[:] = qpos[n, h]
                mujoco.mj_kinematics(m, scratch)
                sites[n, h] = scratch.site_xpos[self.sites]
        return keys, sites

    def key_paths(self, start: mujoco.MjData, ctrl: np.ndarray) -> np.ndarray:
        """(N, H * S, 88) rad: every key's angle after each substep of :meth:`run_ctrl`'s
        rollouts (S substeps per control step)."""
        return self._states(start, ctrl)[..., self._qpos][..., self.key_qpos]

    def _states(self, start: mujoco.MjData, ctrl: np.ndarray) -> np.ndarray:
        """(N, H * S, nstate) the full-physics state after every substep of ``ctrl`` (N, H, nu)
        held for each control step, from ``start``."""
        m = self.model
        N = ctrl.shape[0]
        mujoco.mj_getState(m, start, self._state, _STATE)
        control = np.repeat(ctrl, self.substeps, axis=1)  # held for each step's substeps
        states, _ = self._pool.rollout(
            m,
            self._datas,
            np.tile(self._state, (N, 1)),
            control,
            initial_warmstart=np.tile(start.qacc_warmstart, (N, 1)),
        )
        return states
