"""The full scene: piano, one or two hands, lights and cameras, and the physics presets.

:func:`build_scene` returns a :class:`Scene` holding the compiled ``mujoco.MjModel`` and the
index arrays the environment needs, so that nothing downstream looks names up at step time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np

from pianist.sim import constants as C
from pianist.sim.hands import HandOptions, Side, attach_hand, is_fingertip_body
from pianist.sim.piano import add_piano, key_name

HandsSpec = Literal["both", "right", "left"]


@dataclass(frozen=True)
class PhysicsPreset:
    """Simulator settings. ``faithful`` reproduces the original; ``fast`` trades fidelity.

    Each fast option's effect on raw physics speed, cumulative, two-hand scene with random
    controls, measured by ``benchmarks/bench_physics.py`` on the 2-core machine: faithful
    4.7k steps/s; + sleeping islands 6.0k (1.27x); + no hand frictionloss 7.6k (1.61x);
    + fingertip contacts only 11.2k (2.37x); + 20 solver iterations 11.3k (2.39x).
    """

    name: str
    timestep_s: float = C.PHYSICS_TIMESTEP_S
    solver: int = int(mujoco.mjtSolver.mjSOL_NEWTON)
    iterations: int = 100
    ls_iterations: int = 50
    cone: int = int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
    impratio: float = 10.0
    integrator: int = int(mujoco.mjtIntegrator.mjINT_EULER)
    sleep: bool = False
    """Sleeping islands (``mjENBL_SLEEP``): keys resting on their stops are not simulated."""
    hand_frictionloss: bool = True
    """Dry friction in the hands' joints; each joint adds a constraint row."""
    fingertip_contacts_only: bool = False
    """Only the distal phalanges of the hands collide, with the keys and with each other;
    palms, other phalanges and forearms pass through everything (so the forearm reward is
    always 0.5)."""


FAITHFUL = PhysicsPreset(name="faithful")
FAST = PhysicsPreset(
    name="fast",
    iterations=20,
    ls_iterations=10,
    sleep=True,
    hand_frictionloss=False,
    fingertip_contacts_only=True,
)
PHYSICS_PRESETS: dict[str, PhysicsPreset] = {p.name: p for p in (FAITHFUL, FAST)}


@dataclass(frozen=True)
class SceneOptions:
    """Everything that changes the compiled model."""

    hands: HandsSpec = "both"
    hand: HandOptions = field(default_factory=HandOptions)
    physics: str | PhysicsPreset = "faithful"

    def __post_init__(self) -> None:
        if self.hands not in ("both", "right", "left"):
            raise ValueError(f"hands must be 'both', 'right' or 'left', not {self.hands!r}")
        if not isinstance(self.physics, str | PhysicsPreset) or (
            isinstance(self.physics, str) and self.physics not in PHYSICS_PRESETS
        ):
            raise ValueError(
                f"unknown physics preset {self.physics!r}; choose from {sorted(PHYSICS_PRESETS)}"
            )

    @property
    def physics_preset(self) -> PhysicsPreset:
        if isinstance(self.physics, PhysicsPreset):
            return self.physics
        return PHYSICS_PRESETS[self.physics]

    @property
    def sides(self) -> tuple[Side, ...]:
        return ("right", "left") if self.hands == "both" else (self.hands,)


@dataclass(frozen=True)
class HandIndex:
    """Addresses of one hand's elements in the compiled model."""

    side: Side
    joint_qpos: np.ndarray  # (n,) qpos addresses of the hand's joints, forearm joints included
    actuators: np.ndarray  # (m,) actuator ids, contiguous
    fingertip_sites: np.ndarray  # (5,) site ids, thumb..little
    forearm_body: int
    forearm_geoms: np.ndarray  # collision geoms of the forearm body


@dataclass(frozen=True)
class Scene:
    """A compiled scene and the index arrays into it."""

    model: mujoco.MjModel
    options: SceneOptions
    key_qpos: np.ndarray  # (88,) qpos address of each key's hinge
    key_dof: np.ndarray  # (88,) dof address of each key's hinge
    key_geoms: np.ndarray  # (88,)
    key_sites: np.ndarray  # (88,) fingertip targets
    key_max_angle_rad: np.ndarray  # (88,)
    hands: tuple[HandIndex, ...]
    actuator_force_sensors: np.ndarray  # (nu,) sensordata address of each actuator's force
    actuator_velocity_sensors: np.ndarray  # (nu,) sensordata address of each actuator's velocity
    key_history_cursor: np.ndarray  # (88,) data.history address of each key sensor's cursor
    key_history_times: np.ndarray  # (88, n) data.history addresses of the sample times
    key_history_values: np.ndarray  # (88, n) data.history addresses of the sampled positions

    @property
    def actuator_ranges(self) -> np.ndarray:
        """(nu, 2) control range of every actuator."""
        return self.model.actuator_ctrlrange

    @property
    def forearms_can_touch(self) -> bool:
        """Whether the two forearms have geoms that may collide with each other."""
        if len(self.hands) != 2:
            return False
        m = self.model
        a, b = (h.forearm_geoms for h in self.hands)
        if a.size == 0 or b.size == 0:
            return False
        return bool(
            np.any(m.geom_contype[a][:, None] & m.geom_conaffinity[b][None, :])
            or np.any(m.geom_contype[b][:, None] & m.geom_conaffinity[a][None, :])
        )

    def hand(self, side: Side) -> HandIndex:
        for h in self.hands:
            if h.side == side:
                return h
        raise KeyError(f"the scene has no {side} hand")


def build_spec(options: SceneOptions, key_history: int = 10) -> mujoco.MjSpec:
    """The uncompiled scene, for callers who want to edit it further.

    ``key_history`` is how many past samples each key's position sensor keeps (see
    :attr:`Scene.key_history_values`): at least the substeps of one control step.
    """
    preset = options.physics_preset
    spec = mujoco.MjSpec()
    spec.modelname = "pianist"
    spec.compiler.autolimits = True
    spec.compiler.degree = False  # every angle in this package is in radians
    spec.nuserdata = 1  # userdata[0] carries the sustain pedal state (0 or 1)
    _set_physics(spec, preset)
    _add_stage(spec)
    add_piano(spec)
    for side in options.sides:
        attach_hand(spec, side, options.hand)
    _add_actuator_sensors(spec)
    _add_key_sensors(spec, key_history)
    if not preset.hand_frictionloss:
        for joint in spec.joints:
            if joint.name.startswith(("rh/", "lh/")):
                joint.frictionloss = 0.0
    if preset.fingertip_contacts_only:
        for geom in spec.geoms:
            body = geom.parent
            if body.name.startswith(("rh/", "lh/")) and not is_fingertip_body(body.name):
                geom.contype = 0
                geom.conaffinity = 0
    return spec


def build_scene(options: SceneOptions | None = None, key_history: int = 10) -> Scene:
    """Compile the scene described by ``options`` (defaults: both hands, paper setup)."""
    options = options or SceneOptions()
    model = build_spec(options, key_history).compile()
    return _index(model, options)


def _add_key_sensors(spec: mujoco.MjSpec, samples: int) -> None:
    """A position sensor on every key that keeps its last ``samples`` values (MuJoCo sensor
    history). One ``mj_step(nstep=S)`` call, which releases Python's lock for the whole
    control step, then still tells where every key was after every substep."""
    for key in range(C.NUM_KEYS):
        sensor = spec.add_sensor(
            name=f"{key_name(key)}_pos",
            type=mujoco.mjtSensor.mjSENS_JOINTPOS,
            objtype=mujoco.mjtObj.mjOBJ_JOINT,
            objname=key_name(key),
        )
        sensor.nsample = samples


def _add_actuator_sensors(spec: mujoco.MjSpec) -> None:
    """Force and velocity of every actuator as sensors, so that the energy term can be read
    from ``sensordata`` after ``mj_step`` and from ``mujoco.rollout`` alike."""
    for act in list(spec.actuators):
        for kind, tag in (
            (mujoco.mjtSensor.mjSENS_ACTUATORFRC, "force"),
            (mujoco.mjtSensor.mjSENS_ACTUATORVEL, "velocity"),
        ):
            spec.add_sensor(
                name=f"{act.name}_{tag}",
                type=kind,
                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                objname=act.name,
            )


def _set_physics(spec: mujoco.MjSpec, preset: PhysicsPreset) -> None:
    opt = spec.option
    opt.timestep = preset.timestep_s
    opt.solver = preset.solver
    opt.iterations = preset.iterations
    opt.ls_iterations = preset.ls_iterations
    opt.cone = preset.cone
    opt.impratio = preset.impratio
    opt.integrator = preset.integrator
    # mujoco 4.0.0's sparse Cholesky diverges on this scene (facts page, section 8); the dense
    # Jacobian is stable and no slower here.
    opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    if preset.sleep:
        opt.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP


def _add_stage(spec: mujoco.MjSpec) -> None:
    """Lights, floor-free backdrop and the named cameras of the original."""
    spec.visual.headlight.ambient = (0.4, 0.4, 0.4)
    spec.visual.headlight.diffuse = (0.6, 0.6, 0.6)
    spec.visual.global_.offwidth = 1920
    spec.visual.global_.offheight = 1080
    world = spec.worldbody
    world.add_light(name="top", pos=(0, 0, 1.5), dir=(0, 0, -1), castshadow=False)
    cameras = {
        # name: (position, point looked at)
        "closeup": ((0.45, -0.0, 0.35), (0.0, 0.0, 0.05)),
        "left": ((0.3, -0.9, 0.4), (0.0, -0.2, 0.05)),
        "right": ((0.3, 0.9, 0.4), (0.0, 0.2, 0.05)),
        "back": ((0.9, 0.0, 0.6), (0.0, 0.0, 0.0)),
        "egocentric": ((0.55, 0.0, 0.5), (-0.05, 0.0, 0.0)),
        "topdown": ((0.0, 0.0, 1.4), (0.0, 0.0, 0.0)),
        # The whole keyboard from above the player's seat, tilted down 55 degrees (the video's
        # ``auto`` camera is this one moved closer to what a piece plays).
        "front": ((0.79, 0.0, 1.12), (0.035, 0.0, 0.05)),
    }
    for name, (pos, target) in cameras.items():
        world.add_camera(name=name, pos=pos, xyaxes=_look_at(np.array(pos), np.array(target)))


def _look_at(pos: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Camera xyaxes (6,) looking from ``pos`` at ``target`` with world z up."""
    forward = target - pos
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    if abs(forward @ up) > 0.99:  # looking straight down: let the image's up be -x (far side)
        up = np.array([-1.0, 0.0, 0.0])
    x = np.cross(forward, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, forward)
    return np.concatenate([x, y])


def _key_history_index(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    # Layout of one scalar sensor's history (MuJoCo 4): [user, cursor, n times, n values];
    # the cursor is the slot of the newest sample of a circular buffer.
    ids = [model.sensor(f"{key_name(k)}_pos").id for k in range(C.NUM_KEYS)]
    adr = model.sensor_historyadr[ids]
    n = int(model.sensor_history[ids[0], 0])
    slots = np.arange(n)
    return {
        "key_history_cursor": adr + 1,
        "key_history_times": adr[:, None] + 2 + slots,
        "key_history_values": adr[:, None] + 2 + n + slots,
    }


def _index(model: mujoco.MjModel, options: SceneOptions) -> Scene:
    key_joints = [model.joint(key_name(k)).id for k in range(C.NUM_KEYS)]
    hands = []
    for side in options.sides:
        p = C.HAND_PREFIX[side]
        joint_ids = [j for j in range(model.njnt) if model.joint(j).name.startswith(p)]
        actuators = np.array(
            [a for a in range(model.nu) if model.actuator(a).name.startswith(p)], dtype=np.intp
        )
        if actuators.size and not np.all(np.diff(actuators) == 1):
            raise AssertionError(f"{side} hand actuators are not contiguous")
        forearm = model.body(f"{p}forearm").id
        hands.append(
            HandIndex(
                side=side,
                joint_qpos=model.jnt_qposadr[joint_ids].astype(np.intp),
                actuators=actuators,
                fingertip_sites=np.array(
                    [model.site(f"{p}{f}tip").id for f in C.FINGER_NAMES], dtype=np.intp
                ),
                forearm_body=forearm,
                forearm_geoms=np.flatnonzero(
                    (model.geom_bodyid == forearm)
                    & ((model.geom_contype != 0) | (model.geom_conaffinity != 0))
                ),
            )
        )
    return Scene(
        model=model,
        options=options,
        key_qpos=model.jnt_qposadr[key_joints].astype(np.intp),
        key_dof=model.jnt_dofadr[key_joints].astype(np.intp),
        key_geoms=np.array([model.geom(key_name(k)).id for k in range(C.NUM_KEYS)], np.intp),
        key_sites=np.array([model.site(key_name(k)).id for k in range(C.NUM_KEYS)], np.intp),
        key_max_angle_rad=model.jnt_range[key_joints, 1].copy(),
        hands=tuple(hands),
        **_key_history_index(model),
        actuator_force_sensors=np.array(
            [
                model.sensor_adr[model.sensor(f"{model.actuator(a).name}_force").id]
                for a in range(model.nu)
            ],
            dtype=np.intp,
        ),
        actuator_velocity_sensors=np.array(
            [
                model.sensor_adr[model.sensor(f"{model.actuator(a).name}_velocity").id]
                for a in range(model.nu)
            ],
            dtype=np.intp,
        ),
    )
