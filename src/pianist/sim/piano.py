"""The 88-key piano, built with ``mujoco.MjSpec`` from :mod:`pianist.sim.constants`.

Every key is a body ``key_{i}`` holding a hinge joint, a box geom and a target site that all
share the name ``key_{i}`` (i = 0 for A0 .. 87 for C8), so a key is addressed by its index.
"""

from __future__ import annotations

import mujoco
import numpy as np

from pianist.sim import constants as C

WHITE_RGBA = (0.95, 0.95, 0.93, 1.0)
BLACK_RGBA = (0.08, 0.08, 0.08, 1.0)
BASE_RGBA = (0.15, 0.15, 0.15, 1.0)

# Keys only collide with the hands: contype 0 means two keys (or a key and the base) never
# generate a contact, conaffinity bit 0 lets any geom whose contype has bit 0 touch them.
PIANO_CONTYPE = 0
PIANO_CONAFFINITY = 1


def key_name(key: int) -> str:
    """Name shared by the body, joint, geom and site of key ``key`` (0-87)."""
    return f"key_{key}"


def add_piano(spec: mujoco.MjSpec, parent: mujoco.MjsBody | None = None) -> mujoco.MjsBody:
    """Add the piano (base and 88 hinged keys) to ``spec`` and return its root body."""
    parent = parent if parent is not None else spec.worldbody
    piano = parent.add_body(name="piano")
    piano.add_geom(
        name="piano_base",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=np.array(C.BASE_SIZE_M) / 2,
        pos=C.BASE_CENTRE_M,
        rgba=BASE_RGBA,
        contype=PIANO_CONTYPE,
        conaffinity=PIANO_CONAFFINITY,
    )
    centre_y = C.key_centre_y()
    for key in range(C.NUM_KEYS):
        _add_key(piano, key, float(centre_y[key]))
    return piano


def _add_key(piano: mujoco.MjsBody, key: int, centre_y: float) -> None:
    black = C.is_black_key(key)
    if black:
        length, width, height = C.BLACK_KEY_LENGTH_M, C.BLACK_KEY_WIDTH_M, C.BLACK_KEY_HEIGHT_M
        centre = (C.BLACK_KEY_CENTRE_X_M, centre_y, C.BLACK_KEY_CENTRE_Z_M)
        mass, max_angle, rgba = C.BLACK_KEY_MASS_KG, C.BLACK_KEY_MAX_ANGLE_RAD, BLACK_RGBA
    else:
        length, width, height = C.WHITE_KEY_LENGTH_M, C.WHITE_KEY_WIDTH_M, C.WHITE_KEY_HEIGHT_M
        centre = (C.WHITE_KEY_CENTRE_X_M, centre_y, C.WHITE_KEY_CENTRE_Z_M)
        mass, max_angle, rgba = C.WHITE_KEY_MASS_KG, C.WHITE_KEY_MAX_ANGLE_RAD, WHITE_RGBA
    half = np.array([length, width, height]) / 2
    name = key_name(key)

    body = piano.add_body(name=name, pos=centre)
    body.mass = mass
    # Box inertia about the centre of mass.
    body.inertia = (
        mass
        / 3
        * np.array(
            [half[1] ** 2 + half[2] ** 2, half[0] ** 2 + half[2] ** 2, half[0] ** 2 + half[1] ** 2]
        )
    )
    body.explicitinertial = True
    # Rotating about +y by a positive angle moves the front (+x) end of the key down.
    body.add_joint(
        name=name,
        type=mujoco.mjtJoint.mjJNT_HINGE,
        axis=(0, 1, 0),
        pos=(-half[0], 0, 0),
        range=(0.0, max_angle),
        limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        stiffness=C.KEY_SPRING_STIFFNESS_NM_PER_RAD,
        springref=C.KEY_SPRING_REF_RAD,
        damping=C.KEY_DAMPING_NMS_PER_RAD,
        armature=C.KEY_ARMATURE_KGM2,
    )
    body.add_geom(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=half,
        rgba=rgba,
        contype=PIANO_CONTYPE,
        conaffinity=PIANO_CONAFFINITY,
        solref=C.KEY_SOLREF,
    )
    # Where a fingertip should strike: towards the player along the key, up from the centre.
    body.add_site(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=(0.002, 0, 0),
        pos=(C.KEY_TARGET_FORWARD_FRACTION * half[0], 0, half[2] / 2),
        rgba=(1, 0, 0, 0),
        group=4,
    )
