"""An inverse-kinematics planner: plays a fingered song with no training.

Each control step it

1. plans where each forearm should be: for every goal frame, the slide position that puts the
   assigned fingers over their keys (fingertip offsets measured in the rest pose), held until
   the hand's next note, and commanded ``forearm_lead_s`` ahead so the hand arrives in time;
2. sets fingertip targets: the assigned fingertip pressed into each key due at the coming
   frame, fingers due within ``hover_lead_s`` hovering just above their keys, the others lifted
   clear of the keyboard;
3. solves damped least squares on the fingertip sites' Jacobians (``mujoco.mj_jacSite``) over
   each hand's actuated joints, with the coupled J1+J2 finger tendons as one DoF, a pull
   towards a rest posture, and joint limits as clipping, on a scratch ``MjData`` whose forearms
   sit where they were commanded to go;
4. sends those joint targets as the position-servo controls; the pedal follows the goal.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import mujoco
import numpy as np

from pianist.sim import constants as C

FINGERS_PER_HAND = 5


@dataclass(frozen=True)
class PlannerConfig:
    """Tuning of :class:`IKPlanner`; lengths in m, times in s."""

    press_depth_m: float = 0.014
    """How far below the key's top surface the fingertip contact is sent when pressing."""
    hover_height_m: float = 0.012
    """Clearance above the key top of a finger that is due soon."""
    lift_height_m: float = 0.03
    """Clearance above the white keys of a finger that is not due."""
    press_lead_frames: int = 1
    """Frames ahead of the scored frame whose keys the fingers go for."""
    hover_lead_s: float = 0.25
    align_tolerance_m: float = 0.006
    """How close (horizontally) to its key a finger must be before it presses."""
    forearm_lead_s: float = 0.2
    forearm_separation_m: float = 0.21
    """Closest the two forearm roots may come along the keyboard (they collide below ~0.15)."""
    iterations: int = 6
    damping: float = 0.005
    """Levenberg damping of the least squares (1/rad scale)."""
    rest_weight: float = 1e-4
    """Pull of every joint towards its rest angle (per rad^2, against fingertip error in m^2)."""
    idle_weight: float = 0.4
    """Weight of a lifted finger's target against a pressing finger's (1)."""
    step_limit_rad: float = 0.4
    """Largest change of one joint in one IK iteration."""


class IKPlanner:
    """Plays the song of a :class:`pianist.env.PianoEnv` from its goal frames and fingering.

    Use like any controller: ``reset(env)``, then ``act(observation)`` each step. Needs every
    note fingered and the reduced or full action space with the ``tx`` forearm slide.
    """

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config or PlannerConfig()

    # ----------------------------------------------------------------------------- set-up

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        base = env.unwrapped
        self.env = base
        self.model: mujoco.MjModel = base.model
        self.scratch = mujoco.MjData(self.model)
        goal = base.goal
        due = goal.keys
        if np.any(due & (goal.fingers < 0)):
            raise ValueError(
                "the planner needs a finger for every note; this song has unfingered notes"
            )
        self.goal = goal
        self.dt = base.config.control_timestep_s
        m = self.model
        mujoco.mj_resetData(m, self.scratch)
        mujoco.mj_kinematics(m, self.scratch)
        self.key_target = self.scratch.site_xpos[base.scene.key_sites].copy()
        self.key_top_z = np.where(
            C.BLACK_KEY_MASK,
            C.WHITE_KEY_HEIGHT_M + C.BLACK_KEY_TOP_ABOVE_WHITE_M,
            C.WHITE_KEY_HEIGHT_M,
        )
        self.hands = [_HandModel(m, self.scratch, base, hand) for hand in base.scene.hands]
        for hand in self.hands:
            hand.calibrate(m, self.scratch, self.key_target, self.key_top_z, self.config)
            hand.plan_forearm(goal, self.key_target, self.dt, self.config)
        if len(self.hands) == 2:
            _keep_forearms_apart(*self.hands, self.config.forearm_separation_m)
        self.nu = m.nu

    # ----------------------------------------------------------------------------- acting

    def act(self, observation: object = None) -> np.ndarray:
        cfg, env, m, scratch = self.config, self.env, self.model, self.scratch
        t = env.step_index
        T = self.goal.num_frames
        ctrl = np.array(env.data.ctrl)
        scratch.qpos[:] = env.data.qpos
        for hand in self.hands:
            hand.command_forearm(scratch, ctrl, t, self.dt, cfg)
        _kinematics(m, scratch)
        press_frame = min(t + cfg.press_lead_frames, T - 1)
        hover_frames = range(
            press_frame + 1, min(T, press_frame + 1 + round(cfg.hover_lead_s / self.dt))
        )
        for hand in self.hands:
            targets, weights = hand.fingertip_targets(
                self.goal,
                press_frame,
                hover_frames,
                scratch,
                env.data.site_xpos[hand.sites],
                self.key_target,
                self.key_top_z,
                cfg,
            )
            hand.solve(m, scratch, targets, weights, cfg)
            ctrl[hand.actuators] = hand.controls(scratch)
        action = np.empty(self.nu + 1)
        low, high = m.actuator_ctrlrange.T
        action[:-1] = np.clip(2 * (ctrl - low) / (high - low) - 1, -1, 1)
        action[-1] = 1.0 if self.goal.sustain[min(t + cfg.press_lead_frames, T - 1)] else -1.0
        return action.astype(np.float32)


class _HandModel:
    """Indices and per-hand state of the planner for one hand."""

    def __init__(self, m: mujoco.MjModel, data: mujoco.MjData, env: object, hand: object) -> None:
        self.side = hand.side
        self.finger_offset = 0 if hand.side == "right" else FINGERS_PER_HAND
        self.sites = np.asarray(hand.fingertip_sites)
        prefix = C.HAND_PREFIX[hand.side]
        self.tx_joint = m.joint(f"{prefix}forearm_tx").id
        self.tx_qpos = m.jnt_qposadr[self.tx_joint]
        self.tx_actuator = m.actuator(f"{prefix}A_forearm_tx").id
        forearm_actuators = {
            a for a in hand.actuators if m.actuator(a).name.startswith(f"{prefix}A_forearm")
        }
        # Actuated DoFs of the fingers and wrist: a joint, or a tendon coupling two joints.
        self.actuators = np.array([a for a in hand.actuators if a not in forearm_actuators])
        self.columns: list[np.ndarray] = []  # dof addresses moved by each actuator
        self.qpos_of: list[np.ndarray] = []
        for a in self.actuators:
            if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_TENDON:
                tendon = m.actuator_trnid[a, 0]
                start, count = m.tendon_adr[tendon], m.tendon_num[tendon]
                joints = m.wrap_objid[start : start + count]
            else:
                joints = np.array([m.actuator_trnid[a, 0]])
            self.columns.append(m.jnt_dofadr[joints])
            self.qpos_of.append(m.jnt_qposadr[joints])
        self.share = np.array([1.0 / len(c) for c in self.columns])  # tendon: split evenly
        self.low, self.high = m.actuator_ctrlrange[self.actuators].T
        # Rest posture: fingers gently curled so that the tips point down at the keys.
        self.rest = np.clip(np.zeros(len(self.actuators)), self.low, self.high)
        for i, a in enumerate(self.actuators):
            name = m.actuator(a).name
            if name.endswith(("FFJ3", "MFJ3", "RFJ3", "LFJ3")):
                self.rest[i] = 0.6
            elif name.endswith("J0") and "TH" not in name:
                self.rest[i] = 1.0
            elif name.endswith("WRJ1"):
                self.rest[i] = 0.0
        self.rest = np.clip(self.rest, self.low, self.high)
        self.tx_range = m.jnt_range[self.tx_joint]
        self.root_y = C.FOREARM_ROOT_POS_M[hand.side][1]
        self.tx_dof = m.jnt_dofadr[self.tx_joint]
        self.jacp = np.zeros((3, m.nv))

    def calibrate(self, m, data, key_target, key_top_z, cfg: PlannerConfig) -> None:
        """Where the forearm must be, relative to a key, for each finger to press it.

        For each finger, solve the IK with the forearm slide free for that finger pressing a
        white key near the hand's home position (others lifted), and record key y - slide.
        """
        mujoco.mj_resetData(m, data)
        _kinematics(m, data)
        home_y = data.site_xpos[self.sites[2], 1]  # middle finger over its home key
        key = int(np.argmin(np.abs(key_target[:, 1] - home_y) + 1.0 * C.BLACK_KEY_MASK))
        self.tip_offset_y = np.zeros(FINGERS_PER_HAND)
        for finger in range(FINGERS_PER_HAND):
            mujoco.mj_resetData(m, data)
            _kinematics(m, data)
            targets = data.site_xpos[self.sites].copy()
            targets[:, 2] = C.WHITE_KEY_HEIGHT_M + cfg.lift_height_m + C.FINGERTIP_CAPSULE_RADIUS_M
            targets[finger] = key_target[key]
            targets[finger, 2] = key_top_z[key] + C.FINGERTIP_CAPSULE_RADIUS_M - cfg.press_depth_m
            weights = np.full(FINGERS_PER_HAND, cfg.idle_weight)
            weights[finger] = 1.0
            self._weights_xy = (np.arange(FINGERS_PER_HAND) == finger).astype(float)
            cfg_more = PlannerConfig(**{**cfg.__dict__, "iterations": 40})
            self.solve(m, data, targets, weights, cfg_more, free_forearm=True)
            self.tip_offset_y[finger] = key_target[key, 1] - data.qpos[self.tx_qpos]

    def plan_forearm(self, goal, key_target: np.ndarray, dt: float, cfg: PlannerConfig) -> None:
        """Forearm slide position wanted at every frame, shape (T,)."""
        T = goal.num_frames
        wanted = np.full(T, np.nan)
        for t in range(T):
            keys = np.flatnonzero(goal.keys[t])
            fingers = goal.fingers[t, keys]
            mine = (fingers >= self.finger_offset) & (fingers < self.finger_offset + 5)
            if mine.any():
                local = fingers[mine] - self.finger_offset
                wanted[t] = np.mean(key_target[keys[mine], 1] - self.tip_offset_y[local])
        # Between notes, hold the next note's position (go there early); after the last, stay.
        self.busy = ~np.isnan(wanted)
        known = np.flatnonzero(self.busy)
        if known.size == 0:
            wanted[:] = 0.0
        else:
            nxt = np.searchsorted(known, np.arange(T))
            nxt = np.minimum(nxt, known.size - 1)
            fill = np.isnan(wanted)
            wanted[fill] = wanted[known[nxt[fill]]]
        self.tx_plan = np.clip(wanted, *self.tx_range)

    def command_forearm(self, scratch, ctrl: np.ndarray, t: int, dt: float, cfg) -> None:
        lead = round(cfg.forearm_lead_s / dt)
        target = self.tx_plan[min(t + lead, len(self.tx_plan) - 1)]
        # The fingers are solved for where the forearm is now, not where it is going: they
        # then reach their keys even while the forearm is still on its way.
        ctrl[self.tx_actuator] = target

    def fingertip_targets(
        self, goal, frame: int, hover_frames, scratch, real_tips, key_target, key_top_z, cfg
    ) -> tuple[np.ndarray, np.ndarray]:
        """(5, 3) fingertip targets and (5,) weights for this hand.

        A finger due to press comes down only once it is over its key (``real_tips``, the
        fingertips' actual positions, within ``align_tolerance_m``): a finger that lands beside
        its key sticks to the key top by friction and presses the gap or the neighbour.
        """
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        tips = scratch.site_xpos[self.sites]
        targets = tips.copy()
        targets[:, 2] = C.WHITE_KEY_HEIGHT_M + cfg.lift_height_m + radius
        weights = np.full(FINGERS_PER_HAND, cfg.idle_weight)
        weights_xy = np.zeros(FINGERS_PER_HAND)  # lifted fingers: only height matters
        assigned = np.zeros(FINGERS_PER_HAND, dtype=bool)
        keys = np.flatnonzero(goal.keys[frame])
        for key in keys:
            finger = goal.fingers[frame, key] - self.finger_offset
            if 0 <= finger < FINGERS_PER_HAND:
                targets[finger] = key_target[key]
                aligned = np.hypot(*(real_tips[finger, :2] - key_target[key, :2]))
                if (
                    aligned <= cfg.align_tolerance_m
                    or real_tips[finger, 2] < key_top_z[key] + radius
                ):
                    targets[finger, 2] = key_top_z[key] + radius - cfg.press_depth_m
                else:
                    targets[finger, 2] = key_top_z[key] + radius + cfg.hover_height_m
                weights[finger] = 1.0
                weights_xy[finger] = 1.0
                assigned[finger] = True
        for t in hover_frames:
            for key in np.flatnonzero(goal.keys[t]):
                finger = goal.fingers[t, key] - self.finger_offset
                if 0 <= finger < FINGERS_PER_HAND and not assigned[finger]:
                    targets[finger] = key_target[key]
                    targets[finger, 2] = key_top_z[key] + radius + cfg.hover_height_m
                    weights[finger] = 0.7
                    weights_xy[finger] = 0.7
                    assigned[finger] = True
        self._weights_xy = weights_xy
        return targets, weights

    def solve(
        self, m, scratch, targets: np.ndarray, weights: np.ndarray, cfg, free_forearm=False
    ) -> None:
        """Damped least squares on the scratch data, in actuator space (plus the forearm
        slide along the keyboard when ``free_forearm``)."""
        n = len(self.actuators) + int(free_forearm)
        u = self.controls(scratch)
        low, high, rest = self.low, self.high, self.rest
        if free_forearm:
            u = np.append(u, scratch.qpos[self.tx_qpos])
            low, high = np.append(low, self.tx_range[0]), np.append(high, self.tx_range[1])
            rest = np.append(rest, u[-1])
        w = np.repeat(weights, 3)
        w[0::3] = np.where(self._weights_xy > 0, w[0::3], 0.0)  # lifted: x, y free
        w[1::3] = np.where(self._weights_xy > 0, w[1::3], 0.0)
        J = np.zeros((3 * FINGERS_PER_HAND, n))
        for _ in range(cfg.iterations):
            _kinematics(m, scratch)
            for f, site in enumerate(self.sites):
                mujoco.mj_jacSite(m, scratch, self.jacp, None, int(site))
                for i, cols in enumerate(self.columns):
                    J[3 * f : 3 * f + 3, i] = self.jacp[:, cols].sum(axis=1) * self.share[i]
                if free_forearm:
                    J[3 * f : 3 * f + 3, -1] = self.jacp[:, self.tx_dof]
            error = (targets - scratch.site_xpos[self.sites]).ravel()
            A = J.T @ (w[:, None] * J) + (cfg.damping**2 + cfg.rest_weight) * np.eye(n)
            b = J.T @ (w * error) + cfg.rest_weight * (rest - u)
            du = np.clip(np.linalg.solve(A, b), -cfg.step_limit_rad, cfg.step_limit_rad)
            u = np.clip(u + du, low, high)
            self._set(scratch, u[: len(self.actuators)])
            if free_forearm:
                scratch.qpos[self.tx_qpos] = u[-1]
        _kinematics(m, scratch)

    def controls(self, scratch) -> np.ndarray:
        """Actuator-space angles of the scratch pose (tendon = sum of its joints)."""
        return np.array([scratch.qpos[q].sum() for q in self.qpos_of])

    def _set(self, scratch, u: np.ndarray) -> None:
        for value, q, share in zip(u, self.qpos_of, self.share, strict=True):
            scratch.qpos[q] = value * share


def _keep_forearms_apart(a: _HandModel, b: _HandModel, separation: float) -> None:
    """Shift the forearm plans so the right forearm stays ``separation`` m right of the left.

    A hand with nothing to play yields to the other; when both play, both give way equally.
    """
    right, left = (a, b) if a.side == "right" else (b, a)
    y_right = right.tx_plan + right.root_y
    y_left = left.tx_plan + left.root_y
    short = np.maximum(separation - (y_right - y_left), 0.0)
    right_share = np.where(
        right.busy & ~left.busy, 0.0, np.where(left.busy & ~right.busy, 1.0, 0.5)
    )
    right.tx_plan = np.clip(right.tx_plan + short * right_share, *right.tx_range)
    left.tx_plan = np.clip(left.tx_plan - short * (1 - right_share), *left.tx_range)


def _kinematics(m: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Positions and the quantities ``mj_jacSite`` reads (cdof, subtree centres of mass)."""
    mujoco.mj_kinematics(m, data)
    mujoco.mj_comPos(m, data)
