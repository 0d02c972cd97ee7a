"""Each finger's actuated joints, the hand's poses, and the sampled postures the IK starts from.

A hand plays in one of a few poses (:meth:`PlannerConfig.hand_poses`): the home pose (the
wrist straight) and the reach poses (the wrist turned towards the thumb and flexed, which
spans an octave). For every pose, every finger's joints are sampled uniformly within their
limits (``PlannerConfig.samples`` postures, always with generator seed 0) with the forearm at
its playing height and the wrist at the pose, and each sample's fingertip is computed
relative to the forearm body. The samples are made once per scene, config and pose
(:data:`_POSTURES`) and are read only. From them each pose (:class:`HandPose`) takes

- every finger's lifted posture (dof,) rad: the sample whose fingertip is nearest a point
  above its resting place, ``lift_height_m`` clear of the keys;
- ``rest_tips`` and ``lift_tips`` (5, 3) m, fingertips relative to the forearm body;
- ``tip_offset_y`` (5,) m: the forearm slide that puts finger f over a key at y is
  ``y - tip_offset_y[f]``;
- ``reach`` and ``full_reach`` (5, 2, 2) m: per finger, for a white (0) and a black (1) key,
  the lowest and highest key y minus forearm slide from which the finger presses the key
  (``reach`` shrunk by ``reach_margin``).

:meth:`HandPostures.use_pose` binds one pose's arrays to the hand (and its samples and lifted
postures to the fingers): the stages that plan and execute read the pose in use.

Inputs: the MuJoCo model, a scratch ``MjData``, the hands' indices, the config.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import scipy.spatial

from pianist.control.planner.config import FINGERS_PER_HAND, PlannerConfig
from pianist.sim import constants as C
from pianist.sim.scene import SceneOptions


class Finger:
    """The actuated joints of one finger: actuator ids, limits, how to set and differentiate."""

    lift: np.ndarray
    """The lifted posture (dof,), of the pose in use (:meth:`HandPostures.use_pose`)."""

    def __init__(self, m, actuators: list[int], site: int) -> None:
        self.actuators = np.asarray(actuators, dtype=int)
        self.site = site
        self.dof = len(actuators)
        self.qpos = [_actuated_qpos(m, a) for a in actuators]
        self.dofs = [m.jnt_dofadr[_actuated_joints(m, a)] for a in actuators]
        self.share = np.array([1.0 / len(q) for q in self.qpos])  # tendon: split evenly
        self.low, self.high = m.actuator_ctrlrange[self.actuators].T
        self.names = [m.actuator(a).name for a in actuators]
        self.angles = np.zeros(self.dof)
        # Flat index arrays (the IK calls these every iteration): joint j of the finger is
        # driven by actuator owner[j] with a share of its command.
        owner = np.repeat(np.arange(self.dof), [len(q) for q in self.qpos])
        self._qpos, self._owner = np.concatenate(self.qpos), owner
        self._share = self.share[owner]
        self._dofs = np.concatenate(self.dofs)
        self._mix = np.zeros((len(owner), self.dof))  # joint velocities -> actuator space
        self._mix[np.arange(len(owner)), owner] = self._share

    def set(self, data, angles: np.ndarray) -> None:
        data.qpos[self._qpos] = angles[self._owner] * self._share

    def jacobian(self, jacp: np.ndarray) -> np.ndarray:
        """(3, dof) fingertip Jacobian in actuator space from the full (3, nv) one."""
        return jacp[:, self._dofs] @ self._mix

    def index_samples(
        self, samples: np.ndarray, tips: np.ndarray, tree: scipy.spatial.cKDTree
    ) -> None:
        """Keep the sampled postures (S, dof), their fingertips (S, 3) in the forearm frame and
        a k-d tree over the fingertips (all shared between planners: read only)."""
        self.samples, self.sample_tips, self._tree = samples, tips, tree

    def nearest(self, target: np.ndarray) -> int:
        """Index of the sampled posture whose fingertip is closest to ``target`` (forearm frame)."""
        return int(self._tree.query(target)[1])


def _actuated_joints(m, actuator: int) -> np.ndarray:
    if m.actuator_trntype[actuator] == mujoco.mjtTrn.mjTRN_TENDON:
        tendon = m.actuator_trnid[actuator, 0]
        start, count = m.tendon_adr[tendon], m.tendon_num[tendon]
        return m.wrap_objid[start : start + count]
    return np.array([m.actuator_trnid[actuator, 0]])


def _actuated_qpos(m, actuator: int) -> np.ndarray:
    return m.jnt_qposadr[_actuated_joints(m, actuator)]


def _rest_angles(m, finger: Finger) -> np.ndarray:
    """A relaxed playing posture: knuckles bent a little, fingertips pointing down."""
    angles = np.zeros(finger.dof)
    for i, name in enumerate(finger.names):
        if name.endswith("J3") and "TH" not in name:
            angles[i] = 0.6
        elif name.endswith("J0"):
            angles[i] = 1.0
    return np.clip(angles, finger.low, finger.high)


@dataclass(frozen=True)
class HandPose:
    """One pose of a hand (wrist angles, the forearm's ``ty`` and height) and what its fingers do
    in it."""

    wrist: tuple[float, float]
    """WRJ2 (sideways; negative turns the hand towards its thumb) and WRJ1 (flexion), rad."""
    ty: float
    """The forearm's slide into the keys (m; 0 where the scene has none)."""
    raise_m: float
    """The forearm raised above its playing height (m; where the scene has the slide)."""
    samples: list[tuple[np.ndarray, np.ndarray, scipy.spatial.cKDTree]]
    """Per finger, thumb first: sampled postures (S, dof) rad, their fingertips (S, 3) m in
    the forearm frame, and a k-d tree over those (read only, shared between planners)."""
    lift: list[np.ndarray]
    """Per finger, its lifted posture (dof,) rad."""
    rest_tips: np.ndarray
    """(5, 3) m: fingertips of the resting posture relative to the forearm body."""
    lift_tips: np.ndarray
    """(5, 3) m: the lifted fingertips, ``lift_height_m`` clear of the keys."""
    tip_offset_y: np.ndarray
    """(5,) m: the forearm slide that puts finger f over a key at y is y - tip_offset_y[f]."""
    reach: np.ndarray
    """(5, 2, 2) m: per finger, white (0) / black (1) key, the lowest and highest key y
    minus forearm slide from which the finger presses the key, shrunk by ``reach_margin``."""
    full_reach: np.ndarray
    """(5, 2, 2) m: the same, not shrunk."""


class HandPostures:
    """A hand's poses (the home pose and the reach poses), with each pose's posture samples,
    lifted postures and reach; the pose in use is bound to the hand (:meth:`use_pose`)."""

    # Set by ``Hand.__init__``.
    side: str
    sites: np.ndarray
    forearm_body: int
    tx_qpos: int
    tz_qpos: int | None
    ty_qpos: int | None
    ty_actuator: int | None
    fingers: list[Finger]
    held_actuators: np.ndarray
    wrist: list[tuple[int, np.ndarray]]
    # Set here.
    poses: list[HandPose]
    """Every pose the hand may take, the home pose first (:meth:`PlannerConfig.hand_poses`)."""
    pose_index: int
    """The pose in use (index into ``poses``): its arrays below, and its samples and lifted
    postures in ``fingers``."""
    wrist_angles: tuple[float, float]
    pose_ty: float
    pose_raise: float
    wrist_bent_up: float
    """How far (rad) the keys have bent the wrist up from its pose, measured each step."""
    rest_tips: np.ndarray
    lift_tips: np.ndarray
    tip_offset_y: np.ndarray
    reach: np.ndarray
    full_reach: np.ndarray

    def use_pose(self, index: int) -> None:
        """Bind pose ``index``'s wrist angles, samples, lifted postures and reach to the hand."""
        if getattr(self, "pose_index", None) == index:  # (none bound before the first call)
            return
        pose = self.poses[index]
        self.pose_index = index
        self.wrist_angles, self.pose_ty, self.pose_raise = pose.wrist, pose.ty, pose.raise_m
        for finger, samples, lift in zip(self.fingers, pose.samples, pose.lift, strict=True):
            finger.index_samples(*samples)
            finger.lift = lift
        self.rest_tips, self.lift_tips = pose.rest_tips, pose.lift_tips
        self.tip_offset_y = pose.tip_offset_y
        self.reach, self.full_reach = pose.reach, pose.full_reach

    def make_pose(self, m, data, cfg: PlannerConfig, samples) -> HandPose:
        """The lifted posture of each finger, the forearm offsets and the reach at the pose
        ``wrist_angles`` / ``pose_ty``, from the fingers' ``samples`` (see :class:`HandPose`)."""
        for finger, sample in zip(self.fingers, samples, strict=True):
            finger.index_samples(*sample)
        # The lifted posture: the sample nearest the rest posture's fingertip, lifted clear.
        mujoco.mj_resetData(m, data)
        self.lower(data, cfg)
        self.set_wrist(data, None, cfg)
        rest = [_rest_angles(m, f) for f in self.fingers]
        for finger, angles in zip(self.fingers, rest, strict=True):
            finger.set(data, angles)
        mujoco.mj_kinematics(m, data)
        origin = data.xpos[self.forearm_body].copy()
        lift_z = C.WHITE_KEY_HEIGHT_M + cfg.lift_height_m + C.FINGERTIP_CAPSULE_RADIUS_M
        rest_tips = data.site_xpos[self.sites] - origin
        lift_tips = rest_tips.copy()
        lift_tips[:, 2] = lift_z - origin[2]
        # Thumb: under the side of the palm, a little more than a key from the index finger.
        side = 1.0 if self.side == "right" else -1.0
        lift_tips[0, 1] = rest_tips[1, 1] - side * cfg.thumb_offset_m
        lift = [
            finger.samples[finger.nearest(lift_tips[f])] for f, finger in enumerate(self.fingers)
        ]
        # Forearm slide that puts finger f over a key at y: key y - tip_offset_y[f].
        tip_offset_y = lift_tips[:, 1] + origin[1] - data.qpos[self.tx_qpos]
        slide = data.qpos[self.tx_qpos]
        return HandPose(
            wrist=self.wrist_angles,
            ty=self.pose_ty,
            raise_m=self.pose_raise,
            samples=list(samples),
            lift=lift,
            rest_tips=rest_tips,
            lift_tips=lift_tips,
            tip_offset_y=tip_offset_y,
            reach=self._reach(origin, slide, tip_offset_y, cfg.reach_margin, cfg),
            full_reach=self._reach(origin, slide, tip_offset_y, 0.0, cfg),
        )

    def _reach(
        self,
        origin: np.ndarray,
        slide: float,
        tip_offset_y: np.ndarray,
        margin: float,
        cfg: PlannerConfig,
    ) -> np.ndarray:
        """(5, 2, 2): per finger, for a white (0) and a black (1) key, the lowest and highest
        key y minus forearm slide at which the finger can press the key.

        From the sampled postures whose fingertip is at the key's press point (x) and below
        its top: the range of their y, shrunk by ``reach_margin`` of its width at each end.
        A finger that never gets there (the thumb on a black key) gets its resting offset.
        """
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        reach = np.repeat(tip_offset_y[:, None, None], 2, axis=1).repeat(2, axis=2)
        for f, finger in enumerate(self.fingers):
            tips = finger.sample_tips + origin
            for black in (0, 1):
                if black:
                    x = cfg.black_press_x_m
                    top = C.WHITE_KEY_HEIGHT_M + C.BLACK_KEY_TOP_ABOVE_WHITE_M
                else:
                    x = cfg.thumb_white_press_x_m if f == 0 else cfg.white_press_x_m
                    top = C.WHITE_KEY_HEIGHT_M
                ok = (np.abs(tips[:, 0] - x) < cfg.reach_x_tolerance_m) & (
                    tips[:, 2] < top + radius - cfg.reach_depth_m
                )
                if ok.sum() >= 10:
                    lo, hi = np.percentile(tips[ok, 1] - slide, [1, 99])
                    shrink = margin * (hi - lo)
                    reach[f, black] = lo + shrink, hi - shrink
        return reach

    def lower(self, data, cfg: PlannerConfig) -> None:
        """Put the forearm at its playing height (raised by the pose's) in ``data`` (when it
        has a height slide), and at the pose's ``ty`` (when it has that slide)."""
        if self.tz_qpos is not None:
            data.qpos[self.tz_qpos] = cfg.hand_height_m + self.pose_raise
        if self.ty_qpos is not None:
            data.qpos[self.ty_qpos] = self.pose_ty

    def set_wrist(self, data, ctrl: np.ndarray | None, cfg: PlannerConfig) -> None:
        """Put the wrist at the pose's angles in ``data`` (the fingers are solved for it)
        and, given ``ctrl`` (nu,), command it there (with feedback on how far it is off),
        the forearm's ``ty`` to the pose's, and the joints the reduced hand does without
        to 0."""
        if ctrl is not None:
            ctrl[self.held_actuators] = 0.0
            if self.ty_actuator is not None:
                ctrl[self.ty_actuator] = self.pose_ty
        self.wrist_bent_up = 0.0
        for i, ((actuator, qpos), angle, gain) in enumerate(
            zip(self.wrist, self.wrist_angles, cfg.wrist_feedback, strict=False)
        ):
            off = float(np.mean(data.qpos[qpos])) - angle
            if i == 1:  # WRJ1, flexion: the keys push it negative (the hand bends up)
                self.wrist_bent_up = max(-off, 0.0)
            data.qpos[qpos] = angle  # the fingers are solved for the wrist at its pose
            if ctrl is not None:
                ctrl[actuator] = angle - gain * off  # a stiffer servo against the swing


#: Posture samples of every finger, (samples (S, dof), fingertips (S, 3)) per finger, keyed by
#: the scene's options (the model is built from them deterministically), the planner's config
#: and the pose: sampling takes ~0.15 s, most of a short episode's reset, and is the same
#: each time.
_Postures = list[tuple[np.ndarray, np.ndarray, scipy.spatial.cKDTree]]
_POSTURES: dict[tuple[SceneOptions, PlannerConfig, tuple[float, ...]], _Postures] = {}
_POSTURES_KEPT = 24  # scenes x configs x poses kept per process (~2 MB each)


def _use_postures(
    m, data, hands: Sequence[HandPostures], cfg: PlannerConfig, scene_options: SceneOptions
) -> None:
    """Give every hand its poses (:meth:`PlannerConfig.hand_poses`), each with its posture
    samples (sampled once per scene, config and pose, see :data:`_POSTURES`), lifted
    postures and reach, and put it in its home pose."""
    has_tz = all(hand.tz_qpos is not None for hand in hands)
    for hand in hands:
        hand.poses = []
        hand.__dict__.pop("pose_index", None)
    for pose in cfg.hand_poses(has_tz):
        for hand in hands:
            hand.wrist_angles, hand.pose_ty, hand.pose_raise = (pose[0], pose[1]), *pose[2:]
        key = (scene_options, cfg, pose)
        samples = _POSTURES.get(key)
        if samples is None:
            # The samples do not depend on the episode: always the same generator seed.
            samples = _sample_postures(m, data, hands, cfg, np.random.default_rng(0))
            if len(_POSTURES) >= _POSTURES_KEPT:
                del _POSTURES[next(iter(_POSTURES))]
            _POSTURES[key] = samples
        for h, hand in enumerate(hands):
            mine = samples[h * FINGERS_PER_HAND : (h + 1) * FINGERS_PER_HAND]
            hand.poses.append(hand.make_pose(m, data, cfg, mine))
    for hand in hands:
        hand.use_pose(0)


def _sample_postures(
    m, data, hands: Sequence[HandPostures], cfg: PlannerConfig, rng: np.random.Generator
) -> _Postures:
    """Fingertip positions relative to the forearm for random postures of every finger.

    Fingers (and hands) share no joints, so one kinematics pass samples all of them at once;
    the joint positions of every sample are laid out in one array first so that the loop
    only copies a row and runs ``mj_kinematics``.

    Returns:
        Per finger, right hand then left, thumb..little: postures (S, dof) in rad, fingertips
        (S, 3) in m relative to the forearm body, and a k-d tree over the fingertips; the
        arrays are read only.
    """
    mujoco.mj_resetData(m, data)
    for hand in hands:
        hand.lower(data, cfg)
        hand.set_wrist(data, None, cfg)
    batch = np.tile(data.qpos, (cfg.samples, 1))
    postures = []
    for hand in hands:
        for finger in hand.fingers:
            angles = rng.uniform(finger.low, finger.high, (cfg.samples, finger.dof))
            for i, (qpos, share) in enumerate(zip(finger.qpos, finger.share, strict=True)):
                batch[:, qpos] = angles[:, i : i + 1] * share
            postures.append(angles)
    sites = np.concatenate([hand.sites for hand in hands])
    origins = np.repeat([hand.forearm_body for hand in hands], FINGERS_PER_HAND)
    tips = np.empty((cfg.samples, len(sites), 3))
    for s in range(cfg.samples):
        data.qpos[:] = batch[s]
        mujoco.mj_kinematics(m, data)
        tips[s] = data.site_xpos[sites] - data.xpos[origins]
    out = []
    for i, angles in enumerate(postures):
        finger_tips = tips[:, i].copy()  # not a view of this call's scratch array
        angles.setflags(write=False)
        finger_tips.setflags(write=False)
        out.append((angles, finger_tips, scipy.spatial.cKDTree(finger_tips)))
    return out
