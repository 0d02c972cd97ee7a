"""The hand's poses, the sampled postures the IK starts from, and the wrist's command.

A hand plays in one of a few poses (:meth:`PoseConfig.hand_poses`): the home pose (the
wrist straight) and the reach poses (the wrist turned towards the thumb and flexed, which
spans an octave). For every pose, every finger's joints are sampled uniformly within their
limits (``PoseConfig.samples`` postures, always with generator seed 0) with the forearm at
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
  (``reach`` shrunk by ``reach_margin``);
- ``batch``: the samples and lifted postures laid out for the IK
  (:class:`~pianist.control.planner.ik.FingerBatch`).

:func:`hand_poses` makes every hand's poses; the stages that plan and execute are given the
pose they work in. :func:`set_wrist` and :func:`place_forearm` put a hand in a pose.

Inputs: the MuJoCo model, a scratch ``MjData``, the hands' indices, the config.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import scipy.spatial

from pianist.control.planner.config import FINGERS_PER_HAND, PlannerConfig
from pianist.control.planner.hand import Finger, Hand
from pianist.control.planner.ik import FingerBatch
from pianist.sim import constants as C
from pianist.sim.scene import SceneOptions


def _rest_angles(finger: Finger) -> np.ndarray:
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
    batch: FingerBatch
    """The fingers' samples and lifted postures laid out for the IK."""


def make_pose(
    m, data, hand: Hand, pose: tuple[float, ...], cfg: PlannerConfig, samples
) -> HandPose:
    """The lifted posture of each finger, the forearm offsets and the reach of ``hand`` in
    ``pose`` (WRJ2, WRJ1 rad, ty m, raise m) from the fingers' ``samples`` (see
    :class:`HandPose`); ``data`` is scratch."""
    wrist, ty, raise_m = (pose[0], pose[1]), pose[2], pose[3]
    # The lifted posture: the sample nearest the rest posture's fingertip, lifted clear.
    mujoco.mj_resetData(m, data)
    place_forearm(data, hand, ty, raise_m, cfg)
    set_wrist(data, None, hand, wrist, ty, cfg)
    for finger in hand.fingers:
        finger.set(data, _rest_angles(finger))
    mujoco.mj_kinematics(m, data)
    origin = data.xpos[hand.forearm_body].copy()
    lift_z = C.WHITE_KEY_HEIGHT_M + cfg.poses.lift_height_m + C.FINGERTIP_CAPSULE_RADIUS_M
    rest_tips = data.site_xpos[hand.sites] - origin
    lift_tips = rest_tips.copy()
    lift_tips[:, 2] = lift_z - origin[2]
    # Thumb: under the side of the palm, a little more than a key from the index finger.
    side = 1.0 if hand.side == "right" else -1.0
    lift_tips[0, 1] = rest_tips[1, 1] - side * cfg.poses.thumb_offset_m
    lift = [
        postures[int(tree.query(lift_tips[f])[1])] for f, (postures, _, tree) in enumerate(samples)
    ]
    # Forearm slide that puts finger f over a key at y: key y - tip_offset_y[f].
    tip_offset_y = lift_tips[:, 1] + origin[1] - data.qpos[hand.tx_qpos]
    slide = data.qpos[hand.tx_qpos]
    tips = [finger_tips + origin for _, finger_tips, _ in samples]
    return HandPose(
        wrist=wrist,
        ty=ty,
        raise_m=raise_m,
        samples=list(samples),
        lift=lift,
        rest_tips=rest_tips,
        lift_tips=lift_tips,
        tip_offset_y=tip_offset_y,
        reach=_reach(tips, slide, tip_offset_y, cfg.poses.reach_margin, cfg),
        full_reach=_reach(tips, slide, tip_offset_y, 0.0, cfg),
        batch=FingerBatch(hand.fingers, [(p, t) for p, t, _ in samples], lift, m.nv),
    )


def _reach(
    tips: list[np.ndarray],
    slide: float,
    tip_offset_y: np.ndarray,
    margin: float,
    cfg: PlannerConfig,
) -> np.ndarray:
    """(5, 2, 2): per finger, for a white (0) and a black (1) key, the lowest and highest
    key y minus forearm slide at which the finger can press the key.

    From the sampled postures (their fingertips ``tips`` (S, 3) m per finger, world frame)
    whose fingertip is at the key's press point (x) and below its top: the range of their y,
    shrunk by ``margin`` of its width at each end. A finger that never gets there (the thumb
    on a black key) gets its resting offset.
    """
    radius = C.FINGERTIP_CAPSULE_RADIUS_M
    reach = np.repeat(tip_offset_y[:, None, None], 2, axis=1).repeat(2, axis=2)
    for f, finger_tips in enumerate(tips):
        for black in (0, 1):
            if black:
                x = cfg.keys.black_press_x_m
                top = C.WHITE_KEY_HEIGHT_M + C.BLACK_KEY_TOP_ABOVE_WHITE_M
            else:
                x = cfg.keys.thumb_white_press_x_m if f == 0 else cfg.keys.white_press_x_m
                top = C.WHITE_KEY_HEIGHT_M
            ok = (np.abs(finger_tips[:, 0] - x) < cfg.poses.reach_x_tolerance_m) & (
                finger_tips[:, 2] < top + radius - cfg.poses.reach_depth_m
            )
            if ok.sum() >= 10:
                lo, hi = np.percentile(finger_tips[ok, 1] - slide, [1, 99])
                shrink = margin * (hi - lo)
                reach[f, black] = lo + shrink, hi - shrink
    return reach


def place_forearm(data, hand: Hand, ty: float, raise_m: float, cfg: PlannerConfig) -> None:
    """Put the forearm at its playing height raised by ``raise_m`` (m) in ``data`` (when it
    has a height slide), and at ``ty`` (m, when it has that slide)."""
    if hand.tz_qpos is not None:
        data.qpos[hand.tz_qpos] = cfg.forearm.hand_height_m + raise_m
    if hand.ty_qpos is not None:
        data.qpos[hand.ty_qpos] = ty


def set_wrist(
    data,
    ctrl: np.ndarray | None,
    hand: Hand,
    wrist: tuple[float, float],
    ty: float,
    cfg: PlannerConfig,
) -> float:
    """Put the wrist at ``wrist`` (WRJ2, WRJ1 rad) in ``data`` (the fingers are solved for
    it) and, given ``ctrl`` (nu,), command it there (with feedback on how far it is off),
    the forearm's ``ty`` (m) there, and the joints the reduced hand does without to 0.

    Returns:
        How far (rad) the keys have bent the wrist up from ``wrist`` (WRJ1), as measured in
        ``data`` before it is overwritten.
    """
    if ctrl is not None:
        ctrl[hand.held_actuators] = 0.0
        if hand.ty_actuator is not None:
            ctrl[hand.ty_actuator] = ty
    bent_up = 0.0
    for i, ((actuator, qpos), angle, gain) in enumerate(
        zip(hand.wrist, wrist, cfg.poses.wrist_feedback, strict=False)
    ):
        off = float(np.mean(data.qpos[qpos])) - angle
        if i == 1:  # WRJ1, flexion: the keys push it negative (the hand bends up)
            bent_up = max(-off, 0.0)
        data.qpos[qpos] = angle  # the fingers are solved for the wrist at its pose
        if ctrl is not None:
            ctrl[actuator] = angle - gain * off  # a stiffer servo against the swing
    return bent_up


#: Posture samples of every finger, (samples (S, dof), fingertips (S, 3)) per finger, keyed by
#: the scene's options (the model is built from them deterministically), the planner's config
#: and the pose: sampling takes ~0.15 s, most of a short episode's reset, and is the same
#: each time.
_Postures = list[tuple[np.ndarray, np.ndarray, scipy.spatial.cKDTree]]
_POSTURES: dict[tuple[SceneOptions, PlannerConfig, tuple[float, ...]], _Postures] = {}
_POSTURES_KEPT = 24  # scenes x configs x poses kept per process (~2 MB each)


def hand_poses(
    m, data, hands: Sequence[Hand], cfg: PlannerConfig, scene_options: SceneOptions
) -> list[tuple[HandPose, ...]]:
    """Every hand's poses (:meth:`PoseConfig.hand_poses`, the home pose first), each with
    its posture samples (sampled once per scene, config and pose, see :data:`_POSTURES`),
    lifted postures and reach; per hand, in the order of ``hands``. ``data`` is scratch."""
    has_tz = all(hand.tz_qpos is not None for hand in hands)
    poses: list[list[HandPose]] = [[] for _ in hands]
    for pose in cfg.poses.hand_poses(has_tz):
        key = (scene_options, cfg, pose)
        samples = _POSTURES.get(key)
        if samples is None:
            # The samples do not depend on the episode: always the same generator seed.
            samples = _sample_postures(m, data, hands, pose, cfg, np.random.default_rng(0))
            if len(_POSTURES) >= _POSTURES_KEPT:
                del _POSTURES[next(iter(_POSTURES))]
            _POSTURES[key] = samples
        for h, hand in enumerate(hands):
            mine = samples[h * FINGERS_PER_HAND : (h + 1) * FINGERS_PER_HAND]
            poses[h].append(make_pose(m, data, hand, pose, cfg, mine))
    return [tuple(p) for p in poses]


def _sample_postures(
    m,
    data,
    hands: Sequence[Hand],
    pose: tuple[float, ...],
    cfg: PlannerConfig,
    rng: np.random.Generator,
) -> _Postures:
    """Fingertip positions relative to the forearm for random postures of every finger.

    Fingers (and hands) share no joints, so one kinematics pass samples all of them at once;
    the joint positions of every sample are laid out in one array first so that the loop
    only copies a row and runs ``mj_kinematics``. Every hand is in ``pose`` (WRJ2, WRJ1
    rad, ty m, raise m).

    Returns:
        Per finger, right hand then left, thumb..little: postures (S, dof) in rad, fingertips
        (S, 3) in m relative to the forearm body, and a k-d tree over the fingertips; the
        arrays are read only.
    """
    mujoco.mj_resetData(m, data)
    for hand in hands:
        place_forearm(data, hand, pose[2], pose[3], cfg)
        set_wrist(data, None, hand, (pose[0], pose[1]), pose[2], cfg)
    batch = np.tile(data.qpos, (cfg.poses.samples, 1))
    postures = []
    for hand in hands:
        for finger in hand.fingers:
            angles = rng.uniform(finger.low, finger.high, (cfg.poses.samples, finger.dof))
            for i, (qpos, share) in enumerate(zip(finger.qpos, finger.share, strict=True)):
                batch[:, qpos] = angles[:, i : i + 1] * share
            postures.append(angles)
    sites = np.concatenate([hand.sites for hand in hands])
    origins = np.repeat([hand.forearm_body for hand in hands], FINGERS_PER_HAND)
    tips = np.empty((cfg.poses.samples, len(sites), 3))
    for s in range(cfg.poses.samples):
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
