"""Each finger's joint angles for its fingertip target: inverse kinematics, wrist held still.

Inputs: the (5, 3) fingertip targets (m, relative to the forearm body) and (5,) bool active
flags from :mod:`targets`, and a scratch ``MjData`` with the forearm and wrist as commanded.
Each active finger starts from its nearest sampled posture (:mod:`postures`), then takes
``iterations`` damped least-squares steps on ``mujoco.mj_jacSite`` over its actuated joints,
clipped to their limits; an inactive one takes its lifted posture. A pressing finger is then
pushed further down (``thumb_push_rad``, ``finger_push_rad``).

The five fingers are solved together: their postures are padded to the widest finger's
actuators (:class:`FingerBatch`), so that each iteration is one kinematics pass and a handful of
batched array operations instead of five rounds of small ones (the IK runs at every control
step for every hand, and per-call overhead, not arithmetic, was its cost). A padded actuator
has no Jacobian column and limits (0, 0): it never moves, and the real ones get the same
steps as a finger solved alone.

Output (:func:`solve_fingers`): every finger's angles, (5, D) rad padded (also set in the
scratch state); :func:`finger_controls` gathers them, thumb to little finger: the hand's
finger commands. A hand's :class:`FingerBatch` per pose is made with the pose
(:class:`~pianist.control.planner.postures.HandPose`).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from pianist.control.planner.hand import Finger, FingerMemory, Hand
from pianist.control.planner.targets import FingerState


class FingerBatch:
    """A hand's five fingers laid out side by side, padded to ``D`` actuators each.

    Arrays (F = 5 fingers, D = the most actuators of a finger, S = posture samples, J = the
    most joints of a finger):

    - ``low``, ``high`` (F, D) rad: actuator limits (0 for padding);
    - ``dofs`` (F, J) int: each finger's joint dof addresses (padding: dof 0, unused);
    - ``mix`` (F, J, D): joint velocities -> actuator space (zero rows for padding);
    - ``qpos`` (Q,) int, ``source`` (Q,) int, ``share`` (Q,): the joints' qpos addresses, the
      flat (F * D) slot driving each and its share of the command (a tendon splits evenly);
    - ``samples`` (F, S, D) rad and ``tips`` (F, S, 3) m: the sampled postures and their
      fingertips in the forearm frame;
    - ``tip_norms`` (F, S) m^2: the squared length of each of those fingertips;
    - ``lift`` (F, D) rad: the lifted postures;
    - ``jacs`` (F, 3, nv), ``jacp`` (3, nv): scratch Jacobians the solve writes into.
    """

    def __init__(
        self,
        fingers: Sequence[Finger],
        samples: Sequence[tuple[np.ndarray, np.ndarray]],
        lift: Sequence[np.ndarray],
        nv: int,
    ) -> None:
        """``samples``: per finger, its sampled postures (S, dof) rad and their fingertips
        (S, 3) m in the forearm frame; ``lift``: per finger, its lifted posture (dof,)."""
        F = len(fingers)
        D = max(f.dof for f in fingers)
        J = max(len(f._dofs) for f in fingers)
        S = len(samples[0][0])
        self.width = D
        self.sites = np.array([f.site for f in fingers])
        self.low, self.high = np.zeros((F, D)), np.zeros((F, D))
        self.dofs = np.zeros((F, J), dtype=int)
        self.mix = np.zeros((F, J, D))
        self.samples, self.tips = np.zeros((F, S, D)), np.empty((F, S, 3))
        self.lift = np.zeros((F, D))
        qpos, source, share = [], [], []
        for f, finger in enumerate(fingers):
            d, j = finger.dof, len(finger._dofs)
            self.low[f, :d], self.high[f, :d] = finger.low, finger.high
            self.dofs[f, :j] = finger._dofs
            self.mix[f, :j, :d] = finger._mix
            self.samples[f, :, :d] = samples[f][0]
            self.tips[f] = samples[f][1]
            self.lift[f, :d] = lift[f]
            qpos.append(finger._qpos)
            source.append(f * D + finger._owner)
            share.append(finger._share)
        self.tip_norms = np.einsum("fsi,fsi->fs", self.tips, self.tips)
        self.qpos, self.source = np.concatenate(qpos), np.concatenate(source)
        self.share = np.concatenate(share)
        # Scratch Jacobians: each finger's fingertip (F, 3, nv), and one finger's (3, nv).
        self.jacs = np.zeros((F, 3, nv))
        self.jacp = np.zeros((3, nv))
        self.nv = nv
        self._subsets: dict[tuple[bytes, bytes, float, float], _Subset] = {}
        self._dampings: dict[float, np.ndarray] = {}

    def subset(
        self,
        active: np.ndarray,
        thumb_lateral_weight: float,
        high: np.ndarray | None = None,
        height_weight: float = 1.0,
    ) -> _Subset:
        """The arrays for the ``active`` (F,) bool fingers, the error in height of the
        ``high`` (F,) bool ones weighted ``height_weight`` (made once per pattern)."""
        raised = np.zeros_like(active) if high is None or height_weight == 1.0 else high
        key = (active.tobytes(), raised.tobytes(), thumb_lateral_weight, height_weight)
        sub = self._subsets.get(key)
        if sub is None:
            sub = self._subsets[key] = _Subset(
                self, np.flatnonzero(active), thumb_lateral_weight, raised, height_weight
            )
        return sub

    def damping(self, value: float) -> np.ndarray:
        """(D, D) ``value`` times the identity (made once per value)."""
        eye = self._dampings.get(value)
        if eye is None:
            eye = self._dampings[value] = value * np.eye(self.width)
        return eye

    def nearest(
        self, fingers: np.ndarray, targets: np.ndarray, weights: np.ndarray | None = None
    ) -> np.ndarray:
        """(k, D) sampled postures whose fingertips are nearest ``targets`` (k, 3), for the
        ``fingers`` (k,) indices; with ``weights`` (k, 3), by the weighted distance of the
        fingers whose weights are not all 1."""
        # |tip - target|^2 less the target's own |target|^2, the same for every sample.
        best = [
            int(np.argmin(self.tip_norms[f] - 2.0 * (self.tips[f] @ target)))
            for f, target in zip(fingers.tolist(), targets, strict=True)
        ]
        if weights is not None:
            for i in np.flatnonzero((weights != 1.0).any(axis=1)).tolist():
                error = (self.tips[fingers[i]] - targets[i]) * weights[i]
                best[i] = int(np.argmin(np.einsum("si,si->s", error, error)))
        return self.samples[fingers, best]

    def set(self, data, angles: np.ndarray) -> None:
        """Write the (F, D) padded angles to their joints in ``data.qpos``."""
        data.qpos[self.qpos] = angles.reshape(-1)[self.source] * self.share


class _Subset:
    """The padded arrays of the k active fingers ``fingers`` (k,) of a :class:`FingerBatch`:
    ``sites`` (k,), ``low``, ``high`` (k, D), ``mix`` (k, J, D), ``weights`` (k, 3) the
    error's weights (the thumb's across the keys: ``thumb_lateral_weight``), ``row_weights``
    (k, 3, 1) the same for the Jacobian's rows, and ``jacobian_index`` (k, 3, J): where each
    finger's joint columns are in the flattened (F, 3, nv) Jacobians."""

    def __init__(
        self,
        b: FingerBatch,
        fingers: np.ndarray,
        thumb_lateral_weight: float,
        raised: np.ndarray,
        height_weight: float,
    ) -> None:
        self.fingers = fingers
        self.pairs = [(int(f), int(b.sites[f])) for f in fingers]
        self.sites = b.sites[fingers]
        self.low, self.high, self.mix = b.low[fingers], b.high[fingers], b.mix[fingers]
        self.weights = np.ones((fingers.size, 3))
        self.weights[fingers == 0, 1] = thumb_lateral_weight
        self.weights[raised[fingers], 2] = height_weight
        # The nearest sample of a raised finger is found by the weighted distance too.
        self.raised_weights = self.weights if raised[fingers].any() else None
        self.row_weights = self.weights[:, :, None]
        rows = (fingers[:, None] * 3 + np.arange(3)[None, :]) * b.nv  # (k, 3)
        self.jacobian_index = rows[:, :, None] + b.dofs[fingers][:, None, :]


def solve_fingers(
    m,
    scratch,
    hand: Hand,
    batch: FingerBatch,
    targets: np.ndarray,
    active: np.ndarray,
    memory: FingerMemory,
    wrist_bent_up: float,
    reach_pose: bool,
    cfg,
) -> np.ndarray:
    """Every finger's joint angles for its fingertip target, set in ``scratch`` too.

    Args:
        m: the model; ``scratch``: an ``MjData`` with the forearm and wrist as commanded
            (the fingers' joints are overwritten).
        hand: the hand's indices; ``batch``: its fingers' postures in the pose in use.
        targets: (5, 3) m fingertip targets relative to the forearm body; ``active`` (5,)
            bool which fingers have one (the others take their lifted posture).
        memory: this step's finger decisions (``pressing``, ``unsounded``, ``repress``,
            ``state``: :func:`~pianist.control.planner.targets.fingertip_targets`).
        wrist_bent_up: rad the keys have bent the wrist up from its pose
            (:func:`~pianist.control.planner.postures.set_wrist`).
        reach_pose: whether the hand is in a reach pose (not the home pose).
    Returns:
        (5, D) rad: each finger's actuator angles, padded to the batch's width (a finger's
        first ``dof`` are its own; :func:`finger_controls` gathers them).
    """
    b = batch
    angles = b.lift.copy()  # (F, D)
    # In a reach pose a hovering finger keeps its height first (``hover_height_weight``).
    weight = cfg.ik.hover_height_weight if reach_pose else 1.0
    sub = b.subset(
        active, cfg.ik.thumb_lateral_weight, memory.state == FingerState.HOVERING, weight
    )
    act = sub.fingers
    if act.size:
        goal = targets[act]
        angles[act] = b.nearest(act, goal, sub.raised_weights)
        damping = b.damping(cfg.ik.damping**2 + cfg.ik.rest_weight)
        limit = cfg.ik.step_limit_rad
        jacs = b.jacs
        flat = jacs.reshape(-1)  # a view: mj_jacSite writes into jacs
    b.set(scratch, angles)
    for _ in range(cfg.ik.iterations if act.size else 0):
        mujoco.mj_kinematics(m, scratch)
        mujoco.mj_comPos(m, scratch)  # mj_jacSite reads cdof and subtree centres
        origin = scratch.xpos[hand.forearm_body]
        error = (goal - (scratch.site_xpos[sub.sites] - origin)) * sub.weights  # (k, 3)
        for f, site in sub.pairs:
            mujoco.mj_jacSite(m, scratch, jacs[f], None, site)
        J = (flat[sub.jacobian_index] @ sub.mix) * sub.row_weights  # (k, 3, D)
        JT = J.transpose(0, 2, 1)
        step = np.linalg.solve(JT @ J + damping, JT @ error[:, :, None])[:, :, 0]
        # np.minimum / np.maximum: np.clip's result at a fraction of its call's cost.
        step = np.minimum(np.maximum(step, -limit), limit)
        angles[act] = np.minimum(np.maximum(angles[act] + step, sub.low), sub.high)
        b.set(scratch, angles)
    # A pressing finger is commanded further along the joint direction that lowers its
    # tip: the position servos' force grows with that error, and a target out of reach
    # (often the thumb's) leaves the IK at the boundary with too little error to push.
    if not act.size or not memory.pressing.any():
        return angles
    mujoco.mj_kinematics(m, scratch)
    mujoco.mj_comPos(m, scratch)
    for f in np.flatnonzero(memory.pressing).tolist():
        finger = hand.fingers[f]
        amount = cfg.ik.thumb_push_rad if f == 0 else cfg.ik.finger_push_rad[f - 1]
        if memory.unsounded[f] >= cfg.ik.unsounded_steps:  # pressing its key, not sounding it
            amount += cfg.ik.unsounded_push_rad
        if memory.repress[f]:  # pressing again the key it let up last step
            amount += cfg.ik.restrike_push_rad[f]
        # The other fingers' keys bend the wrist up and lift this one off its key.
        bent = cfg.ik.reach_bent_wrist_push if reach_pose else cfg.ik.bent_wrist_push
        amount += bent * wrist_bent_up
        mujoco.mj_jacSite(m, scratch, b.jacp, None, finger.site)
        down = -finger.jacobian(b.jacp)[2]
        norm = np.linalg.norm(down)
        if amount > 0 and norm > 0:
            push = angles[f, : finger.dof] + amount * down / norm
            angles[f, : finger.dof] = np.clip(push, finger.low, finger.high)
    return angles


def descent_directions(m, scratch, hand: Hand, fingers: Sequence[int]) -> list[np.ndarray]:
    """Per finger of ``fingers`` (0 thumb .. 4), the unit direction (its ``dof`` actuator
    angles) that lowers its fingertip fastest, at the posture ``scratch`` holds."""
    mujoco.mj_kinematics(m, scratch)
    mujoco.mj_comPos(m, scratch)
    jacp = np.zeros((3, m.nv))
    directions = []
    for f in fingers:
        finger = hand.fingers[f]
        mujoco.mj_jacSite(m, scratch, jacp, None, finger.site)
        down = -finger.jacobian(jacp)[2]
        norm = float(np.linalg.norm(down))
        directions.append(down / norm if norm > 0 else down)
    return directions


def finger_controls(hand: Hand, angles: np.ndarray) -> np.ndarray:
    """The hand's finger commands (rad), thumb to little finger in the order of
    ``hand.finger_actuators``, from :func:`solve_fingers`' padded (5, D) angles."""
    return np.concatenate([angles[f, : finger.dof] for f, finger in enumerate(hand.fingers)])
