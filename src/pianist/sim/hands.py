"""The two Shadow Dexterous Hands (MuJoCo Menagerie E3M5), loaded and adapted with MjSpec.

The Menagerie model is shipped unchanged in ``assets/shadow_hand`` with its Apache-2.0 licence;
every change for the piano (fingertip sites, forearm slides, reduced action space, capsule
fingertips, gravity compensation, contact filtering) is made here on the loaded spec.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from typing import Literal

import mujoco
import numpy as np

from pianist.sim import constants as C

Side = Literal["right", "left"]

# Contact bits (contype/conaffinity). Bit 0 is the piano's; every hand geom that may touch a key
# carries it in contype. Each hand has its own bit for self-contacts, and takes the other hand's
# bit in conaffinity only when hand-hand collisions are on.
PIANO_BIT = 1
HAND_BIT: dict[str, int] = {"right": 2, "left": 4}

FOREARM_DOFS = ("tx", "ty", "tz", "roll", "pitch", "yaw")
DEFAULT_FOREARM_DOFS = ("tx", "ty")

# Rotate the Menagerie hand (fingers along +x, palm towards +z) by pi about y so that the
# fingers point into the keys (-x) with the palm facing down.
_HAND_FRAME_QUAT = (0.0, 0.0, 1.0, 0.0)
_MENAGERIE_PREFIX = {"right": "rh_", "left": "lh_"}


@dataclass(frozen=True)
class HandOptions:
    """How each hand is built. Defaults are the paper's training setup."""

    reduced_action_space: bool = True
    """Remove THJ5, THJ1 and LFJ5 and narrow THJ2 to [0, 0.698] rad (19 actuators a hand)."""
    primitive_fingertip_collisions: bool = True
    """Collide with capsules instead of the distal phalanx meshes."""
    gravity_compensation: bool = True
    """Cancel gravity on every hand body."""
    hand_collisions: bool = True
    """Let the two hands (and forearms) collide with each other."""
    forearm_dofs: tuple[str, ...] = DEFAULT_FOREARM_DOFS
    """Forearm joints among tx (along the keyboard), ty (into the keys), tz, roll, pitch, yaw."""

    def __post_init__(self) -> None:
        unknown = set(self.forearm_dofs) - set(FOREARM_DOFS)
        if unknown:
            raise ValueError(f"unknown forearm DoFs {sorted(unknown)}; choose from {FOREARM_DOFS}")
        if len(set(self.forearm_dofs)) != len(self.forearm_dofs):
            raise ValueError(f"repeated forearm DoF in {self.forearm_dofs}")


def hand_asset_dir() -> resources.abc.Traversable:
    """Folder holding the shipped Menagerie Shadow hand model."""
    return resources.files("pianist.sim") / "assets" / "shadow_hand"


def load_hand_spec(side: Side) -> mujoco.MjSpec:
    """The unmodified Menagerie spec of one hand."""
    path = hand_asset_dir() / f"{side}_hand.xml"
    spec = mujoco.MjSpec.from_file(str(path))
    return spec


def is_fingertip_body(name: str) -> bool:
    return name.endswith("distal")


def _prepare_hand(spec: mujoco.MjSpec, side: Side, opts: HandOptions) -> None:
    """Apply the piano-specific changes to one hand's own spec (before attaching)."""
    p = _MENAGERIE_PREFIX[side]
    if opts.reduced_action_space:
        for joint in C.REDUCED_REMOVED_JOINTS:
            for act in list(spec.actuators):
                if act.target == p + joint:
                    spec.delete(act)
            spec.delete(spec.joint(p + joint))
        thj2 = next(a for a in spec.actuators if a.target == p + "THJ2")
        thj2.ctrlrange = C.REDUCED_THJ2_RANGE_RAD

    own, other = HAND_BIT[side], HAND_BIT["left" if side == "right" else "right"]
    for geom in spec.geoms:
        if geom.contype == 0 and geom.conaffinity == 0:
            continue  # visual only
        geom.contype = PIANO_BIT | own
        geom.conaffinity = own | (other if opts.hand_collisions else 0)

    for finger in C.FINGER_NAMES:
        distal = spec.body(f"{p}{finger}distal")
        distal.add_site(
            name=f"{finger}tip",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=(0.004, 0, 0),
            pos=(0, 0, C.FINGERTIP_SITE_OFFSET_M[finger]),
            rgba=(0.9, 0.2, 0.2, 1.0),
            group=4,
        )
        if opts.primitive_fingertip_collisions:
            mesh_geom = next(
                g
                for g in distal.geoms
                if g.type == mujoco.mjtGeom.mjGEOM_MESH and (g.contype or g.conaffinity)
            )
            distal.add_geom(
                name=f"{finger}tip_capsule",
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                size=(C.FINGERTIP_CAPSULE_RADIUS_M, C.FINGERTIP_CAPSULE_HALF_LENGTH_M, 0),
                pos=(0, 0, C.FINGERTIP_CAPSULE_CENTRE_M),
                contype=mesh_geom.contype,
                conaffinity=mesh_geom.conaffinity,
                solimp=mesh_geom.solimp,
                solref=mesh_geom.solref,
                group=3,
                rgba=(0.5, 0.5, 0.5, 1.0),
            )
            spec.delete(mesh_geom)

    if opts.gravity_compensation:
        for body in spec.bodies:
            if body.name:  # every body but the world
                body.gravcomp = 1.0

    # Drop the Menagerie's own rh_/lh_ so that attaching with the prefix rh/ or lh/ gives
    # readable names (rh/FFJ3, rh/A_FFJ3, rh/fftip).
    # References by name (actuator targets, contact excludes) must follow the renaming.
    def strip(name: str) -> str:
        return name[len(p) :] if name.startswith(p) else name

    for act in spec.actuators:
        act.target = strip(act.target)
    for exclude in spec.excludes:
        exclude.bodyname1 = strip(exclude.bodyname1)
        exclude.bodyname2 = strip(exclude.bodyname2)
    # Tendon paths resolve joints by name at compile time too: rebuild the coupling tendons.
    for tendon in list(spec.tendons):
        name = strip(tendon.name)
        path = [(strip(w.target.name), w.coef) for w in tendon.path]
        spec.delete(tendon)
        rebuilt = spec.add_tendon(name=name)
        for joint_name, coef in path:
            rebuilt.wrap_joint(joint_name, coef)
    for element in (
        *spec.bodies,
        *spec.joints,
        *spec.actuators,
        *spec.tendons,
        *spec.geoms,
        *spec.sites,
    ):
        element.name = strip(element.name)


def attach_hand(spec: mujoco.MjSpec, side: Side, opts: HandOptions) -> mujoco.MjsBody:
    """Attach one prepared hand to ``spec`` and add its forearm joints and actuators.

    Every name of the hand gets the prefix ``rh/`` or ``lh/`` (``rh/FFJ3``, ``rh/A_FFJ3``,
    ``rh/fftip``); the forearm joints are ``rh/forearm_tx`` and so on, with actuators
    ``rh/A_forearm_tx``. Returns the hand's forearm (root) body.
    """
    hand = load_hand_spec(side)
    _prepare_hand(hand, side, opts)
    p = C.HAND_PREFIX[side]
    frame = spec.worldbody.add_frame(pos=C.FOREARM_ROOT_POS_M[side], quat=_HAND_FRAME_QUAT)
    spec.attach(hand, prefix=p, frame=frame)
    forearm = spec.body(f"{p}forearm")
    _add_forearm_dofs(spec, forearm, side, opts.forearm_dofs)
    return forearm


def _add_forearm_dofs(
    spec: mujoco.MjSpec, forearm: mujoco.MjsBody, side: Side, dofs: tuple[str, ...]
) -> None:
    p = C.HAND_PREFIX[side]
    root_y = C.FOREARM_ROOT_POS_M[side][1]
    half_keyboard = C.KEYBOARD_LENGTH_M / 2
    # Joint axes are given in the forearm's own frame: express world directions in it.
    world_to_local = _forearm_rotation(forearm).T
    specs = {
        # Along the keyboard: the hand's root may reach either end of the keyboard.
        "tx": (
            "slide",
            (0, 1, 0),
            (-half_keyboard - root_y, half_keyboard - root_y),
            C.FOREARM_SLIDE_KP,
        ),
        "ty": ("slide", (-1, 0, 0), C.FOREARM_INTO_KEYS_RANGE_M, C.FOREARM_SLIDE_KP),
        "tz": ("slide", (0, 0, 1), C.FOREARM_TZ_RANGE_M, C.FOREARM_TZ_KP),
        "roll": ("hinge", (-1, 0, 0), C.FOREARM_ROLL_RANGE_RAD, C.FOREARM_ROTATION_KP),
        "pitch": ("hinge", (0, 1, 0), C.FOREARM_PITCH_RANGE_RAD, C.FOREARM_ROTATION_KP),
        "yaw": ("hinge", (0, 0, 1), C.FOREARM_YAW_RANGE_RAD, C.FOREARM_ROTATION_KP),
    }
    for dof in FOREARM_DOFS:  # a fixed order, whatever the order asked for
        if dof not in dofs:
            continue
        kind, axis, rng, kp = specs[dof]
        name = f"{p}forearm_{dof}"
        forearm.add_joint(
            name=name,
            type=mujoco.mjtJoint.mjJNT_SLIDE if kind == "slide" else mujoco.mjtJoint.mjJNT_HINGE,
            axis=world_to_local @ np.array(axis, dtype=float),
            range=rng,
            limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        )
        act = spec.add_actuator(name=f"{p}A_forearm_{dof}", target=name)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        # Critically damped servo: kv = 2 sqrt(kp * reflected inertia), computed at compile time.
        act.set_to_position(kp=kp, dampratio=1.0)
        act.ctrlrange = rng
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE


def _forearm_rotation(forearm: mujoco.MjsBody) -> np.ndarray:
    """World rotation of the forearm body (3, 3) from its frame and own quaternion."""
    mat_frame = np.zeros(9)
    mujoco.mju_quat2Mat(mat_frame, np.array(_HAND_FRAME_QUAT))
    mat_body = np.zeros(9)
    quat = np.array(forearm.quat, dtype=float)
    mujoco.mju_quat2Mat(mat_body, quat / np.linalg.norm(quat))
    return mat_frame.reshape(3, 3) @ mat_body.reshape(3, 3)
