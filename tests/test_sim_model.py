"""The compiled MuJoCo model: piano geometry and joints, hands, contact bits, physics presets."""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np
import pytest

from pianist.sim import constants as C
from pianist.sim.hands import HandOptions
from pianist.sim.scene import Scene, SceneOptions, build_scene

WHITE_MAX = math.atan(0.01 / 0.15)
BLACK_MAX = math.atan(0.008 / 0.09)
FINGERS = ("th", "ff", "mf", "rf", "lf")
PREFIX = {"right": "rh/", "left": "lh/"}


@functools.cache
def scene_for(options: SceneOptions | None = None) -> Scene:
    """Compile each configuration once per test module (the options are frozen, hashable)."""
    return build_scene(options or SceneOptions())


def hand_options(**kwargs: object) -> SceneOptions:
    hands = kwargs.pop("hands", "both")
    physics = kwargs.pop("physics", "faithful")
    return SceneOptions(hands=hands, physics=physics, hand=HandOptions(**kwargs))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def scene() -> Scene:
    return scene_for()


@pytest.fixture(scope="module")
def kin(scene: Scene) -> mujoco.MjData:
    """Data of the default scene at its initial pose, kinematics computed."""
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return data


def can_collide(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """MuJoCo's bitmask filter: (contype1 & conaffinity2) or (contype2 & conaffinity1)."""
    return bool(
        (model.geom_contype[g1] & model.geom_conaffinity[g2])
        or (model.geom_contype[g2] & model.geom_conaffinity[g1])
    )


def hand_geoms(model: mujoco.MjModel, side: str, collision_only: bool = True) -> list[int]:
    p = PREFIX[side]
    out = []
    for g in range(model.ngeom):
        if not model.body(model.geom_bodyid[g]).name.startswith(p):
            continue
        if collision_only and model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        out.append(g)
    return out


# --------------------------------------------------------------------------------- piano


def test_key_elements_share_the_name_key_i(scene: Scene) -> None:
    m = scene.model
    for k in range(88):
        name = f"key_{k}"
        body = m.body(name).id
        assert m.joint(name).id == m.body_jntadr[body]
        assert m.jnt_qposadr[m.joint(name).id] == scene.key_qpos[k]
        assert m.jnt_dofadr[m.joint(name).id] == scene.key_dof[k]
        assert m.geom(name).id == scene.key_geoms[k]
        assert m.geom_bodyid[scene.key_geoms[k]] == body
        assert m.site(name).id == scene.key_sites[k]
        assert m.site_bodyid[scene.key_sites[k]] == body
        assert m.body_jntnum[body] == 1
        assert m.jnt_type[m.joint(name).id] == mujoco.mjtJoint.mjJNT_HINGE


def test_keys_sorted_by_pitch_along_plus_y(scene: Scene, kin: mujoco.MjData) -> None:
    geom_y = kin.geom_xpos[scene.key_geoms, 1]
    site_y = kin.site_xpos[scene.key_sites, 1]
    assert np.all(np.diff(geom_y) > 0)
    assert np.all(np.diff(site_y) > 0)
    assert geom_y[0] < -0.55 and geom_y[87] > 0.55


def test_black_and_white_keys(scene: Scene) -> None:
    m = scene.model
    black = np.array([k % 12 in {1, 4, 6, 9, 11} for k in range(88)])
    assert black.sum() == 36 and (~black).sum() == 52
    np.testing.assert_array_equal(C.BLACK_KEY_MASK, black)
    sizes = m.geom_size[scene.key_geoms]
    np.testing.assert_allclose(sizes[black], np.tile([0.045, 0.005, 0.009], (36, 1)))
    np.testing.assert_allclose(sizes[~black], np.tile([0.075, 0.01125, 0.01125], (52, 1)))
    masses = m.body_mass[m.geom_bodyid[scene.key_geoms]]
    np.testing.assert_allclose(masses[black], 0.02)
    np.testing.assert_allclose(masses[~black], 0.04)


def test_key_geometry(scene: Scene, kin: mujoco.MjData) -> None:
    black = C.BLACK_KEY_MASK
    centre = kin.geom_xpos[scene.key_geoms]
    white_y = centre[~black, 1]
    np.testing.assert_allclose(white_y, -0.6105 + 0.01125 + np.arange(52) * 0.0235, atol=1e-12)
    np.testing.assert_allclose(centre[~black, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(centre[~black, 2], 0.01125, atol=1e-12)
    np.testing.assert_allclose(centre[black, 0], -0.03, atol=1e-12)
    np.testing.assert_allclose(centre[black, 2], 0.026, atol=1e-12)
    # A black key sits on the gap between its two white neighbours (A#0 between A0 and B0).
    for k in np.flatnonzero(black):
        gap = (centre[k - 1, 1] + centre[k + 1, 1]) / 2
        assert centre[k, 1] == pytest.approx(gap, abs=1e-12)
    # Keyboard length 52 * 22.5 mm + 51 * 1 mm, centred on y = 0.
    assert C.KEYBOARD_LENGTH_M == pytest.approx(1.221)
    assert white_y[0] - 0.01125 == pytest.approx(-0.6105)
    assert white_y[-1] + 0.01125 == pytest.approx(0.6105)
    base = scene.model.geom("piano_base")
    np.testing.assert_allclose(2 * base.size, [0.1, 1.221, 0.04])
    np.testing.assert_allclose(kin.geom_xpos[base.id], [-0.127, 0.0, 0.02])


def test_key_joint_parameters(scene: Scene) -> None:
    m = scene.model
    joints = [m.joint(f"key_{k}").id for k in range(88)]
    black = C.BLACK_KEY_MASK
    ranges = m.jnt_range[joints]
    np.testing.assert_allclose(ranges[:, 0], 0.0)
    np.testing.assert_allclose(ranges[black, 1], BLACK_MAX, rtol=1e-12)
    np.testing.assert_allclose(ranges[~black, 1], WHITE_MAX, rtol=1e-12)
    assert BLACK_MAX == pytest.approx(0.088656, abs=1e-6)
    assert WHITE_MAX == pytest.approx(0.066568, abs=1e-6)
    np.testing.assert_allclose(scene.key_max_angle_rad, ranges[:, 1])
    assert m.jnt_limited[joints].all()
    np.testing.assert_allclose(m.jnt_axis[joints], np.tile([0, 1, 0], (88, 1)))
    np.testing.assert_allclose(m.jnt_stiffness[joints], 2.0)
    np.testing.assert_allclose(m.qpos_spring[scene.key_qpos], math.radians(-1.0))
    np.testing.assert_allclose(m.dof_damping[scene.key_dof], 0.05)
    np.testing.assert_allclose(m.dof_armature[scene.key_dof], 0.001)


@pytest.mark.parametrize("key", [0, 1, 39, 87])
def test_pressing_a_key_lowers_its_front_by_the_travel(scene: Scene, key: int) -> None:
    """A positive hinge angle moves the front (player) end down: 10 mm white, 8 mm black."""
    m = scene.model
    data = mujoco.MjData(m)
    geom = scene.key_geoms[key]
    half = m.geom_size[geom]

    def front_bottom_z() -> float:
        mujoco.mj_kinematics(m, data)
        local = np.array([half[0], 0.0, 0.0])  # front end, on the key's centre line
        return float((data.geom_xpos[geom] + data.geom_xmat[geom].reshape(3, 3) @ local)[2])

    rest = front_bottom_z()
    data.qpos[scene.key_qpos[key]] = scene.key_max_angle_rad[key]
    pressed = front_bottom_z()
    travel = 0.008 if C.is_black_key(key) else 0.01
    # The front end moves on an arc: its drop is L sin(atan(d / L)), within 0.1 mm of d.
    assert rest - pressed == pytest.approx(travel, abs=1e-4)
    # The fingertip target site goes down with the key.
    assert data.site_xpos[scene.key_sites[key], 2] < data.geom_xpos[geom, 2] + half[2]


def test_keys_collide_only_with_hands(scene: Scene) -> None:
    m = scene.model
    piano = [*scene.key_geoms.tolist(), m.geom("piano_base").id]
    for g1 in piano:
        for g2 in piano:
            assert not can_collide(m, g1, g2)
    for side in ("right", "left"):
        geoms = hand_geoms(m, side)
        assert geoms
        assert any(can_collide(m, g, scene.key_geoms[40]) for g in geoms)
        # Every collision geom of the hands may touch the keys in the faithful preset.
        for g in geoms:
            assert can_collide(m, g, scene.key_geoms[0])


def test_black_and_white_keys_overlap_but_make_no_contacts(
    scene: Scene, kin: mujoco.MjData
) -> None:
    """The black key boxes intersect their white neighbours: only the contact bits keep them
    from generating contacts (which would jam the keyboard)."""
    m = scene.model
    piano_geoms = {*scene.key_geoms.tolist(), m.geom("piano_base").id}
    pairs = {tuple(c.geom) for c in kin.contact}
    assert not any(g1 in piano_geoms and g2 in piano_geoms for g1, g2 in pairs)
    # The geometric overlap that the bits must neutralise is real: each black box reaches
    # into both white neighbours, sideways and in height.
    pos, size = kin.geom_xpos[scene.key_geoms], m.geom_size[scene.key_geoms]
    for k in np.flatnonzero(C.BLACK_KEY_MASK):
        assert pos[k, 1] - size[k, 1] < pos[k - 1, 1] + size[k - 1, 1]
        assert pos[k, 1] + size[k, 1] > pos[k + 1, 1] - size[k + 1, 1]
        assert pos[k, 2] - size[k, 2] < pos[k - 1, 2] + size[k - 1, 2]


# --------------------------------------------------------------------------------- sizes


@pytest.mark.parametrize(
    ("options", "nu", "nq", "per_hand_actuators", "per_hand_joints", "sides"),
    [
        (hand_options(), 38, 88 + 46, 19, 23, ("right", "left")),
        (hand_options(reduced_action_space=False), 44, 88 + 52, 22, 26, ("right", "left")),
        (hand_options(hands="right"), 19, 88 + 23, 19, 23, ("right",)),
        (hand_options(hands="left"), 19, 88 + 23, 19, 23, ("left",)),
        (hand_options(forearm_dofs=("tx", "ty", "tz")), 40, 88 + 48, 20, 24, ("right", "left")),
        (
            hand_options(forearm_dofs=("tx", "ty", "tz", "roll", "pitch", "yaw")),
            46,
            88 + 54,
            23,
            27,
            ("right", "left"),
        ),
        (hand_options(forearm_dofs=()), 34, 88 + 42, 17, 21, ("right", "left")),
    ],
    ids=["both-reduced", "both-full", "right", "left", "tz", "six-dofs", "no-forearm-dofs"],
)
def test_model_sizes(
    options: SceneOptions,
    nu: int,
    nq: int,
    per_hand_actuators: int,
    per_hand_joints: int,
    sides: tuple[str, ...],
) -> None:
    s = scene_for(options)
    m = s.model
    assert m.nu == nu
    assert m.nq == nq and m.nv == nq  # hinges and slides only
    assert tuple(h.side for h in s.hands) == sides
    names = [m.actuator(i).name for i in range(m.nu)]
    start = 0
    for hand in s.hands:
        p = PREFIX[hand.side]
        assert len(hand.actuators) == per_hand_actuators
        assert len(hand.joint_qpos) == per_hand_joints
        # Right hand first, then left, contiguous.
        np.testing.assert_array_equal(hand.actuators, np.arange(start, start + per_hand_actuators))
        assert all(names[a].startswith(p) for a in hand.actuators)
        start += per_hand_actuators
    assert start == nu
    for side in {"right", "left"} - set(sides):
        assert not any(n.startswith(PREFIX[side]) for n in names)


def test_reduced_action_space_removes_joints_and_narrows_thj2() -> None:
    reduced = scene_for(hand_options()).model
    full = scene_for(hand_options(reduced_action_space=False)).model
    for p in ("rh/", "lh/"):
        for joint in ("THJ5", "THJ1", "LFJ5"):
            full.joint(p + joint)  # exists
            with pytest.raises(KeyError):
                reduced.joint(p + joint)
        np.testing.assert_allclose(reduced.actuator(p + "A_THJ2").ctrlrange, [0.0, 0.698])
        assert full.actuator(p + "A_THJ2").ctrlrange[0] < 0


# --------------------------------------------------------------------------------- hands


def test_fingertip_sites(scene: Scene, kin: mujoco.MjData) -> None:
    m = scene.model
    for hand in scene.hands:
        p = PREFIX[hand.side]
        expected = [m.site(f"{p}{f}tip").id for f in FINGERS]
        np.testing.assert_array_equal(hand.fingertip_sites, expected)
        for finger, site in zip(FINGERS, expected, strict=True):
            distal = m.body(f"{p}{finger}distal").id
            assert m.site_bodyid[site] == distal
            offset = 0.0275 if finger == "th" else 0.026
            distance = np.linalg.norm(kin.site_xpos[site] - kin.xpos[distal])
            assert distance == pytest.approx(offset, abs=1e-9)


def test_hand_placement_and_orientation(scene: Scene, kin: mujoco.MjData) -> None:
    right, left = scene.hand("right"), scene.hand("left")
    np.testing.assert_allclose(kin.xpos[right.forearm_body], [0.4, 0.15, 0.13], atol=1e-12)
    np.testing.assert_allclose(kin.xpos[left.forearm_body], [0.4, -0.15, 0.13], atol=1e-12)
    for hand in (right, left):
        tips = kin.site_xpos[hand.fingertip_sites]
        root = kin.xpos[hand.forearm_body]
        # Fingers point into the keys (-x), the fingertips hover over the keyboard.
        assert np.all(tips[:, 0] < root[0] - 0.25)
        assert np.all(np.abs(tips[:, 0]) < 0.075)
        assert np.all(tips[:, 2] > 0.0225 + 0.0125)  # above the black key tops: nothing pressed
        # Palm down, seen from the player (+x looking at -x): the right hand's thumb is on its
        # left (-y) and its little finger on its right; mirrored for the left hand.
        thumb, fingers = tips[0, 1], tips[1:, 1]
        if hand.side == "right":
            assert thumb < fingers.min() and np.all(np.diff(fingers) > 0)
        else:
            assert thumb > fingers.max() and np.all(np.diff(fingers) < 0)
    assert kin.xpos[right.forearm_body, 1] > kin.xpos[left.forearm_body, 1]


def test_forearm_joint_axes_and_servos() -> None:
    s = scene_for(hand_options(forearm_dofs=("tx", "ty", "tz", "roll", "pitch", "yaw")))
    m = s.model
    data = mujoco.MjData(m)
    for hand in s.hands:
        p = PREFIX[hand.side]
        home = np.array(C.FOREARM_ROOT_POS_M[hand.side])
        for dof, value, shift in (
            ("tx", 0.1, (0, 0.1, 0)),  # along the keyboard, +y
            ("ty", 0.03, (-0.03, 0, 0)),  # into the keys, -x
            ("tz", -0.02, (0, 0, -0.02)),  # up is +z
        ):
            mujoco.mj_resetData(m, data)
            data.qpos[m.joint(p + "forearm_" + dof).qposadr[0]] = value
            mujoco.mj_kinematics(m, data)
            np.testing.assert_allclose(data.xpos[hand.forearm_body], home + shift, atol=1e-9)
        for dof, kp in (("tx", 300), ("ty", 300), ("tz", 1000), ("roll", 50)):
            act = m.actuator(p + "A_forearm_" + dof)
            joint = m.joint(p + "forearm_" + dof)
            assert act.gainprm[0] == pytest.approx(kp)
            assert act.biasprm[1] == pytest.approx(-kp)
            assert act.biasprm[2] < 0  # a damped servo
            np.testing.assert_allclose(act.ctrlrange, joint.range)
            assert joint.limited[0]
        np.testing.assert_allclose(m.joint(p + "forearm_ty").range, [0.0, 0.06])
        np.testing.assert_allclose(m.joint(p + "forearm_tz").range, [-0.04, 0.0])
        np.testing.assert_allclose(m.joint(p + "forearm_pitch").range, [0.0, 0.15])
        # The slide along the keyboard lets the root reach both ends of it.
        low, high = m.joint(p + "forearm_tx").range + home[1]
        assert low <= -0.6105 + 1e-9 and high >= 0.6105 - 1e-9


def test_extra_forearm_dofs_in_fixed_order() -> None:
    s = scene_for(hand_options(forearm_dofs=("yaw", "tz", "tx", "ty")))
    m = s.model
    names = [m.joint(j).name for j in range(m.njnt) if "forearm" in m.joint(j).name]
    assert names == [f"{p}forearm_{d}" for p in ("rh/", "lh/") for d in ("tx", "ty", "tz", "yaw")]


@pytest.mark.parametrize("primitive", [True, False])
def test_fingertip_collision_geoms(primitive: bool) -> None:
    m = scene_for(hand_options(primitive_fingertip_collisions=primitive)).model
    for p in ("rh/", "lh/"):
        for finger in FINGERS:
            body = m.body(f"{p}{finger}distal").id
            colliding = [
                g
                for g in range(m.ngeom)
                if m.geom_bodyid[g] == body and (m.geom_contype[g] or m.geom_conaffinity[g])
            ]
            types = [int(m.geom_type[g]) for g in colliding]
            if primitive:
                assert types == [int(mujoco.mjtGeom.mjGEOM_CAPSULE)]
                assert m.geom_size[colliding[0], 0] == pytest.approx(0.0095)
            else:
                assert types == [int(mujoco.mjtGeom.mjGEOM_MESH)]


@pytest.mark.parametrize("on", [True, False])
def test_gravity_compensation(on: bool) -> None:
    m = scene_for(hand_options(gravity_compensation=on)).model
    hand_bodies = [b for b in range(m.nbody) if m.body(b).name.startswith(("rh/", "lh/"))]
    other = [b for b in range(m.nbody) if b not in hand_bodies]
    assert len(hand_bodies) > 40
    np.testing.assert_array_equal(m.body_gravcomp[hand_bodies], 1.0 if on else 0.0)
    np.testing.assert_array_equal(m.body_gravcomp[other], 0.0)


@pytest.mark.parametrize("on", [True, False])
def test_hand_collisions_bits(on: bool) -> None:
    s = scene_for(hand_options(hand_collisions=on))
    m = s.model
    right, left = hand_geoms(m, "right"), hand_geoms(m, "left")
    cross = [can_collide(m, g1, g2) for g1 in right for g2 in left]
    if on:
        assert all(cross)
        fr, fl = (h.forearm_geoms for h in s.hands)
        assert fr.size and fl.size and can_collide(m, int(fr[0]), int(fl[0]))
    else:
        assert not any(cross)
    # Either way, each hand still plays the piano and keeps its self-collisions.
    for geoms in (right, left):
        assert all(can_collide(m, g, s.key_geoms[10]) for g in geoms)
        assert any(can_collide(m, g1, g2) for g1 in geoms for g2 in geoms if g1 != g2)


# --------------------------------------------------------------------------------- physics


def hand_dofs(m: mujoco.MjModel) -> np.ndarray:
    joints = [j for j in range(m.njnt) if m.joint(j).name.startswith(("rh/", "lh/"))]
    return m.jnt_dofadr[joints]


def test_faithful_physics_preset(scene: Scene) -> None:
    opt = scene.model.opt
    assert opt.timestep == pytest.approx(0.005)
    assert opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    assert opt.iterations == 100
    assert opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert opt.impratio == pytest.approx(10.0)
    assert opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    assert opt.jacobian == mujoco.mjtJacobian.mjJAC_DENSE
    assert not opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP
    finger_dofs = [
        scene.model.joint(j).dofadr[0]
        for j in range(scene.model.njnt)
        if scene.model.joint(j).name.startswith(("rh/FF", "lh/MF"))
    ]
    np.testing.assert_allclose(scene.model.dof_frictionloss[finger_dofs], 0.01)


def test_fast_physics_preset() -> None:
    s = scene_for(SceneOptions(physics="fast"))
    m = s.model
    assert m.opt.jacobian == mujoco.mjtJacobian.mjJAC_DENSE
    assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP
    assert m.opt.timestep == pytest.approx(0.005)
    np.testing.assert_array_equal(m.dof_frictionloss[hand_dofs(m)], 0.0)
    # Only the distal phalanges (fingertips) may touch the keys (which all share their bits).
    assert len(set(m.geom_contype[s.key_geoms])) == len(set(m.geom_conaffinity[s.key_geoms])) == 1
    touching = set()
    for side in ("right", "left"):
        for g in hand_geoms(m, side, collision_only=False):
            body = m.body(m.geom_bodyid[g]).name
            if can_collide(m, g, s.key_geoms[0]):
                touching.add(body)
    expected = {f"{p}{f}distal" for p in ("rh/", "lh/") for f in FINGERS}
    assert touching == expected
    # The faithful scene lets palms, phalanges and forearms touch the keys.
    faithful = scene_for()
    fm = faithful.model
    palm = [g for g in hand_geoms(fm, "right") if fm.body(fm.geom_bodyid[g]).name == "rh/palm"]
    assert palm and all(can_collide(fm, g, faithful.key_geoms[0]) for g in palm)


def test_invalid_options_raise() -> None:
    with pytest.raises(ValueError, match="physics"):
        SceneOptions(physics="ludicrous")
    with pytest.raises(ValueError, match="hands"):
        SceneOptions(hands="three")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="forearm"):
        HandOptions(forearm_dofs=("tx", "spin"))
    with pytest.raises(ValueError):
        HandOptions(forearm_dofs=("tx", "tx"))
