"""One hand as the planner's stages see it: its indices into the model, and its fingers' memory.

- :class:`Finger`: one finger's actuated joints (actuator ids, limits, qpos and dof
  addresses, how a command spreads over a tendon's joints);
- :class:`Hand`: a hand's forearm slides, wrist, fingers and fingertip sites, read from the
  model once per episode (frozen: no stage writes to it);
- :class:`FingerMemory`: what each finger remembers from one step to the next (the press,
  hover and push decisions of :mod:`targets` read it and return it updated).

The stages are functions of these and of arrays: the poses (:mod:`postures`), the plan
(:mod:`forearm`, :mod:`plans`), the fingertip targets (:mod:`targets`) and the IK (:mod:`ik`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import mujoco
import numpy as np

from pianist.control.planner.config import FINGER_PREFIXES, FINGERS_PER_HAND
from pianist.sim import constants as C


class Finger:
    """The actuated joints of one finger: actuator ids, limits, how to set and differentiate.

    ``dof`` actuators (a joint each, or a tendon over two joints); ``low``, ``high`` (dof,) rad
    their command limits. Made once per episode; nothing changes it after."""

    def __init__(self, m, actuators: list[int], site: int) -> None:
        self.actuators = np.asarray(actuators, dtype=int)
        self.site = site
        self.dof = len(actuators)
        self.qpos = [_actuated_qpos(m, a) for a in actuators]
        self.dofs = [m.jnt_dofadr[_actuated_joints(m, a)] for a in actuators]
        self.share = np.array([1.0 / len(q) for q in self.qpos])  # tendon: split evenly
        self.low, self.high = m.actuator_ctrlrange[self.actuators].T
        self.names = [m.actuator(a).name for a in actuators]
        # Flat index arrays (the IK calls these every iteration): joint j of the finger is
        # driven by actuator owner[j] with a share of its command.
        owner = np.repeat(np.arange(self.dof), [len(q) for q in self.qpos])
        self._qpos, self._owner = np.concatenate(self.qpos), owner
        self._share = self.share[owner]
        self._dofs = np.concatenate(self.dofs)
        self._mix = np.zeros((len(owner), self.dof))  # joint velocities -> actuator space
        self._mix[np.arange(len(owner)), owner] = self._share

    def set(self, data, angles: np.ndarray) -> None:
        """Write the finger's actuator angles (dof,) rad to its joints in ``data.qpos``."""
        data.qpos[self._qpos] = angles[self._owner] * self._share

    def jacobian(self, jacp: np.ndarray) -> np.ndarray:
        """(3, dof) fingertip Jacobian in actuator space from the full (3, nv) one."""
        return jacp[:, self._dofs] @ self._mix


@dataclass(frozen=True, eq=False)
class Hand:
    """One hand's indices into the model (:meth:`build`): slides, wrist, fingers, sites."""

    side: str
    """"right" or "left"."""
    finger_offset: int
    """0 for the right hand, 5 for the left: its fingers' numbers are offset + 0-4."""
    sites: np.ndarray
    """(5,) int: the fingertip sites, thumb first."""
    forearm_body: int
    """The forearm body: fingertip targets are relative to its origin."""
    tx_qpos: int
    tx_dof: int
    tx_actuator: int
    tx_range: np.ndarray
    """(2,) m: the ``tx`` slide's range (along the keyboard)."""
    root_y: float
    """m: the forearm's y at ``tx`` 0."""
    tz_actuator: int | None
    tz_qpos: int | None
    tz_range: np.ndarray | None
    """(2,) m: the height slide's command range, None where the scene has no ``tz``."""
    ty_actuator: int | None
    ty_qpos: int | None
    fingers: tuple[Finger, ...]
    """Thumb to little finger."""
    wrist: tuple[tuple[int, np.ndarray], ...]
    """(actuator, qpos addresses) of WRJ2 (sideways), then WRJ1 (flexion)."""
    held_actuators: np.ndarray
    """Actuators of joints the reduced hand does without (commanded 0 every step in the full
    action space, unless ``full_hand``)."""
    finger_actuators: np.ndarray
    """Every finger's actuators, thumb first: the order of the IK's controls."""

    @property
    def slide_range(self) -> tuple[float, float]:
        """The ``tx`` slide's range (m)."""
        return float(self.tx_range[0]), float(self.tx_range[1])

    @classmethod
    def build(cls, m, hand, full_hand: bool = False) -> Hand:
        """The indices of the scene's ``hand`` (a :class:`pianist.sim.scene` hand) in ``m``;
        ``full_hand``: drive every finger joint of the action space (not the reduced hand's)."""
        prefix = C.HAND_PREFIX[hand.side]
        tx = m.joint(f"{prefix}forearm_tx").id
        tz = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{prefix}A_forearm_tz")
        ty = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{prefix}A_forearm_ty")
        sites = np.asarray(hand.fingertip_sites)
        fingers = []
        for i, finger_prefix in enumerate(FINGER_PREFIXES):
            acts = [
                a
                for a in hand.actuators
                if m.actuator(a).name.startswith(f"{prefix}A_{finger_prefix}")
                and (full_hand or not _reduced_away(m.actuator(a).name))
            ]
            finger = Finger(m, acts, int(sites[i]))
            if not full_hand:
                _narrow_to_reduced(finger)
            fingers.append(finger)
        return cls(
            side=hand.side,
            finger_offset=0 if hand.side == "right" else FINGERS_PER_HAND,
            sites=sites,
            forearm_body=m.body(f"{prefix}forearm").id,
            tx_qpos=int(m.jnt_qposadr[tx]),
            tx_dof=int(m.jnt_dofadr[tx]),
            tx_actuator=m.actuator(f"{prefix}A_forearm_tx").id,
            tx_range=m.jnt_range[tx].copy(),
            root_y=C.FOREARM_ROOT_POS_M[hand.side][1],
            tz_actuator=tz if tz >= 0 else None,
            tz_qpos=int(m.jnt_qposadr[m.joint(f"{prefix}forearm_tz").id]) if tz >= 0 else None,
            tz_range=m.actuator_ctrlrange[tz].copy() if tz >= 0 else None,
            ty_actuator=ty if ty >= 0 else None,
            ty_qpos=int(m.jnt_qposadr[m.joint(f"{prefix}forearm_ty").id]) if ty >= 0 else None,
            fingers=tuple(fingers),
            wrist=tuple(
                (int(a), _actuated_qpos(m, a))
                for a in hand.actuators
                if m.actuator(a).name.startswith(f"{prefix}A_WR")
            ),
            held_actuators=np.array(
                [a for a in hand.actuators if not full_hand and _reduced_away(m.actuator(a).name)],
                dtype=int,
            ),
            finger_actuators=np.concatenate([f.actuators for f in fingers]),
        )

    def own_keys(self, goal) -> np.ndarray:
        """(T, 88) bool: the due keys the song gives this hand."""
        local = goal.fingers - self.finger_offset
        return goal.keys & (local >= 0) & (local < FINGERS_PER_HAND)


def _zeros_int() -> np.ndarray:
    return np.zeros(FINGERS_PER_HAND, dtype=int)


def _none_int() -> np.ndarray:
    return np.full(FINGERS_PER_HAND, -1)


@dataclass(eq=False)
class FingerMemory:
    """What a hand's fingers remember between steps, (5,) arrays thumb first (the fingertip
    targets read it and return it updated,
    :func:`~pianist.control.planner.targets.fingertip_targets`; a look-ahead copies it and
    goes back to the copy)."""

    pressing: np.ndarray = field(default_factory=lambda: np.zeros(FINGERS_PER_HAND, dtype=bool))
    """bool: sent below its key's top this step."""
    stuck: np.ndarray = field(default_factory=_zeros_int)
    """int: steps a hovering finger has stood still (``still_m``)."""
    last_tips: np.ndarray = field(default_factory=lambda: np.zeros((FINGERS_PER_HAND, 3)))
    """(5, 3) m: the fingertips last step (world frame)."""
    last_key: np.ndarray = field(default_factory=_none_int)
    """int: the key each finger pressed last, kept while it hovers on to the next (-1: none)."""
    unsounded: np.ndarray = field(default_factory=_zeros_int)
    """int: steps a finger has pressed the same key without it sounding."""
    repress: np.ndarray = field(default_factory=lambda: np.zeros(FINGERS_PER_HAND, dtype=bool))
    """bool: pressing again this step the key it let up the step before (a re-strike)."""
    state: np.ndarray = field(default_factory=lambda: np.zeros(FINGERS_PER_HAND, dtype=np.int8))
    """int8: each finger's :class:`~pianist.control.planner.targets.FingerState` this step."""
    active: np.ndarray = field(default_factory=lambda: np.zeros(FINGERS_PER_HAND, dtype=bool))
    """bool: which fingers had a target this step (the others took their lifted posture)."""
    push_key: np.ndarray = field(default_factory=_none_int)
    """int: the key of the soft note a finger pushed last (-1: none, see :mod:`strikes`)."""
    strike_key: np.ndarray = field(default_factory=_none_int)
    """int: the key a finger starts to strike this step, a note whose strike is predicted
    (-1: none, :mod:`strike_prediction`)."""
    strike_frame: np.ndarray = field(default_factory=_none_int)
    """int: the frame that note is due at."""
    push_target: np.ndarray = field(default_factory=lambda: np.full(FINGERS_PER_HAND, np.nan))
    """rad: the angle a predicted push aims its key at by this step's end (NaN: no predicted
    push this step, :mod:`strike_prediction`)."""

    def copy(self) -> FingerMemory:
        """A copy whose arrays share nothing with this one."""
        return FingerMemory(**{f.name: getattr(self, f.name).copy() for f in fields(self)})

    def equals(self, other: FingerMemory) -> bool:
        """Whether every array is the same."""
        return all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name), equal_nan=True)
            for f in fields(self)
        )


def _actuated_joints(m, actuator: int) -> np.ndarray:
    if m.actuator_trntype[actuator] == mujoco.mjtTrn.mjTRN_TENDON:
        tendon = m.actuator_trnid[actuator, 0]
        start, count = m.tendon_adr[tendon], m.tendon_num[tendon]
        return m.wrap_objid[start : start + count]
    return np.array([m.actuator_trnid[actuator, 0]])


def _actuated_qpos(m, actuator: int) -> np.ndarray:
    return m.jnt_qposadr[_actuated_joints(m, actuator)]


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
