"""The video's stage: the ``auto`` camera framed on what an episode plays, lights, colours, floor.

Everything here changes only a *copy* of the model that the video renders (and the renderer's
scene), never the environment's model, so the physics of the scene stays exactly as it is.

The ``auto`` camera looks at the keyboard from the player's side (+x), above the forearms, tilted
down by :data:`AUTO_PITCH_RAD`, with no roll, so low keys are on the left as a pianist sees them.
Its position is the closest one from which every given point (the hands' bodies at every step,
the corners of the keys the episode asks for or plays) lies inside the frame with a margin: a
small linear problem solved in closed form by :func:`frame_points`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Downward tilt of the auto camera below the horizontal: steep enough to see the keys between
#: the fingers and in front of the palms, shallow enough to see the fingers' bend.
AUTO_PITCH_RAD = math.radians(55.0)
#: Fraction of each half-frame kept free around the framed points.
AUTO_MARGIN = 0.06
#: The narrowest keyboard span the auto camera frames (m): about two octaves, so a one-hand
#: song is not seen through a magnifying glass.
AUTO_MIN_SPAN_M = 0.40

# Colours of the stage: hands a light blue-grey (the hand's own dark material disappears
# against black keys and the dark base), on a warm light floor, so the hands and the white keys
# stand out from the background and from each other.
HAND_RGBA = {
    "black": (0.42, 0.50, 0.62, 1.0),  # most of the hand's shells
    "gray": (0.78, 0.80, 0.84, 1.0),
    "metallic": (0.86, 0.87, 0.90, 1.0),
}
FLOOR_RGBA = (0.86, 0.83, 0.77, 1.0)
FLOOR_Z_M = -0.02  # just under the piano's base (whose bottom is at z = 0)
FLOOR_HALF_SIZE_M = 3.0


def look_axes(pitch_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The auto camera's axes: (right, up, forward) unit vectors in world coordinates.

    The camera faces -x (from the player's seat towards the piano), tilted down by
    ``pitch_rad``; right is +y (towards the high keys).
    """
    forward = np.array([-math.cos(pitch_rad), 0.0, -math.sin(pitch_rad)])
    right = np.array([0.0, 1.0, 0.0])
    up = np.cross(right, forward)
    return right, up, forward


def frame_points(
    points: np.ndarray,
    *,
    pitch_rad: float = AUTO_PITCH_RAD,
    fovy_rad: float = math.radians(45.0),
    aspect: float = 4 / 3,
    margin: float = AUTO_MARGIN,
) -> tuple[np.ndarray, np.ndarray]:
    """The closest camera pose, facing as :func:`look_axes`, that sees every point.

    In camera coordinates a point p seen from position c has depth z = f.(p - c), and is in
    the frame when |r.(p - c)| <= tx z and |u.(p - c)| <= ty z, with tx, ty the tangents of
    the half field of view shrunk by ``margin``. With c written as a r + b u + e f these are
    linear in (a, b, e): the largest e (closest camera) is the smaller of the horizontal and
    vertical bounds below, and a, b are then centred in their feasible intervals.

    Args:
        points: (N, 3) world points, N >= 1, metres.
        pitch_rad: downward tilt, radians in (0, pi/2).
        fovy_rad: vertical field of view, radians.
        aspect: frame width / height.
        margin: fraction of each half-frame left free, in [0, 1).
    Returns:
        (pos, xyaxes): the camera position (3,) and MuJoCo's xyaxes (6,) (right, then up).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    right, up, forward = look_axes(pitch_rad)
    ty = math.tan(fovy_rad / 2) * (1.0 - margin)
    tx = math.tan(fovy_rad / 2) * aspect * (1.0 - margin)
    pr, pu, pf = points @ right, points @ up, points @ forward
    # Horizontal: pr - a <= tx (pf - e) and a - pr <= tx (pf - e) for every point.
    e_x = (np.min(pr + tx * pf) - np.max(pr - tx * pf)) / (2 * tx)
    e_y = (np.min(pu + ty * pf) - np.max(pu - ty * pf)) / (2 * ty)
    e = min(e_x, e_y)
    a = (np.max(pr - tx * (pf - e)) + np.min(pr + tx * (pf - e))) / 2
    b = (np.max(pu - ty * (pf - e)) + np.min(pu + ty * (pf - e))) / 2
    pos = a * right + b * up + e * forward
    return pos, np.concatenate([right, up])


def project(
    points: np.ndarray, pos: np.ndarray, xyaxes: np.ndarray, fovy_rad: float, size: tuple[int, int]
) -> np.ndarray:
    """Pixel coordinates of world points seen by a pinhole camera (MuJoCo's conventions).

    Args:
        points: (N, 3) world points.
        pos: (3,) camera position; xyaxes: (6,) its right and up axes (it looks along -z).
        fovy_rad: vertical field of view.
        size: (height, width) of the image in pixels.
    Returns:
        (N, 3): column, row (from the top-left corner, pixels) and depth (m, > 0 in front).
    """
    height, width = size
    right, up = np.asarray(xyaxes[:3], float), np.asarray(xyaxes[3:], float)
    forward = np.cross(up, right)  # the camera looks along -z = -(right x up)
    rel = np.asarray(points, dtype=np.float64).reshape(-1, 3) - np.asarray(pos, float)
    depth = rel @ forward
    focal = height / 2 / math.tan(fovy_rad / 2)
    col = width / 2 + focal * (rel @ right) / depth
    row = height / 2 - focal * (rel @ up) / depth
    return np.stack([col, row, depth], axis=1)


def auto_camera_points(
    model: Any, data: Any, qpos: np.ndarray, hand_bodies: np.ndarray, key_geoms: np.ndarray
) -> np.ndarray:
    """The points the auto camera must see: hands at every step and the given keys' corners.

    Args:
        model, data: a MuJoCo model and a scratch ``MjData`` (its qpos is overwritten).
        qpos: (T + 1, nq) the episode's joint positions.
        hand_bodies: body ids of the hands (forearms left out: they reach towards the camera,
            and a pianist's view shows them cut by the frame's lower edge too).
        key_geoms: geom ids of the keys the episode asks for or plays (may be empty).
    Returns:
        (N, 3) world points, metres.
    """
    import mujoco

    chunks = []
    # Every step (kinematics costs ~0.1 ms a step): a hand can cross the frame's edge briefly.
    for row in np.asarray(qpos):
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        chunks.append(data.xpos[hand_bodies].copy())
    mujoco.mj_kinematics(model, data)
    for geom in np.asarray(key_geoms, dtype=int):
        half = model.geom_size[geom]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = corners * half
        chunks.append(data.geom_xpos[geom] + local @ data.geom_xmat[geom].reshape(3, 3).T)
    points = np.concatenate(chunks) if chunks else np.zeros((1, 3))
    # Widen a narrow span along the keyboard (y) symmetrically to the minimum.
    low, high = points[:, 1].min(), points[:, 1].max()
    if high - low < AUTO_MIN_SPAN_M:
        mid = (low + high) / 2
        extra = points[[0, 0]].copy()
        extra[:, 1] = (mid - AUTO_MIN_SPAN_M / 2, mid + AUTO_MIN_SPAN_M / 2)
        points = np.concatenate([points, extra])
    return points


def style_model(model: Any) -> None:
    """Recolour the hands and brighten the lights of a render-only model copy, in place."""
    for mat in range(model.nmat):
        name = model.mat(mat).name.split("/")[-1]
        if name in HAND_RGBA:
            model.mat_rgba[mat] = HAND_RGBA[name]
            model.mat_specular[mat] = 0.3
            model.mat_shininess[mat] = 0.3
    # A soft headlight fills the shadows the overhead light leaves on the palms and fingers.
    model.vis.headlight.ambient[:] = (0.35, 0.35, 0.35)
    model.vis.headlight.diffuse[:] = (0.45, 0.45, 0.45)
    model.vis.headlight.specular[:] = (0.1, 0.1, 0.1)
    model.light_diffuse[:] = (0.55, 0.55, 0.55)
    model.light_specular[:] = (0.15, 0.15, 0.15)


def add_floor(scene: Any) -> None:
    """Append a light floor under the piano to a ``mujoco.MjvScene`` (after ``update_scene``)."""
    import mujoco

    if scene.ngeom >= scene.maxgeom:
        return
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        geom,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=np.array([FLOOR_HALF_SIZE_M, FLOOR_HALF_SIZE_M, 0.001]),
        pos=np.array([0.0, 0.0, FLOOR_Z_M - 0.001]),
        mat=np.eye(3).flatten(),
        rgba=np.array(FLOOR_RGBA, dtype=np.float32),
    )
    scene.ngeom += 1
