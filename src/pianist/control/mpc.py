"""Predictive sampling: the paper's model-based baseline, with MuJoCo itself as the model.

The controller keeps a *nominal* plan: ``num_knots`` knots of normalised actuator actions spread
evenly over a ``horizon_s`` window, interpolated by a spline (:mod:`pianist.control.spline`).
Each planning iteration

1. makes ``num_samples`` candidates (as MJPC counts them, the nominal included): the nominal
   itself as candidate 0, and ``num_samples - 1`` copies of its knots plus Gaussian noise of
   standard deviation ``sigma`` (normalised action units, so sigma is a fraction of half each
   actuator's range), clipped to [-1, 1];
2. rolls every candidate out with ``mujoco.rollout`` on a thread pool, from a copy of the
   environment's full physics state (``mj_getState`` with ``mjSTATE_FULLPHYSICS``, plus the
   solver's warm start), on a copy of the scene that has extra position sensors for the cost
   and no sleeping islands (their state is not part of ``mjSTATE_FULLPHYSICS``; with them the
   rollouts would not be reproducible);
3. scores each rollout with the cost below and makes the cheapest candidate the new nominal,
   so a planning iteration never makes the nominal's cost worse.

After ``iterations`` such iterations the controller returns the nominal's first action, which
the environment holds for one control step; then the plan is shifted one control step in time
(the knots are re-sampled from the spline at their times plus the control step, the last knot
held).

How this maps the paper's settings (MJPC, appendix "Baselines") onto a Gymnasium environment:

- *planning time step 0.01 s* is MJPC's ``agent_timestep``: the rollouts integrate a copy of
  the scene with this timestep (horizon 0.2 s = 20 rollout steps) while the environment's
  physics keeps its own 0.005 s. Set ``planning_timestep_s`` to the physics timestep to plan
  with the exact dynamics.
- MJPC applies the spline at every physics step; the environment holds one action for a whole
  control step (0.05 s, 10 substeps). The rollouts therefore hold the plan the same way: the
  action of control step c inside the horizon is the spline's value at c * 0.05 s, so the
  first 0.05 s of every rollout is exactly what the environment will do with the returned
  action (``test_control_mpc.py`` checks the costs against the real environment).
- MJPC plans continuously in a thread; here the planner runs ``iterations`` iterations per
  control step (the paper preset: 5, one per 0.01 s of simulated time) and the simulation waits
  for it. Real-time factor = simulated time / planning wall time, kept in :meth:`stats`.
- The sustain pedal is not planned: it follows the goal's sustain bit for the current frame.

Cost of a rollout (paper: "unbounded l2 distances", no control or energy cost), averaged over
its steps; the state after rollout step j is scored against the goal frame that the
environment would score it against (the frame of the control step it falls in):

- key term: ``|| key_state - goal_keys ||_2`` over all 88 keys, key_state the normalised key
  depression as in the key-press reward (so wrong presses cost too);
- finger term: mean over the due keys that have a finger of the distance (m) from that
  fingertip to the key's strike point (the fingering reward's target), 0 if none is due.

The controller needs the environment's full state, so it reads the simulator through the
:class:`pianist.env.handle.ControlHandle` of the environment it was reset with (an MPC cannot
act from observations alone).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from pianist.control.base import BaseController
from pianist.control.options import MPCOptions
from pianist.control.registry import parse_controller
from pianist.control.spline import interpolation_weights, knot_times
from pianist.env.handle import ControlHandle, control_handle
from pianist.sim import constants as C
from pianist.sim.scene import build_spec

_FULLPHYSICS = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
_FINGERS = 10


def make_mpc(spec: str | MPCOptions | None = None, **overrides: Any) -> PredictiveSampling:
    """A predictive-sampling controller from a preset name, a spec string or options.

    Args:
        spec: None (the ``paper`` preset), an :class:`MPCOptions`, or the part of a controller
            string after ``mpc:`` (:mod:`pianist.control.registry`), e.g. ``"tenth"`` or
            ``"paper,num_samples=20,iterations=10"``.
        overrides: further :class:`MPCOptions` fields, applied last.
    Raises:
        ValueError: unknown preset or field, or a value that does not parse or is out of range.
    """
    if not isinstance(spec, MPCOptions):
        parsed = parse_controller(f"mpc:{spec or 'paper'}")
        spec = MPCOptions(**{f.name: getattr(parsed, f.name) for f in fields(MPCOptions)})
    options = spec
    names = {f.name for f in fields(MPCOptions)}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise ValueError(f"unknown MPC option(s) {unknown}; choose from {sorted(names)}")
    return PredictiveSampling(replace(options, **overrides))


@dataclass
class _Stats:
    steps: int = 0
    iterations: int = 0
    rollout_steps: int = 0
    plan_seconds: float = 0.0
    rollout_seconds: float = 0.0


class PianoCost:
    """The MPC cost of piano states, from an environment's goal and fingering.

    ``stage_costs`` works on any batch of states, so the same function scores rollouts and the
    real environment.
    """

    def __init__(
        self, env: ControlHandle, key_weight: float = 1.0, finger_weight: float = 1.0
    ) -> None:
        goal = env.goal
        self.key_weight = key_weight
        self.finger_weight = finger_weight
        self.num_frames = goal.num_frames
        self.goal_keys = goal.keys.astype(float)
        self.key_max_rad = np.asarray(env.scene.key_max_angle_rad, dtype=float)
        present = np.zeros(_FINGERS, dtype=bool)
        for hand in env.scene.hands:
            offset = 0 if hand.side == "right" else 5
            present[offset : offset + 5] = True
        # Per frame, the (finger, key) pairs scored by the finger term: fingered due keys of a
        # hand in the scene (the environment's fingering reward scores the same pairs).
        self.pairs: list[tuple[np.ndarray, np.ndarray]] = []
        for keys_due, fingers in zip(goal.keys, goal.fingers, strict=True):
            keys = np.flatnonzero(keys_due)
            keys = keys[fingers[keys] >= 0]
            f = fingers[keys].astype(np.intp)
            keep = present[f]
            self.pairs.append((f[keep], keys[keep]))
        self._no_pairs = (np.zeros(0, np.intp), np.zeros(0, np.intp))

    def frame_goal(self, frames: np.ndarray) -> np.ndarray:
        """(T, 88) goal key bits of ``frames``, zero past the end of the song."""
        frames = np.asarray(frames)
        out = np.zeros((len(frames), C.NUM_KEYS))
        inside = frames < self.num_frames
        out[inside] = self.goal_keys[frames[inside]]
        return out

    def stage_costs(
        self,
        frames: np.ndarray,
        key_qpos: np.ndarray,
        fingertips: np.ndarray,
        key_targets: np.ndarray,
    ) -> np.ndarray:
        """Cost of each state against its goal frame.

        Args:
            frames: (T,) goal frame index of each time step.
            key_qpos: (..., T, 88) key hinge angles in rad.
            fingertips: (..., T, 10, 3) fingertip positions in m, thumb..little right then left
                (rows of an absent hand are ignored).
            key_targets: (..., T, 88, 3) key strike points in m (the keys' fingering sites).
        Returns:
            (..., T) key_weight * key term + finger_weight * finger term (module docstring).
        """
        frames = np.asarray(frames)
        state = np.clip(key_qpos, 0.0, self.key_max_rad) / self.key_max_rad
        key_term = np.sqrt(np.square(state - self.frame_goal(frames)).sum(axis=-1))
        finger_term = np.zeros(key_term.shape)
        for j, frame in enumerate(frames.tolist()):
            finger, key = self.pairs[frame] if frame < self.num_frames else self._no_pairs
            if finger.size:
                d = fingertips[..., j, finger, :] - key_targets[..., j, key, :]
                finger_term[..., j] = np.sqrt(np.square(d).sum(axis=-1)).mean(axis=-1)
        return self.key_weight * key_term + self.finger_weight * finger_term


class PredictiveSampling(BaseController):
    """Predictive-sampling MPC controller (see the module docstring).

    Use like any controller: ``reset(env, seed)``, then ``act(observation)`` once per step of
    that same environment. Call :meth:`close` (or use it as a context manager) to stop the
    rollout threads early; they also stop when the object is collected.
    """

    def __init__(self, options: MPCOptions | None = None) -> None:
        self.options = options or MPCOptions()
        self._pool: mj_rollout.Rollout | None = None
        self._stats = _Stats()

    # ----------------------------------------------------------------------------- set-up

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        handle = control_handle(env)
        o = self.options
        self.handle = handle
        self.model: mujoco.MjModel = handle.model
        self.data: mujoco.MjData = handle.data
        self.control_dt = float(handle.control_timestep_s)
        ratio = self.control_dt / o.planning_timestep_s
        if abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(
                f"the control step {self.control_dt} s must be a multiple of "
                f"planning_timestep_s {o.planning_timestep_s}"
            )
        self._rollout_steps_per_control = round(ratio)
        self.cost = PianoCost(handle, o.key_weight, o.finger_weight)
        self._build_planning_model(handle)
        self._setup_plan()
        self._setup_rollout_buffers()
        self._rng = np.random.default_rng(o.seed if o.seed is not None else seed)
        # Start by holding the pose the environment starts in (its reset sets the servos'
        # targets to their current lengths).
        ctrlrange = self.model.actuator_ctrlrange
        hold = (self.data.ctrl - ctrlrange[:, 0]) / ((ctrlrange[:, 1] - ctrlrange[:, 0]) / 2) - 1
        self.nominal = np.tile(np.clip(hold, -1.0, 1.0), (o.num_knots, 1))
        self.last_costs = np.zeros(0)
        self._stats = _Stats()

    def _build_planning_model(self, env: ControlHandle) -> None:
        """The scene compiled again with position sensors for the cost, at the planning step."""
        o, model, scene = self.options, self.model, env.scene
        spec = build_spec(scene.options, key_history=env.config.substeps)
        sites = [int(s) for hand in scene.hands for s in hand.fingertip_sites]
        sites += [int(s) for s in scene.key_sites]
        for site in sites:
            spec.add_sensor(
                name=f"mpc/{model.site(site).name}",
                type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                objtype=mujoco.mjtObj.mjOBJ_SITE,
                objname=model.site(site).name,
            )
        for key, joint_qpos in enumerate(scene.key_qpos):
            joint = int(np.flatnonzero(model.jnt_qposadr == joint_qpos)[0])
            spec.add_sensor(
                name=f"mpc/key{key}",
                type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                objtype=mujoco.mjtObj.mjOBJ_JOINT,
                objname=model.joint(joint).name,
            )
        planning = spec.compile()
        planning.opt.timestep = o.planning_timestep_s
        # Sleeping islands (the fast preset) keep per-body sleep state in MjData that
        # mjSTATE_FULLPHYSICS does not carry: a rollout would then depend on what its thread's
        # MjData ran before (measured: costs differ by ~1e-5 between a fresh and a used MjData).
        # The planning model stays awake, so rollouts are a pure function of state and plan.
        planning.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        self._nstate = mujoco.mj_stateSize(model, _FULLPHYSICS)
        if mujoco.mj_stateSize(planning, _FULLPHYSICS) != self._nstate or planning.nu != model.nu:
            raise RuntimeError("the planning model's state does not match the environment's")
        self.planning_model = planning
        adr = planning.sensor_adr
        n_tips = 5 * len(scene.hands)
        first = planning.nsensor - len(sites) - C.NUM_KEYS
        tips = adr[first : first + n_tips]
        keys = adr[first + n_tips : first + n_tips + C.NUM_KEYS]
        # (10, 3) sensordata addresses of each finger's position; absent hands read finger 0 of
        # a present hand (their pairs are never scored).
        self._tip_adr = np.empty((_FINGERS, 3), dtype=np.intp)
        row = 0
        for hand in scene.hands:
            offset = 0 if hand.side == "right" else 5
            for f in range(5):
                self._tip_adr[offset + f] = tips[row] + np.arange(3)
                row += 1
        if len(scene.hands) == 1:
            offset = 5 if scene.hands[0].side == "right" else 0
            self._tip_adr[offset : offset + 5] = self._tip_adr[5 - offset : 10 - offset]
        self._target_adr = keys[:, None] + np.arange(3)
        self._key_adr = adr[planning.nsensor - C.NUM_KEYS :]

    def _setup_plan(self) -> None:
        o = self.options
        self.knot_times = knot_times(o.num_knots, o.horizon_s)
        H = o.horizon_steps
        # Control step of each rollout step (one extra step: sensors lag the state by a step).
        step_t = np.arange(H + 1) * o.planning_timestep_s
        self._control_index = np.floor(step_t / self.control_dt + 1e-9).astype(int)
        self._control_weights = interpolation_weights(
            self._control_index * self.control_dt, self.knot_times, o.interpolation
        )  # (H + 1, K)
        self._shift = interpolation_weights(
            self.knot_times + self.control_dt, self.knot_times, o.interpolation
        )  # (K, K)

    def _setup_rollout_buffers(self) -> None:
        o, planning = self.options, self.planning_model
        B, H = o.num_samples, o.horizon_steps
        if self._pool is not None:
            self._pool.close()
        nthread = o.threads if o.threads > 1 else 0
        self._pool = mj_rollout.Rollout(nthread=nthread)
        self._datas = [mujoco.MjData(planning) for _ in range(max(nthread, 1))]
        self._models = [planning] * B
        self._initial_state = np.empty((B, self._nstate))
        self._warmstart = np.empty((B, planning.nv))
        self._ctrl = np.empty((B, H + 1, planning.nu))
        self._state_out = np.empty((B, H + 1, self._nstate))
        self._sensor_out = np.empty((B, H + 1, planning.nsensordata))
        self._state = np.empty(self._nstate)

    # ----------------------------------------------------------------------------- API

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """Plan from the environment's current state; the nominal's first action, (nu + 1,)."""
        start = time.perf_counter()
        o = self.options
        for _ in range(o.iterations):
            self.plan_iteration()
        first = self._control_weights[0] @ self.nominal
        self.nominal = self._shift @ self.nominal
        action = np.empty(self.model.nu + 1, dtype=np.float32)
        action[:-1] = np.clip(first, -1.0, 1.0)
        action[-1] = 1.0 if observation["goal"][0, C.NUM_KEYS] >= 0.5 else -1.0
        self._stats.steps += 1
        self._stats.plan_seconds += time.perf_counter() - start
        return action

    def plan_iteration(self) -> tuple[float, float]:
        """One predictive-sampling iteration from the environment's current state.

        Returns:
            (cost of the nominal before, cost of the new nominal); the second is never larger.
        """
        o = self.options
        candidates = np.empty((o.num_samples, o.num_knots, self.model.nu))
        candidates[0] = self.nominal
        if o.num_samples > 1:
            noise = self._rng.normal(0.0, o.sigma, candidates[1:].shape)
            np.clip(self.nominal + noise, -1.0, 1.0, out=candidates[1:])
        costs = self.rollout_costs(candidates).mean(axis=1)
        costs[~np.isfinite(costs)] = np.inf
        best = int(np.argmin(costs))
        self.nominal = candidates[best].copy()
        self.last_costs = costs
        self._stats.iterations += 1
        return float(costs[0]), float(costs[best])

    def rollout_costs(self, knots: np.ndarray) -> np.ndarray:
        """Roll plans out from the environment's current state and score every step.

        Args:
            knots: (B, K, nu) knots of B plans in normalised action units, B <= num_samples.
        Returns:
            (B, H) cost of the state after each rollout step (H = horizon steps).
        """
        o = self.options
        B, H = len(knots), o.horizon_steps
        if B > o.num_samples or knots.shape[1:] != (o.num_knots, self.model.nu):
            raise ValueError(
                f"knots must have shape (<= {o.num_samples}, {o.num_knots}, {self.model.nu}), "
                f"not {knots.shape}"
            )
        mujoco.mj_getState(self.model, self.data, self._state, _FULLPHYSICS)
        self._initial_state[:B] = self._state
        self._warmstart[:B] = self.data.qacc_warmstart
        # Rounded as the float32 actions that act() returns, so the first control step of a
        # rollout is bit for bit what the environment will do.
        actions = (self._control_weights @ knots).astype(np.float32)  # (B, H + 1, nu)
        self._ctrl[:B] = self.handle.action_to_ctrl(actions)
        start = time.perf_counter()
        self._pool.rollout(  # type: ignore[union-attr]
            self._models[:B],
            self._datas,
            self._initial_state[:B],
            self._ctrl[:B],
            skip_checks=True,
            nstep=H + 1,
            initial_warmstart=self._warmstart[:B],
            state=self._state_out[:B],
            sensordata=self._sensor_out[:B],
        )
        self._stats.rollout_seconds += time.perf_counter() - start
        self._stats.rollout_steps += B * (H + 1)
        # Sensors are computed at the start of a step: row j + 1 measures the state after step j.
        sensors = self._sensor_out[:B, 1:]
        frames = self.handle.step_index + self._control_index[:H]
        return self.cost.stage_costs(
            frames,
            sensors[..., self._key_adr],
            sensors[..., self._tip_adr],
            sensors[..., self._target_adr],
        )

    def stats(self) -> dict[str, float]:
        """Timing since ``reset``, for metrics.json and progress bars.

        ``mpc_realtime_factor`` is simulated seconds per second of planning (0.1 = one tenth of
        real time); ``mpc_rollout_steps_per_s`` the rollout throughput of the physics (rollout
        steps at the planning timestep, all threads together).
        """
        s = self._stats
        simulated = s.steps * getattr(self, "control_dt", 0.0)
        return {
            "mpc_steps": s.steps,
            "mpc_iterations": s.iterations,
            "mpc_plan_seconds": s.plan_seconds,
            "mpc_ms_per_step": 1e3 * s.plan_seconds / s.steps if s.steps else 0.0,
            "mpc_realtime_factor": simulated / s.plan_seconds if s.plan_seconds else 0.0,
            "mpc_rollout_steps_per_s": (
                s.rollout_steps / s.rollout_seconds if s.rollout_seconds else 0.0
            ),
            # Share of the planning time spent inside mujoco.rollout (the rest is Python/NumPy).
            "mpc_rollout_fraction": s.rollout_seconds / s.plan_seconds if s.plan_seconds else 0.0,
        }

    def options_dict(self) -> dict[str, Any]:
        """The options as plain values (for metrics.json / a run's resolved config)."""
        return asdict(self.options)

    def close(self) -> None:
        """Stop the rollout threads."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def __enter__(self) -> PredictiveSampling:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
