"""The fingertip policy as a controller: an MLP decides, the planner's execution stages act.

Each step, for each hand, the policy (:mod:`features`) says where the forearm's slide should
be at the end of the next step and what each finger does (:class:`Mode`); this module turns
that into the action with the planner's fixed stages, following no plan at step time (a
policy that reads the plan's fingering has the planner plan the piece at reset, a fraction
of a second, and by default its forearms follow that plan's path: :data:`Forearm`):

1. the slide is steered to its target (the plan's path, or the policy's own target) through
   its servo's exact dynamics (the planner's ``SlideServo``), the height slide and the wrist held
   as the planner holds them;
2. each finger's fingertip target follows from its mode and its next key by the song's
   fingering: below the key's top (press), above it (hover, re-strike), or the lifted
   posture; a pressing finger whose key does not sound is pushed harder, as the planner does;
3. the planner's per-finger inverse kinematics turns the targets into joint commands.

So a press is a decision (a class), not an average of joint angles: what behaviour cloning of
joint angles could not learn (``docs/notes/2026-12-07-generalist-joint-angle-policy.md``).
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import mujoco
import numpy as np

from pianist.agents.bc import NumpyMLP
from pianist.agents.fingertip.features import (
    FEATURE_DIM,
    FINGERS,
    MOVE_UNIT_M,
    NUM_MODES,
    OUTPUT_DIM,
    SPEED_UNIT,
    WINDOW,
    HandView,
    Mode,
    NextKeys,
    decode_move,
    encode_move,
    hand_features,
)
from pianist.control.base import BaseController
from pianist.control.planner import ENV_OPTIONS, IKPlanner, PlannerConfig
from pianist.control.planner.forearm import command_forearm, command_height
from pianist.control.planner.hand import FingerMemory, Hand
from pianist.control.planner.ik import finger_controls, solve_fingers
from pianist.control.planner.postures import set_wrist
from pianist.control.planner.targets import count_unsounded, mark_represses, press_point
from pianist.files import atomic_dir
from pianist.sim import constants as C

#: The planner whose plan fingers a song for a policy that reads the plan's fingering, and
#: whose decisions label it: its plan chosen from the candidates the shipped policy was
#: trained with, by the key-frames each leaves playable, not by rehearsal (a policy reads no
#: physics ahead, and three rehearsals at reset would slow it from ~14x real time to ~5x),
#: and with the wrist straight throughout (no reach poses): the policy commands no wrist
#: pose, and was trained on plans for a straight hand.
PLAN_FINGERING_CONFIG = PlannerConfig().with_fields(
    choose_plan="playable", best_candidates=("frame", "piece-song", "piece"), reach_poses=()
)

FORMAT = "pianist-fingertip"
VERSION = 1
CONFIG_FILE = "fingertip.json"
WEIGHTS_FILE = "weights.npz"


def step_features(
    p: IKPlanner, nxt: NextKeys, t: int, last_modes: np.ndarray, fingers: np.ndarray
) -> np.ndarray:
    """Every hand's features at step ``t`` (``p`` set up: :meth:`IKPlanner.setup`), shape
    (H, :data:`FEATURE_DIM`), hands in the scene's order; ``last_modes`` (10,) int;
    ``fingers`` (T, 88) the fingering the policy reads (:func:`read_fingering`)."""
    data = p.handle.data
    key_down = data.qpos[p.key_qpos] >= p.key_threshold
    roots = [hand.root_y + data.qpos[hand.tx_qpos] for hand in p.hands]
    rows = []
    for i, hand in enumerate(p.hands):
        others = [roots[j] - roots[i] for j in range(len(p.hands)) if j != i]
        origin = data.xpos[hand.forearm_body]
        home = p.poses[i][0]  # the policy plays in the home pose (PLAN_FINGERING_CONFIG)
        lo = float(hand.tx_range[0])
        hi = float(hand.tx_range[1])
        view = HandView(
            sign=1.0 if hand.side == "right" else -1.0,
            finger_offset=hand.finger_offset,
            tx=float(data.qpos[hand.tx_qpos]),
            tx_vel=float(data.qvel[hand.tx_dof]),
            tx_mid=(lo + hi) / 2,
            tx_half=(hi - lo) / 2,
            other_y=others[0] if others else None,
            tip_offset_y=home.tip_offset_y,
            tips=data.site_xpos[hand.sites],
            lift_tips=home.lift_tips + origin,
        )
        off = hand.finger_offset
        rows.append(
            hand_features(
                view,
                t,
                p.goal.keys,
                fingers,
                nxt,
                p.key_point,
                p.key_top_z,
                key_down,
                last_modes[off : off + FINGERS],
            )
        )
    return np.stack(rows)


@dataclass
class FingertipPolicy:
    """A trained fingertip policy: the network (features -> outputs) and facts about it."""

    net: NumpyMLP
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.net.obs_dim != FEATURE_DIM or self.net.action_dim != OUTPUT_DIM:
            raise ValueError(
                f"a fingertip network maps {FEATURE_DIM} -> {OUTPUT_DIM} values, this one "
                f"{self.net.obs_dim} -> {self.net.action_dim} (made by another version)"
            )


def save_policy(policy: FingertipPolicy, out: str | Path) -> Path:
    """Write ``policy`` to the folder ``out`` (replaced whole, or not at all)."""
    net = policy.net
    arrays: dict[str, np.ndarray] = {"mean": net.mean, "std": net.std}
    for i, (w, b) in enumerate(net.layers):
        arrays[f"W{i}"], arrays[f"b{i}"] = w, b
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "layers": len(net.layers),
        "activation": net.activation_name,
        "window": WINDOW,
        "info": policy.info,
    }
    out = Path(out)
    with atomic_dir(out) as tmp:
        np.savez(tmp / WEIGHTS_FILE, allow_pickle=False, **arrays)
        (tmp / CONFIG_FILE).write_text(json.dumps(meta, indent=2) + "\n")
    return out


def load_policy(folder: str | Path) -> FingertipPolicy:
    """The policy :func:`save_policy` wrote to ``folder``.

    Raises:
        FileNotFoundError: no fingertip policy there.
        ValueError: a damaged file or another version's.
    """
    folder = Path(folder)
    if not (folder / CONFIG_FILE).is_file():
        raise FileNotFoundError(f"{folder} holds no fingertip policy (no {CONFIG_FILE})")
    try:
        meta = json.loads((folder / CONFIG_FILE).read_text())
        if meta.get("format") != FORMAT or meta.get("version") != VERSION:
            raise ValueError(f"unknown format {meta.get('format')} v{meta.get('version')}")
        with np.load(folder / WEIGHTS_FILE, allow_pickle=False) as z:
            layers = [(z[f"W{i}"], z[f"b{i}"]) for i in range(int(meta["layers"]))]
            mean, std = z["mean"], z["std"]
        net = NumpyMLP(layers, mean, std, meta["activation"])
        return FingertipPolicy(net, meta.get("info", {}))
    except (OSError, KeyError, TypeError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{folder} is not a readable fingertip policy ({exc})") from None


#: Which fingering a policy reads: the song's own, or the one the planner's whole-piece plan
#: makes for this robot at reset (:func:`read_fingering`).
Fingering = Literal["song", "plan"]


#: Where a policy's forearm slides go. ``"plan"``: along the path of the whole-piece plan
#: made at reset (the plan whose fingering the policy reads; the expert's own slide labels
#: are that path), so the policy decides every finger and the plan the hands' places.
#: ``"policy"``: to the policy's own slide targets. A policy trained deciding its slide
#: played open-etude-12 at 0.766 one way and 0.741 the other (fast): its slide was what it
#: imitated worst. The one shipped, trained along the plan, plays 0.777 and 0.531
#: (``docs/notes/2026-12-07-generalist-history.md``).
Forearm = Literal["plan", "policy"]


def read_fingering(p: IKPlanner, fingering: Fingering) -> np.ndarray:
    """(T, 88) int: the finger (0-9) that presses each due key, -1 where none.

    ``"song"``: the song's own labels. ``"plan"``: the planner's (``p`` reset, so planned):
    with its default ``hand_planning`` it fingers the piece for this robot, whose fingers
    other than the thumb each reach about one white key from a hand position, and gives the
    keys one hand cannot reach to the other (``docs/generalist.md``).
    """
    if fingering == "song":
        return p.goal.fingers
    if fingering == "plan":
        return np.where(p.goal.keys, p.fingers, -1)
    raise ValueError(f"unknown fingering {fingering!r}: use 'song' or 'plan'")


class FingertipController(BaseController):
    """Plays any fingered song with a :class:`FingertipPolicy` (no planner acting at step
    time, no look-ahead past :data:`WINDOW` frames). ``expert``: an :class:`IKPlanner` run in
    lock-step on the same states whose decisions are recorded as labels (DAgger), not
    played. ``forearm``: :data:`Forearm`; None, ``"plan"`` for a policy that reads the
    plan's fingering (there is a plan to follow), else ``"policy"``."""

    def __init__(
        self,
        policy: FingertipPolicy | str | Path,
        config: PlannerConfig | None = None,
        expert: ExpertRecorder | None = None,
        forearm: Forearm | None = None,
    ) -> None:
        self.policy = policy if isinstance(policy, FingertipPolicy) else load_policy(policy)
        self.config = config or PLAN_FINGERING_CONFIG
        self.expert = expert
        if expert is not None and expert.fingering != self.fingering:
            raise ValueError(
                f"the policy reads the {self.fingering} fingering, its expert labels with the "
                f"{expert.fingering} one"
            )
        if forearm not in (None, "plan", "policy"):
            raise ValueError(f"unknown forearm {forearm!r}: use 'plan' or 'policy'")
        if forearm == "plan" and self.fingering != "plan":
            raise ValueError(
                "forearm 'plan' needs a policy that reads the plan's fingering (this one reads "
                "the song's: no plan is made)"
            )
        self.forearm: Forearm = forearm or ("plan" if self.fingering == "plan" else "policy")

    def env_options(self, song: Any = None) -> dict[str, Any]:
        """The planner's scene (forearm height slide), whatever the song."""
        return dict(ENV_OPTIONS)

    @property
    def fingering(self) -> Fingering:
        """The fingering the policy was trained to read (policies from before the choice
        existed read the song's)."""
        return self.policy.info.get("fingering", "song")

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self.stages = IKPlanner(self.config)
        if self.fingering == "plan":
            self.stages.reset(env, seed)  # the whole-piece plan, for its fingering only
        else:
            self.stages.setup(env)
        p = self.stages
        self.fingers = read_fingering(p, self.fingering)
        self.next_keys = NextKeys.of(p.goal.keys, self.fingers)
        self.last_modes = np.zeros(2 * FINGERS, dtype=int)
        if self.expert is not None:
            self.expert.reset(env, seed)

    def act(self, observation: object = None) -> np.ndarray:
        p = self.stages
        cfg, handle, m, scratch = p.config, p.handle, p.model, p.scratch
        data = handle.data
        T = p.goal.num_frames
        t = min(handle.step_index, T - 1)
        if self.expert is not None:
            self.expert.act(observation)  # labels this state; its action is not played
        out = self.decide(t)
        if self.expert is not None:
            # The policy's own view of the state, with the expert's decisions as its labels.
            self.expert.features[-1] = self.features
        ctrl = np.array(data.ctrl)
        scratch.qpos[:] = data.qpos
        bent_up = []
        for i, (hand, o) in enumerate(zip(p.hands, out, strict=True)):
            home, servo = p.poses[i][0], p.servos[i]
            if self.forearm == "plan":  # as the expert: the plan's path
                command_forearm(ctrl, data, hand, servo, p.plan.hands[i].tx_path, t)
            else:
                sign = 1.0 if hand.side == "right" else -1.0
                tx, vel = float(data.qpos[hand.tx_qpos]), float(data.qvel[hand.tx_dof])
                move, speed = decode_move(o[0], MOVE_UNIT_M), decode_move(o[1], SPEED_UNIT)
                target = np.array([tx + sign * move, sign * speed])
                ctrl[hand.tx_actuator] = servo.command(np.array([tx, vel]), target)
            command_height(ctrl, data, hand, home.raise_m, cfg)
            bent_up.append(set_wrist(scratch, ctrl, hand, home.wrist, home.ty, cfg))
            # As the planner: aim from where the moving forearm will be a little later.
            scratch.qpos[hand.tx_qpos] += cfg.forearm.forearm_lead_s * data.qvel[hand.tx_dof]
        mujoco.mj_kinematics(m, scratch)
        key_down = data.qpos[p.key_qpos] >= p.key_threshold
        for i, (hand, o) in enumerate(zip(p.hands, out, strict=True)):
            modes = np.argmax(o[2:].reshape(FINGERS, NUM_MODES), axis=1)
            targets, active, pressed = self._targets(hand, p.poses[i][0].lift_tips, t, modes)
            memory = p.memories[i] = _pressed_memory(
                p.memories[i],
                pressed,
                key_down,
                # As the planner: a re-strike is pushed from its first step.
                self.last_modes[hand.finger_offset : hand.finger_offset + FINGERS] == Mode.RESTRIKE,
                cfg,
            )
            angles = solve_fingers(
                m,
                scratch,
                hand,
                p.poses[i][0].batch,
                targets,
                active,
                memory,
                bent_up[i],
                False,
                cfg,
            )
            ctrl[hand.finger_actuators] = finger_controls(hand, angles)
            off = hand.finger_offset
            self.last_modes[off : off + FINGERS] = np.where(active, modes, Mode.LIFT)
        action = np.empty(m.nu + 1)
        action[:-1] = handle.ctrl_to_action(ctrl)
        press_frame = min(t + cfg.fingers.press_lead_frames, T - 1)
        action[-1] = 1.0 if p.goal.sustain[press_frame] else -1.0
        return action.astype(np.float32)

    def decide(self, t: int) -> np.ndarray:
        """The policy's outputs for every hand at step ``t``, (H, :data:`OUTPUT_DIM`)."""
        self.features = step_features(self.stages, self.next_keys, t, self.last_modes, self.fingers)
        return self.policy.net(self.features)

    def _targets(
        self, hand: Hand, lift_tips: np.ndarray, t: int, modes: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """(5, 3) fingertip targets relative to the forearm, (5,) bool which fingers have
        one, (5,) int the key each presses (-1: none), from the fingers' modes
        (``lift_tips`` (5, 3) m: the lifted fingertips relative to the forearm)."""
        p, cfg, nxt = self.stages, self.stages.config, self.next_keys
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        origin = p.scratch.xpos[hand.forearm_body]
        targets = lift_tips + origin
        active = np.zeros(FINGERS, dtype=bool)
        pressed = np.full(FINGERS, -1)
        for f in range(FINGERS):
            g = hand.finger_offset + f
            frame = nxt.frame[g, t]
            if modes[f] == Mode.LIFT or frame < 0 or frame >= t + WINDOW:
                continue
            key = int(nxt.key[g, t])
            point = press_point(p, key, f)
            top = p.key_top_z[key] + radius
            if modes[f] == Mode.PRESS:
                extra = cfg.keys.thumb_extra_depth_m if f == 0 else 0.0
                point[2] = top - p.key_depth[key] - extra
                pressed[f] = key
            elif modes[f] == Mode.RESTRIKE:
                point[2] = top + cfg.fingers.release_height_m
            else:
                point[2] = top + cfg.fingers.hover_height_m
            targets[f] = point
            active[f] = True
        return targets - origin, active, pressed


class ExpertRecorder(IKPlanner):
    """The planner, recording for every step it acts the policy's features of that state and
    its own decisions as the policy's outputs (its labels): ``features`` and ``labels``,
    lists of (H, D) and (H, :data:`OUTPUT_DIM`) arrays. ``fingering``: the one the policy
    reads (:func:`read_fingering`)."""

    def __init__(self, config: PlannerConfig | None = None, fingering: Fingering = "plan") -> None:
        super().__init__(config)
        self.fingering = fingering

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        super().reset(env, seed)
        self.read_fingers = read_fingering(self, self.fingering)
        self.next_keys = NextKeys.of(self.goal.keys, self.read_fingers)
        self.last_modes = np.zeros(2 * FINGERS, dtype=int)
        self.features: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def act(self, observation: object = None) -> np.ndarray:
        data = self.handle.data
        T = self.goal.num_frames
        t = min(self.handle.step_index, T - 1)
        x = step_features(self, self.next_keys, t, self.last_modes, self.read_fingers)
        before = [(float(data.qpos[h.tx_qpos])) for h in self.hands]
        action = super().act(observation)
        y = np.zeros((len(self.hands), OUTPUT_DIM), dtype=np.float32)
        for i, hand in enumerate(self.hands):
            sign = 1.0 if hand.side == "right" else -1.0
            path = self.plan.hands[i].tx_path
            pos, vel = path[min(t, len(path) - 3) + 1]
            y[i, 0] = encode_move(sign * (pos - before[i]), MOVE_UNIT_M)
            y[i, 1] = encode_move(sign * vel, SPEED_UNIT)
            modes = _modes(hand, self.memories[i], t, self.next_keys)
            onehot = -np.ones((FINGERS, NUM_MODES), dtype=np.float32)
            onehot[np.arange(FINGERS), modes] = 1.0
            y[i, 2:] = onehot.ravel()
            off = hand.finger_offset
            self.last_modes[off : off + FINGERS] = modes
        self.features.append(x)
        self.labels.append(np.clip(y, -1.0, 1.0))
        return action


def _pressed_memory(
    memory: FingerMemory, pressed: np.ndarray, key_down: np.ndarray, let_up: np.ndarray, cfg
) -> FingerMemory:
    """The fingers' memory after a step in which they press the keys ``pressed`` (5,) int
    (-1: none), ``key_down`` (88,) bool being down and ``let_up`` (5,) bool the fingers that
    let their key up the step before: what the IK's pushes read."""
    memory = memory.copy()
    memory.pressing = pressed >= 0
    memory.unsounded, _ = count_unsounded(
        memory.unsounded, memory.pressing, pressed, memory.last_key, key_down, cfg
    )
    memory.repress = mark_represses(memory.pressing, let_up, cfg)
    memory.last_key = pressed
    return memory


def _modes(hand: Hand, memory: FingerMemory, t: int, nxt: NextKeys) -> np.ndarray:
    """(5,) each finger's :class:`Mode` this step as the planner played it (``memory``: its
    fingers' after the step); a finger whose
    next key (by the fingering the policy reads) is not in the window counts as lifted (the
    policy's decoding could not follow it)."""
    from pianist.agents.fingertip.features import mode_of

    modes = np.array(
        [mode_of(int(s), bool(a)) for s, a in zip(memory.state, memory.active, strict=True)]
    )
    for f in range(FINGERS):
        g = hand.finger_offset + f
        frame = nxt.frame[g, t]
        if frame < 0 or frame >= t + WINDOW:
            modes[f] = Mode.LIFT
    return modes
