"""One hand: its indices into the model and its state, and every stage's methods on it.

:class:`Hand` gathers the stages' mixins (:class:`HandPostures`, :class:`ForearmPlan`,
:class:`FingerTargets`, :class:`FingerIK`, one per module). Its ``__init__`` finds the hand's
forearm slides, wrist and finger actuators and fingertip sites in the model, and starts the
per-finger memory that the fingertip targets keep between steps.
"""

from __future__ import annotations

import mujoco
import numpy as np

from pianist.control.planner.config import FINGER_PREFIXES, FINGERS_PER_HAND, PlannerConfig
from pianist.control.planner.forearm import ForearmPlan
from pianist.control.planner.ik import FingerIK
from pianist.control.planner.postures import Finger, HandPostures, _actuated_qpos
from pianist.control.planner.targets import FingerTargets
from pianist.sim import constants as C


class Hand(HandPostures, ForearmPlan, FingerTargets, FingerIK):
    """One hand: its indices, posture samples, forearm plan and per-finger IK."""

    def __init__(self, m, hand, full_hand: bool = False) -> None:
        self.side = hand.side
        self.finger_offset = 0 if hand.side == "right" else FINGERS_PER_HAND
        self.sites = np.asarray(hand.fingertip_sites)
        prefix = C.HAND_PREFIX[hand.side]
        self.forearm_body = m.body(f"{prefix}forearm").id
        self.tx_qpos = m.jnt_qposadr[m.joint(f"{prefix}forearm_tx").id]
        self.tx_range = m.jnt_range[m.joint(f"{prefix}forearm_tx").id]
        self.tx_actuator = m.actuator(f"{prefix}A_forearm_tx").id
        self.tx_dof = m.jnt_dofadr[m.joint(f"{prefix}forearm_tx").id]
        self.root_y = C.FOREARM_ROOT_POS_M[hand.side][1]
        tz = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{prefix}A_forearm_tz")
        self.tz_actuator = tz if tz >= 0 else None
        self.tz_qpos = m.jnt_qposadr[m.joint(f"{prefix}forearm_tz").id] if tz >= 0 else None
        self.tz_range = m.actuator_ctrlrange[tz] if tz >= 0 else None
        ty = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{prefix}A_forearm_ty")
        self.ty_actuator = ty if ty >= 0 else None
        self.ty_qpos = m.jnt_qposadr[m.joint(f"{prefix}forearm_ty").id] if ty >= 0 else None

        # Actuated joints of each finger (a joint, or a tendon over two joints) and the wrist.
        self.fingers: list[Finger] = []
        self.wrist: list[tuple[int, np.ndarray]] = []
        for i, finger_prefix in enumerate(FINGER_PREFIXES):
            acts = [
                a
                for a in hand.actuators
                if m.actuator(a).name.startswith(f"{prefix}A_{finger_prefix}")
                and (full_hand or not _reduced_away(m.actuator(a).name))
            ]
            finger = Finger(m, acts, int(self.sites[i]))
            if not full_hand:
                _narrow_to_reduced(finger)
            self.fingers.append(finger)
        # Actuators of joints the reduced hand does without, commanded 0 every step (in the
        # full action space, unless ``full_hand``).
        self.held_actuators = np.array(
            [a for a in hand.actuators if not full_hand and _reduced_away(m.actuator(a).name)],
            dtype=int,
        )
        for a in hand.actuators:
            if m.actuator(a).name.startswith(f"{prefix}A_WR"):
                self.wrist.append((int(a), _actuated_qpos(m, a)))
        self.finger_actuators = np.concatenate([f.actuators for f in self.fingers])
        self.jacp = np.zeros((3, m.nv))
        self.pressing = np.zeros(FINGERS_PER_HAND, dtype=bool)
        self.free = np.zeros(0, dtype=bool)
        self.stuck = np.zeros(FINGERS_PER_HAND, dtype=int)
        self.last_tips = np.zeros((FINGERS_PER_HAND, 3))
        self.last_key = np.full(FINGERS_PER_HAND, -1)  # key each finger pressed last, or -1
        self.unsounded = np.zeros(FINGERS_PER_HAND, dtype=int)  # see FingerTargets
        self.repress = np.zeros(FINGERS_PER_HAND, dtype=bool)
        self.state = np.zeros(FINGERS_PER_HAND, dtype=np.int8)  # FingerState.LIFTED
        self.active = np.zeros(FINGERS_PER_HAND, dtype=bool)
        # The push each finger is giving (a soft note, see strikes.py): its key (-1: none),
        # the step its key should sound at and the depth sent the last step (m).
        self.push_key = np.full(FINGERS_PER_HAND, -1)
        self.push_sound = np.full(FINGERS_PER_HAND, -1)
        self.push_depth = np.zeros(FINGERS_PER_HAND)
        # Execution settings of this hand alone (IKPlanner.set_hand_settings); None: the
        # planner's config.
        self.settings: PlannerConfig | None = None


def _reduced_away(actuator_name: str) -> bool:
    """Whether an actuator drives a joint the paper's reduced hand does without (THJ5, THJ1,
    LFJ5): present only in the full action space. The planner commands it to 0, where
    the reduced hand has the joint fixed."""
    return actuator_name.endswith(tuple(f"A_{joint}" for joint in C.REDUCED_REMOVED_JOINTS))


def _narrow_to_reduced(finger: Finger) -> None:
    """Limit THJ2's command to the reduced hand's range (a no-op where it already is)."""
    for j, name in enumerate(finger.names):
        if name.endswith("A_THJ2"):
            low, high = C.REDUCED_THJ2_RANGE_RAD
            finger.low[j] = max(finger.low[j], low)
            finger.high[j] = min(finger.high[j], high)
