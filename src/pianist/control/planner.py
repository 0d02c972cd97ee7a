"""An inverse-kinematics planner: plays a song whose notes have hands, with no training.

At reset it plans where each forearm will be along the keyboard over the whole piece, either
frame by frame with the song's fingering (the hand goes where the assigned fingers reach
their keys, and stays while they still do) or over the whole piece at once
(:mod:`pianist.control.hand_plan`: a dynamic programme that also chooses the fingers the
Shadow hand can actually span, and shares keys one hand cannot reach with the other), and
keeps the plan that leaves the most notes playable (``PlannerConfig.hand_planning``). Then
each control step it

1. steers each forearm's slide along that plan: a quick move that ends as the note starts
   (a jump takes the steps the slide's servo needs, on a minimum-jerk path), in closed loop
   through the servo's exact dynamics; for a large move the fingers let go of their keys and
   travel just above the next ones; with the optional height slide (``tz``) the forearm is
   held low enough for the thumb to reach a key's bottom, pushed down harder when the keys
   lift it;
2. gives every fingertip a target: the assigned fingertip pressed below the top of each key
   due at the coming frame (once it is over the key), fingers due soon hovering above their
   keys, the others lifted to a fixed posture clear of the keyboard;
3. solves each finger's inverse kinematics with the wrist held still, so the five fingers are
   independent small problems: the nearest of a few thousand sampled postures of that finger
   (computed once at reset, which avoids the local minima the thumb falls into), then a few
   damped least-squares iterations on ``mujoco.mj_jacSite`` over the finger's actuated joints
   (a J1+J2 tendon counts as one joint, its angle split evenly), clipped to the joint limits;
4. sends those angles as the position-servo controls; the pedal follows the goal.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any, Literal

import gymnasium as gym
import mujoco
import numpy as np
import scipy.linalg
import scipy.spatial

from pianist.control.base import BaseController
from pianist.control.hand_plan import HandPlanCosts, free_frames, move_frames, plan_hand
from pianist.env.handle import control_handle
from pianist.sim import constants as C
from pianist.sim.scene import SceneOptions

if TYPE_CHECKING:
    from pianist.music import Song

FINGERS_PER_HAND = 5
FINGER_PREFIXES = ("TH", "FF", "MF", "RF", "LF")


@dataclass(frozen=True)
class PlannerConfig:
    """Tuning of :class:`IKPlanner`; lengths in m, times in s, angles in rad."""

    white_press_depth_m: float = 0.025
    """How far below a white key's top the fingertip is sent: past the key's travel, so the
    position servo keeps pushing it down."""
    black_press_depth_m: float = 0.045
    """The same for a black key (shorter lever, so it needs more force)."""
    thumb_extra_depth_m: float = 0.02
    """Added to the thumb's press depth: its servos are weak for the force a key needs."""
    thumb_push_rad: float = 0.3
    """Extra command of a pressing thumb along the joint direction that lowers its tip."""
    finger_push_rad: float = 0.0
    """The same for the other fingers."""
    hover_height_m: float = 0.01
    """Clearance above the key top of a finger that is due soon, or not yet over its key."""
    release_height_m: float = 0.003
    """Clearance above the key top a finger goes to between two strikes of one key."""
    lift_height_m: float = 0.035
    """Clearance above the white keys of a finger that is not due."""
    white_press_x_m: float = 0.045
    """Where along a white key (x from its centre, towards the player) a finger presses it,
    in front of the black keys."""
    thumb_white_press_x_m: float = 0.064
    """The same for the thumb, which reaches lowest near the front edge."""
    black_press_x_m: float = 0.01
    """Where along a black key (world x) a finger presses it, near its front end."""
    hand_height_m: float = -0.03
    """Height command of the forearm's ``tz`` slide (when the scene has one)."""
    height_feedback: float = 3.0
    """Gain of the forearm height command on how far the hand has risen above its height."""
    wrist_pose: tuple[float, float] = (0.0, 0.0)
    """WRJ2 and WRJ1, held constant, when the forearm has its height slide."""
    wrist_pose_without_tz: tuple[float, float] = (0.0, 0.25)
    """The same without it: the wrist flexed, else the fingers cannot reach a key's bottom
    from the home height."""
    wrist_feedback: tuple[float, float] = (2.0, 0.0)
    """Gains (WRJ2, WRJ1) of the wrist commands on how far each joint is off its pose. A
    forearm move swings the hand sideways on its soft wrist servo (kp 10): left alone, WRJ2
    is still ~0.04 rad off (4 mm at the fingertips) a step after a shift and then drifts a
    few mm, enough to land a finger beside its key; with the feedback it is back within
    ~0.01 rad. (Stiffening the flexion WRJ1 the same way leaves the thumb too high to sound
    its key.)"""
    skip_out_of_reach: bool = True
    """A chord struck together that no hand position covers (an octave is beyond the Shadow
    hand's span) is played without the keys that cannot be reached along with the most
    others, keeping the outer voice (the bass in the left hand, the top in the right); its
    fingers stay off. Otherwise the hand goes halfway and usually reaches none of them."""
    press_lead_frames: int = 1
    """Frames ahead of the scored frame whose keys the fingers go for (servo lag)."""
    hover_lead_s: float = 0.25
    """How long before its note a finger comes to hover over its key."""
    align_tolerance_m: float = 0.009
    """How close (across the keys) to a white key's press point a finger must be before it
    presses: a finger that lands beside its key sticks to the neighbour by friction."""
    black_align_tolerance_m: float = 0.008
    """The same for a black key. (Half the white one, 4.5 mm, held a finger back for a frame
    while the hand was still settling from a move: every black key of the D major scale
    sounded a frame late.)"""
    align_along_m: float = 0.02
    """How far behind the press point (x) a finger other than the thumb may be and press a
    white key (further back it would land on a black key). Along a black key there is no
    such limit: a finger that slid back on it still presses it."""
    stuck_frames: int = 2
    """Steps a finger may hover off its key without moving before it presses from there."""
    stuck_reach_m: float = 0.013
    """How far off its key (across) a stuck finger may be and still press from there."""
    still_m: float = 0.0015
    """A fingertip that moved less than this in a step stands still."""
    keep_pressing_ratio: float = 1.3
    """A pressing finger keeps pressing until it is this many tolerances off its key."""
    forearm_lead_s: float = 0.05
    """The fingers aim from where the forearm will be this much later at its current velocity
    (0: from where it is)."""
    forearm_move_s: float = 0.05
    """Duration of the forearm's move to a new hand position, ending ``press_lead_frames``
    before the note (a shift: ``shift_lead_frames``): one control step (the slide is steered
    in closed loop, and the wrist held against the swing), so the fingers are off their keys
    as briefly as possible."""
    shift_lead_frames: int = 0
    """Frames before its note a shift (a move the fingers let go for, see
    ``shift_threshold_m``) ends, at most ``press_lead_frames``: 0, the hand arrives as the
    note's frame begins and its fingers press from the hover they travelled in. The keys
    before the shift are then held a frame longer (with 1, the D major scale's F#4 fell
    silent for two frames before the thumb passed under, now for one)."""
    hover_in_shift: bool = True
    """During a large forearm move the fingers of the note it is for hover over their keys
    (instead of taking their lifted posture)."""
    jump_lift_m: float = 0.03
    """...except a finger still low on the keys (within ``jump_low_m`` of the white keys' top)
    whose key is further than this across the keyboard: it takes its lifted posture for the
    move. Skimming towards a key it cannot reach yet, a finger is dragged across the keys and
    sticks to one (in the original's chord progression the right thumb, 9 cm from its next
    C4, caught F4 and held it, and the hand, through the whole last chord)."""
    jump_low_m: float = 0.01
    """Height above the white keys' top below which a finger counts as low (see above)."""
    lazy_m: float = 0.02
    """The hand stays where it is for the next notes if every finger still reaches its key
    from there and it is at most this far from where those notes would put it (0: always
    re-centre). Every move costs the held keys frames; scales gain most."""
    hover_stops_at_shift: bool = True
    """Fingers hover only over keys due before the hand's next large move: the keys after it
    are out of reach from here, and a finger (the thumb above all) that strains towards one
    dips onto the keys on its way."""
    transfer_height_m: float = 0.003
    """Clearance above the key top of a finger going straight from one key to the next (a
    chord change), lower than ``hover_height_m``: the key it leaves rises slowly and holds
    it by friction, so it lands ~1 step sooner from this low path."""
    shift_threshold_m: float = 0.015
    """A forearm move larger than this lifts the hand's fingers for its duration."""
    forearm_separation_m: float = 0.17
    """Closest the two forearm roots may come along the keyboard (they touch below ~0.15)."""
    thumb_offset_m: float = 0.03
    """How far the thumb presses to the left (right hand; mirrored for the left) of the
    index finger's rest position: the thumb, without its rotation joint, reaches key depth
    only under the side of the palm."""
    reach_margin: float = 0.3
    """Part of a finger's sampled reach (across the keys) left unused at each end when a chord
    forces a finger away from its resting place: a finger at the edge of its reach slips."""
    reach_depth_m: float = 0.008
    """How far below a key's top a sampled fingertip must go to count as reaching the key."""
    reach_x_tolerance_m: float = 0.012
    """How close (along the key) to the press point a sampled fingertip must be to count."""
    samples: int = 4000
    """Sampled postures per finger for the nearest-posture start of the IK."""
    hand_planning: Literal["frame", "piece", "best"] = "best"
    """How the hand positions are planned: ``frame`` by frame with the song's fingering,
    staying put within ``lazy_m``; over the whole ``piece``
    (:mod:`pianist.control.hand_plan`) with the fingering ``refinger`` says; or the ``best``
    of the frame-by-frame plan, the whole-piece plan with the song's fingering and the
    whole-piece plan with its own, in that order of preference: a plan is chosen over the
    ones before it only if it leaves at least ``piece_plan_margin`` more of the song's
    key-frames playable (wide chords, jumps, a fingering the Shadow hand cannot span)."""
    piece_plan_margin: float = 0.02
    """Share of the song's key-frames a later plan must add to be chosen (see above)."""
    playable_tolerance_m: float = 0.005
    """How far outside a finger's sampled reach a key still counts as playable when plans
    are compared (the sampled reach is a little conservative: the frame-by-frame plan's
    chords press keys a few mm beyond it)."""
    hand_plan: HandPlanCosts = HandPlanCosts()
    """Weights of the whole-piece plan."""
    share_keys: bool = True
    """With the plan's fingering, offer the keys one hand cannot reach to the other hand."""
    clearance_cost: float = 5.0
    """Per frame, of a planned forearm position closer than ``forearm_separation_m`` to the
    other forearm's (in lost key-frames)."""
    refinger: bool = True
    """With ``hand_planning="piece"``, choose the fingers too (each key to a finger of its hand
    that reaches it from the planned position) instead of the song's: a pianist's fingering
    spans more than the Shadow hand, whose fingers other than the thumb each reach about one
    white key from a given hand position."""
    iterations: int = 3
    damping: float = 0.01
    rest_weight: float = 1e-4
    """Pull towards the sampled start posture (per rad^2, against tip error in m^2)."""
    step_limit_rad: float = 0.3
    """Largest change of one joint in one IK iteration."""


#: Environment options the planner plays best with: the forearm's height slide added. In the
#: paper's action space the Shadow thumb cannot press a white key: with the forearm at its home
#: height its fingertip capsule stops ~1.5 mm above the depth at which a key sounds, even with
#: the wrist flexed (measured by sampling every thumb and wrist angle).
ENV_OPTIONS: dict[str, Any] = {"forearm_dofs": ("tx", "ty", "tz")}


class IKPlanner(BaseController):
    """Plays the song of a :class:`pianist.env.PianoEnv` from its goal frames and fingering.

    Use like any controller: ``reset(env)``, then ``act(observation)`` each step. Needs every
    note fingered and the ``tx`` forearm slide; works with the reduced or the full action
    space and with one or two hands. Without the ``tz`` slide (the paper's scene) the wrist is
    flexed so the fingers reach, but the thumb cannot press a white key at all: it declares
    the slide in :meth:`env_options` (:data:`ENV_OPTIONS`).
    """

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config or PlannerConfig()

    # ----------------------------------------------------------------------------- set-up

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        """The environment the planner plays in (:data:`ENV_OPTIONS`), whatever the song."""
        return dict(ENV_OPTIONS)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        handle = control_handle(env)
        goal = handle.goal
        if np.any(goal.keys & (goal.fingers < 0)):
            raise ValueError(
                "the planner needs a finger for every note; this song has unfingered notes"
            )
        self.handle = handle
        self.model: mujoco.MjModel = handle.model
        self.scratch = mujoco.MjData(self.model)
        self.goal = goal
        self.dt = handle.control_timestep_s
        cfg, m = self.config, self.model
        mujoco.mj_resetData(m, self.scratch)
        mujoco.mj_kinematics(m, self.scratch)
        # Press point and top height of every key, (88, 3) and (88,).
        self.key_top_z = np.where(
            C.BLACK_KEY_MASK,
            C.WHITE_KEY_HEIGHT_M + C.BLACK_KEY_TOP_ABOVE_WHITE_M,
            C.WHITE_KEY_HEIGHT_M,
        )
        self.key_point = self.scratch.site_xpos[handle.scene.key_sites].copy()
        self.key_point[:, 0] = np.where(C.BLACK_KEY_MASK, cfg.black_press_x_m, cfg.white_press_x_m)
        self.key_depth = np.where(
            C.BLACK_KEY_MASK, cfg.black_press_depth_m, cfg.white_press_depth_m
        )
        self.key_qpos = handle.scene.key_qpos
        self.key_threshold = (
            np.where(C.BLACK_KEY_MASK, C.BLACK_KEY_MAX_ANGLE_RAD, C.WHITE_KEY_MAX_ANGLE_RAD)
            - C.KEY_ACTIVATION_THRESHOLD_RAD
        )
        self.hands = [_Hand(m, hand) for hand in handle.scene.hands]
        _use_postures(m, self.scratch, self.hands, cfg, handle.scene.options)
        key = (id(goal), handle.scene.options, cfg)
        cached = _PLANS.get(key)
        if cached is not None and cached[0]() is goal:
            # The same song in the same scene (a new episode): the plan is the same.
            self.plan_kind, self.fingers, hand_plans = cached[1:]
            for hand, arrays in zip(self.hands, hand_plans, strict=True):
                hand.__dict__.update(arrays)
            return
        if cfg.hand_planning == "best":
            candidates = [("frame", False), ("piece", False), ("piece", True)]
            playable = [self._plan(goal, kind, refinger) for kind, refinger in candidates]
            enough = max(playable) - cfg.piece_plan_margin * goal.keys.sum()
            self.plan_kind = candidates[next(i for i, n in enumerate(playable) if n >= enough)]
        else:
            self.plan_kind = (cfg.hand_planning, cfg.refinger and cfg.hand_planning == "piece")
        self._plan(goal, *self.plan_kind)
        if len(_PLANS) >= _PLANS_KEPT:
            del _PLANS[next(iter(_PLANS))]
        hand_plans = [{name: getattr(hand, name) for name in _PLAN_ARRAYS} for hand in self.hands]
        _PLANS[key] = (weakref.ref(goal), self.plan_kind, self.fingers, hand_plans)

    def _plan(self, goal, kind: str, refinger: bool) -> int:
        """Plan the hands' positions, fingers and forearm paths (``kind``: "frame" by frame or
        over the whole "piece"; ``refinger``: the piece plan chooses the fingers); returns the
        key-frames the plan leaves playable."""
        cfg = self.config
        piece = kind == "piece"
        # The finger (0-9) that presses each due key: the song's, or the plan's.
        self.fingers = goal.fingers.copy()
        if piece:
            self._plan_piece(goal, refinger)
        else:
            for hand in self.hands:
                hand.plan_forearm(goal, self.key_point, cfg.lazy_m, cfg.skip_out_of_reach)
        if len(self.hands) == 2:
            _keep_forearms_apart(self.hands[0], self.hands[1], cfg.forearm_separation_m)
        for hand in self.hands:
            hand.plan_commands(self.model, self.dt, cfg, multi_step=piece)
        return sum(hand.playable_keyframes(self) for hand in self.hands)

    def _plan_piece(self, goal, refinger: bool) -> None:
        """The whole-piece plan of both hands (:mod:`pianist.control.hand_plan`).

        The right hand is planned first. With ``share_keys`` (and the plan's fingering), keys
        one hand cannot reach from its plan (an octave, a chord wider than the hand) are
        offered to the other, which plans for its own keys and those, kept clear of the first
        forearm; then the first is planned again the same way. A key both hands would play
        stays with the hand the song gives it.
        """
        cfg = self.config
        hands = sorted(self.hands, key=lambda h: h.side != "right")
        plan = partial(
            _Hand.plan_piece,
            goal=goal,
            key_point=self.key_point,
            dt=self.dt,
            costs=cfg.hand_plan,
            refinger=refinger,
        )
        plan(hands[0])
        if len(hands) == 2:
            first, second = hands
            if refinger and cfg.share_keys:
                plan(second, take=first.skip, extra_cost=first.clearance(second, cfg))
                own_second = second.skip & second.own_keys(goal)
                plan(first, take=own_second, extra_cost=second.clearance(first, cfg))
                for a, b in ((first, second), (second, first)):
                    both = (a.key_fingers >= 0) & (b.key_fingers >= 0)
                    b_loses = both & a.own_keys(goal)
                    b.key_fingers[b_loses] = -1
            else:
                plan(second)
        for hand in self.hands:
            mine = hand.key_fingers >= 0
            self.fingers[mine] = hand.key_fingers[mine] + hand.finger_offset
            hand.skip = goal.keys & ~(hand.key_fingers >= 0) & hand.own_keys(goal)

    # ----------------------------------------------------------------------------- acting

    def act(self, observation: object = None) -> np.ndarray:
        cfg, handle, m, scratch = self.config, self.handle, self.model, self.scratch
        T = self.goal.num_frames
        t = min(handle.step_index, T - 1)  # an episode that ran to its end: hold the last frame
        ctrl = np.array(handle.data.ctrl)
        scratch.qpos[:] = handle.data.qpos
        press_frame = min(t + cfg.press_lead_frames, T - 1)
        hover_end = min(T, press_frame + 1 + round(cfg.hover_lead_s / self.dt))
        for hand in self.hands:
            hand.command_forearm(ctrl, handle.data, t, cfg)
            hand.set_wrist(scratch, ctrl, cfg)
            # The fingers are solved for where the moving forearm will be a little later:
            # their servos lag behind their commands by about a control step.
            scratch.qpos[hand.tx_qpos] += cfg.forearm_lead_s * handle.data.qvel[hand.tx_dof]
        mujoco.mj_kinematics(m, scratch)
        for hand in self.hands:
            targets, active = hand.fingertip_targets(self, t, hover_end)
            hand.solve(m, scratch, targets, active, cfg)
            ctrl[hand.finger_actuators] = hand.finger_controls(scratch)
        action = np.empty(m.nu + 1)
        action[:-1] = handle.ctrl_to_action(ctrl)
        action[-1] = 1.0 if self.goal.sustain[press_frame] else -1.0
        return action.astype(np.float32)


class _Hand:
    """One hand: its indices, posture samples, forearm plan and per-finger IK."""

    def __init__(self, m, hand) -> None:
        self.side = hand.side
        self.finger_offset = 0 if hand.side == "right" else FINGERS_PER_HAND
        self.sites = np.asarray(hand.fingertip_sites)
        prefix = C.HAND_PREFIX[hand.side]
        self.forearm_body = m.body(f"{prefix}forearm").id
        self.tx_qpos = m.jnt_qposadr[m.joint(f"{prefix}forearm_tx").id]
        self.tx_range = m.jnt_range[m.joint(f"{prefix}forearm_tx").id]
        self.tx_actuator = m.actuator(f"{prefix}A_forearm_tx").id
        self.tx_dof = m.jnt_dofadr[m.joint(f"{prefix}forearm_tx").id]
        self.root_y = C.FOREARM_ROOT_POS_M[hand.side][1]
        tz = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{prefix}A_forearm_tz")
        self.tz_actuator = tz if tz >= 0 else None
        self.tz_qpos = m.jnt_qposadr[m.joint(f"{prefix}forearm_tz").id] if tz >= 0 else None
        self.tz_range = m.actuator_ctrlrange[tz] if tz >= 0 else None

        # Actuated joints of each finger (a joint, or a tendon over two joints) and the wrist.
        self.fingers: list[_Finger] = []
        self.wrist: list[tuple[int, np.ndarray]] = []
        for i, finger_prefix in enumerate(FINGER_PREFIXES):
            acts = [
                a
                for a in hand.actuators
                if m.actuator(a).name.startswith(f"{prefix}A_{finger_prefix}")
            ]
            self.fingers.append(_Finger(m, acts, int(self.sites[i])))
        for a in hand.actuators:
            if m.actuator(a).name.startswith(f"{prefix}A_WR"):
                self.wrist.append((int(a), _actuated_qpos(m, a)))
        self.finger_actuators = np.concatenate([f.actuators for f in self.fingers])
        self.jacp = np.zeros((3, m.nv))
        self.pressing = np.zeros(FINGERS_PER_HAND, dtype=bool)
        self.free = np.zeros(0, dtype=bool)
        self.stuck = np.zeros(FINGERS_PER_HAND, dtype=int)
        self.last_tips = np.zeros((FINGERS_PER_HAND, 3))
        self.last_key = np.full(FINGERS_PER_HAND, -1)  # key each finger pressed last, or -1

    # -------------------------------------------------------------------- postures

    def choose_lift_posture(self, m, data, cfg: PlannerConfig) -> None:
        """The lifted posture of each finger and the forearm offsets, from the samples."""
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
        self.rest_tips = data.site_xpos[self.sites] - origin
        self.lift_tips = self.rest_tips.copy()
        self.lift_tips[:, 2] = lift_z - origin[2]
        # Thumb: under the side of the palm, a little more than a key from the index finger.
        side = 1.0 if self.side == "right" else -1.0
        self.lift_tips[0, 1] = self.rest_tips[1, 1] - side * cfg.thumb_offset_m
        for f, finger in enumerate(self.fingers):
            finger.lift = finger.samples[finger.nearest(self.lift_tips[f])]
        # Forearm slide that puts finger f over a key at y: key y - tip_offset_y[f].
        self.tip_offset_y = self.lift_tips[:, 1] + origin[1] - data.qpos[self.tx_qpos]
        self.reach = self._reach(origin, data.qpos[self.tx_qpos], cfg.reach_margin, cfg)
        self.full_reach = self._reach(origin, data.qpos[self.tx_qpos], 0.0, cfg)

    def _reach(
        self, origin: np.ndarray, slide: float, margin: float, cfg: PlannerConfig
    ) -> np.ndarray:
        """(5, 2, 2): per finger, for a white (0) and a black (1) key, the lowest and highest
        key y minus forearm slide at which the finger can press the key.

        From the sampled postures whose fingertip is at the key's press point (x) and below
        its top: the range of their y, shrunk by ``reach_margin`` of its width at each end.
        A finger that never gets there (the thumb on a black key) gets its resting offset.
        """
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        reach = np.repeat(self.tip_offset_y[:, None, None], 2, axis=1).repeat(2, axis=2)
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

    # -------------------------------------------------------------------- forearm

    def lower(self, data, cfg: PlannerConfig) -> None:
        """Put the forearm at its playing height in ``data`` (when it has a height slide)."""
        if self.tz_qpos is not None:
            data.qpos[self.tz_qpos] = cfg.hand_height_m

    def set_wrist(self, data, ctrl: np.ndarray | None, cfg: PlannerConfig) -> None:
        pose = cfg.wrist_pose if self.tz_qpos is not None else cfg.wrist_pose_without_tz
        for (actuator, qpos), angle, gain in zip(
            self.wrist, pose, cfg.wrist_feedback, strict=False
        ):
            off = float(np.mean(data.qpos[qpos])) - angle
            data.qpos[qpos] = angle  # the fingers are solved for the wrist at its pose
            if ctrl is not None:
                ctrl[actuator] = angle - gain * off  # a stiffer servo against the swing

    def own_keys(self, goal) -> np.ndarray:
        """(T, 88) the due keys the song gives this hand."""
        local = goal.fingers - self.finger_offset
        return goal.keys & (local >= 0) & (local < FINGERS_PER_HAND)

    def clearance(self, other: _Hand, cfg: PlannerConfig) -> Callable[[np.ndarray], np.ndarray]:
        """Candidate slide positions of ``other`` (P,) -> (T, P) cost of coming closer than
        ``forearm_separation_m`` to this hand's planned forearm (they would collide) while
        this hand plays (when it does not, it makes way: ``_keep_forearms_apart``)."""
        sign = 1.0 if self.side == "right" else -1.0  # this forearm's side of the other

        def cost(grid: np.ndarray) -> np.ndarray:
            gap = sign * ((self.tx_plan[:, None] + self.root_y) - (grid[None, :] + other.root_y))
            close = (gap < cfg.forearm_separation_m) & self.busy[:, None]
            return np.where(close, cfg.clearance_cost, 0.0)

        return cost

    def plan_piece(
        self,
        goal,
        key_point: np.ndarray,
        dt: float,
        costs: HandPlanCosts,
        refinger: bool,
        take: np.ndarray | None = None,
        extra_cost: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        """The forearm slide position at every frame from the whole-piece plan
        (:func:`pianist.control.hand_plan.plan_hand`), with its ``busy``, ``skip`` and
        ``key_fingers`` (T, 88), this hand's finger 0-4 of each due key (-1: none).

        ``take``: (T, 88) further keys (the other hand's) to play if the plan can
        (``refinger`` only); ``extra_cost``: see :func:`plan_hand`.
        """
        local = goal.fingers - self.finger_offset
        local = np.where((local >= 0) & (local < FINGERS_PER_HAND), local, -1)
        if take is not None:
            local = np.where(take & (local < 0), 0, local)  # any finger: the plan chooses
        plan = plan_hand(
            goal.keys,
            local,
            key_point[:, 1],
            C.BLACK_KEY_MASK,
            self.full_reach,
            self.reach,
            self.tip_offset_y,
            (float(self.tx_range[0]), float(self.tx_range[1])),
            start=0.0,
            dt=dt,
            outer="top" if self.side == "right" else "bottom",
            costs=costs,
            refinger=refinger,
            extra_cost=extra_cost,
        )
        self.tx_plan, self.busy, self.skip = plan.position, plan.busy, plan.skip
        self.key_fingers = plan.fingers

    def plan_forearm(
        self,
        goal,
        key_point: np.ndarray,
        lazy_m: float = 0.0,
        skip_out_of_reach: bool = False,
    ) -> None:
        """Forearm slide position wanted at every frame, shape (T,).

        The position that puts each assigned finger at its resting place over its key (the
        mean over the hand's due keys), moved as little as needed to bring every one of those
        keys within its finger's reach: a wide chord otherwise leaves the thumb pressing at
        the edge of its reach, where it slips off the key. With ``lazy_m`` > 0 the hand
        rather stays where it was while every finger still reaches from there (and it is at
        most ``lazy_m`` from that position). With ``skip_out_of_reach``, the keys of a chord
        no position covers are left out, as ``skip`` (T, 88) records (see ``PlannerConfig``).
        """
        T = goal.num_frames
        wanted = np.full(T, np.nan)
        # Keys of this hand it leaves out: a chord wider than the hand (an octave, say).
        self.skip = np.zeros((T, goal.keys.shape[1]), dtype=bool)
        onset = _note_onsets(goal.keys)
        previous = np.nan
        for t in range(T):
            keys = np.flatnonzero(goal.keys[t])
            fingers = goal.fingers[t, keys]
            mine = (fingers >= self.finger_offset) & (fingers < self.finger_offset + 5)
            if not mine.any():
                continue
            keys, local = keys[mine], fingers[mine] - self.finger_offset
            y = key_point[keys, 1]
            reach = self.reach[local, C.BLACK_KEY_MASK[keys].astype(int)]  # (n, 2)
            low, high = np.max(y - reach[:, 1]), np.min(y - reach[:, 0])
            centre = np.mean(y - self.tip_offset_y[local])
            full = self.full_reach[local, C.BLACK_KEY_MASK[keys].astype(int)]
            first, last = y - full[:, 1], y - full[:, 0]  # slide range each key allows
            if skip_out_of_reach and np.max(first) > np.min(last) and len(set(onset[t, keys])) == 1:
                # A chord struck together that no hand position covers: play the most of its
                # keys that one position reaches, the outer voice (the bass in the left hand,
                # the top in the right) among them, rather than none from halfway.
                outer = np.argmax(y) if self.side == "right" else np.argmin(y)
                best = max(
                    np.concatenate([first, last]),
                    key=lambda p: (
                        np.sum((first <= p + 1e-9) & (p - 1e-9 <= last)),
                        first[outer] <= p <= last[outer],
                    ),
                )
                kept = (first <= best + 1e-9) & (best - 1e-9 <= last)
                self.skip[t, keys[~kept]] = True
                keys, local, y, reach = keys[kept], local[kept], y[kept], reach[kept]
                low, high = np.max(y - reach[:, 1]), np.min(y - reach[:, 0])
                centre = np.mean(y - self.tip_offset_y[local])
            # Out of reach together: halfway between what the two worst-off fingers need.
            wanted[t] = np.clip(centre, low, high) if low <= high else (low + high) / 2
            if lazy_m > 0 and low <= high and np.isfinite(previous):
                # Stay where the fingers still reach: every move costs frames.
                if max(low, centre - lazy_m) <= previous <= min(high, centre + lazy_m):
                    wanted[t] = previous
            previous = wanted[t]
        # Between notes, hold the next note's position (go there early); after the last, stay.
        self.busy = ~np.isnan(wanted)
        known = np.flatnonzero(self.busy)
        if known.size == 0:
            wanted[:] = 0.0
        else:
            nxt = np.minimum(np.searchsorted(known, np.arange(T)), known.size - 1)
            fill = np.isnan(wanted)
            wanted[fill] = wanted[known[nxt[fill]]]
        self.tx_plan = np.clip(wanted, *self.tx_range)

    def playable_keyframes(self, planner: IKPlanner) -> int:
        """Key-frames of this hand's plan that a finger can press: not skipped, not during a
        shift, and within the finger's reach from the planned position."""
        goal = planner.goal
        frames, keys = np.nonzero(goal.keys & ~self.skip & ~self.free[:, None])
        finger = planner.fingers[frames, keys] - self.finger_offset
        mine = (finger >= 0) & (finger < FINGERS_PER_HAND)
        frames, keys, finger = frames[mine], keys[mine], finger[mine]
        lo, hi = self.full_reach[finger, C.BLACK_KEY_MASK[keys].astype(int)].T
        relative = planner.key_point[keys, 1] - self.tx_plan[frames]
        tolerance = planner.config.playable_tolerance_m
        return int(np.sum((relative >= lo - tolerance) & (relative <= hi + tolerance)))

    def plan_commands(self, m, dt: float, cfg: PlannerConfig, multi_step: bool) -> None:
        """The forearm's reference path along the keyboard, ``tx_path`` (T + 2, 2): position
        and velocity wanted at the end of every step.

        With ``multi_step`` (the whole-piece plan), a jump takes the steps the slide needs
        (:func:`pianist.control.hand_plan.move_frames`) on a minimum-jerk path, the fingers
        lifted a step before it; otherwise every move takes ``forearm_move_s``.

        The plan's steps become minimum-jerk moves of ``forearm_move_s`` that end
        ``press_lead_frames`` before the note starts (``shift_lead_frames`` for a shift the
        fingers let go for); ``command_forearm`` then steers the
        slide's servo along that path in closed loop. Left alone, the critically damped
        servo needs ~0.45 s to cover 90 % of a jump, which makes the hand late for every
        shift (and for the first note, which the hands reach from their home position).
        """
        plan = self.tx_plan
        T = len(plan)
        n = max(1, round(cfg.forearm_move_s / dt))
        # A pressed finger pins the hand to its key by friction: before a shift too large for
        # the fingers to absorb, the hand lets go of its keys for the move's duration.
        self.free = np.zeros(T, dtype=bool)
        self.shift_to = np.zeros(T, dtype=int)  # during a move: the frame of the note it is for
        # Moves end ``press_lead_frames`` before the note, so that fingers press a still hand;
        # shifts ``shift_lead_frames`` before it, so that the keys before them are held longer.
        lead = cfg.press_lead_frames
        if not 0 <= cfg.shift_lead_frames <= lead:
            raise ValueError("shift_lead_frames must be between 0 and press_lead_frames")
        shifts = np.flatnonzero(np.abs(np.diff(plan)) > cfg.shift_threshold_m) + 1
        delay = lead - cfg.shift_lead_frames
        # Steps each shift takes: a long jump needs more than one (the slide's servo has a
        # limited force); the whole-piece plan knows this and has paid for the frames.
        if multi_step:
            need = move_frames(plan[shifts] - plan[shifts - 1], dt)
        else:
            need = np.full(len(shifts), n)
        lift_first = np.zeros(len(shifts), dtype=int)
        if multi_step:
            lift_first = free_frames(plan[shifts] - plan[shifts - 1], dt) - need
        for k, steps, extra in zip(
            shifts.tolist(), need.tolist(), lift_first.tolist(), strict=True
        ):
            window = slice(max(0, k - steps - extra - lead + delay), max(0, k - lead + delay))
            self.free[window] = True
            self.shift_to[window] = k
        if delay:
            # The path below ends every move ``lead`` frames early: hold the old position
            # ``delay`` frames longer before each shift (later shifts first, so that a shift
            # that follows another keeps its own start).
            plan = plan.copy()
            for k in shifts[::-1]:
                plan[k : min(T, k + delay)] = self.tx_plan[k - 1]
        s = (np.arange(n) + 0.5) / n
        weights = s**2 * (1 - s) ** 2  # minimum-jerk velocity profile
        weights /= weights.sum()
        padded = np.concatenate([plan, np.full(n + 3 + lead, plan[-1])])
        # y[t]: where the forearm should be at the end of step t (two steps past the end too).
        y = np.array([weights @ padded[t + 1 + lead : t + 1 + lead + n] for t in range(T + 2)])
        if multi_step:
            # A jump that takes several steps follows a minimum-jerk path over them, arriving
            # when a one-step move would (not starting before the previous shift has ended):
            # its first step is small, so the fingers are off the keys before the hand flies.
            previous = 0
            for k, steps in zip(shifts.tolist(), need.tolist(), strict=True):
                arrive = k + delay - 1 - lead  # the first step whose end is at the new place
                begin = max(previous, arrive - steps + 1)
                if arrive - begin >= 1:
                    u = (np.arange(begin, arrive + 1) - begin + 1) / (arrive - begin + 1)
                    start, end = y[begin - 1] if begin else y[0], y[arrive]
                    y[begin : arrive + 1] = start + (end - start) * (
                        10 * u**3 - 15 * u**4 + 6 * u**5
                    )
                previous = arrive + 1
        ext = np.concatenate([[y[0]], y, [y[-1]]])
        self.tx_path = np.stack([y, (ext[2:] - ext[:-2]) / (2 * dt)], axis=1)
        self.tx_servo = _Servo(m, self.tx_actuator, self.tx_dof, dt)

    def command_forearm(self, ctrl: np.ndarray, data, t: int, cfg: PlannerConfig) -> None:
        # The fingers are solved for where the forearm actually is (see ``forearm_lead_s``),
        # not for its plan: they then reach their keys even while it is still on its way.
        t = min(t, len(self.tx_path) - 3)
        state = np.array([data.qpos[self.tx_qpos], data.qvel[self.tx_dof]])
        ctrl[self.tx_actuator] = self.tx_servo.command(state, self.tx_path[t + 1])
        if self.tz_actuator is not None:
            assert self.tz_qpos is not None and self.tz_range is not None  # set with tz_actuator
            # The keys push the hand up (about a centimetre under a chord): pressing harder the
            # further it has risen stiffens the slide's servo against them.
            rise = data.qpos[self.tz_qpos] - cfg.hand_height_m
            command = cfg.hand_height_m - cfg.height_feedback * rise
            ctrl[self.tz_actuator] = np.clip(command, *self.tz_range)

    # -------------------------------------------------------------------- fingers

    def fingertip_targets(
        self, planner: IKPlanner, now: int, hover_end: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """(5, 3) fingertip targets relative to the forearm, and which fingers have one.

        Keys scored at the end of this step (frame ``now``) are held down to its end; keys
        due at the next frame are pressed already (the servos lag about a frame), except a key
        that is still down and must sound again: it is let up for this step first. Fingers due
        later hover over their keys; the rest take their lifted posture.
        """
        cfg, goal = planner.config, planner.goal
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        origin = planner.scratch.xpos[self.forearm_body]
        real_tips = planner.handle.data.site_xpos[self.sites]
        targets = self.lift_tips + origin
        active = np.zeros(FINGERS_PER_HAND, dtype=bool)
        self.pressing = np.zeros(FINGERS_PER_HAND, dtype=bool)
        if self.free[now]:
            self.last_key[:] = -1
        if self.free[now] and cfg.hover_in_shift:
            # The hand is moving: the fingers of the note it moves for travel with it just
            # above their keys, the others stay lifted.
            self._hover_over(planner, self.shift_to[now], targets, active)
            # A finger still on the keys with far to go comes up first (``jump_lift_m``).
            low = real_tips[:, 2] < C.WHITE_KEY_HEIGHT_M + radius + cfg.jump_low_m
            far = active & low & (np.abs(targets[:, 1] - real_tips[:, 1]) > cfg.jump_lift_m)
            active[far] = False
            targets[far] = self.lift_tips[far] + origin
            return targets - origin, active
        lead = min(now + cfg.press_lead_frames, goal.num_frames - 1)
        key_down = planner.handle.data.qpos[planner.key_qpos] >= planner.key_threshold
        hovering = np.zeros(FINGERS_PER_HAND, dtype=bool)
        pressed_key = np.full(FINGERS_PER_HAND, -1)
        for frame in (now, lead):
            for key in np.flatnonzero(goal.keys[frame] & ~self.skip[frame]):
                finger = planner.fingers[frame, key] - self.finger_offset
                if not 0 <= finger < FINGERS_PER_HAND or active[finger]:
                    continue
                point = self._press_point(planner, int(key), finger)
                top = planner.key_top_z[key] + radius
                targets[finger] = point
                active[finger] = True
                if frame != now and key_down[key]:
                    targets[finger, 2] = top + cfg.release_height_m  # re-strike: up first
                    continue
                if self.free[frame]:
                    # The hand is moving: its fingers stay clear, or they catch on keys.
                    targets[finger] = self.lift_tips[finger] + origin
                    continue
                black = C.BLACK_KEY_MASK[key]
                tolerance = cfg.black_align_tolerance_m if black else cfg.align_tolerance_m
                # Across the keys is what matters; along a key a few mm either way still press,
                # but a finger too far back over a white key would land on a black one.
                miss = abs(real_tips[finger, 1] - point[1])
                if finger and not black and real_tips[finger, 0] < point[0] - cfg.align_along_m:
                    miss = np.inf
                down = real_tips[finger, 2] < top
                # A pressing finger keeps pressing while it stays roughly on its key; one that
                # slid off (beside a black key, say) comes up to try again.
                # A finger that hovers off its key and no longer moves cannot get closer at
                # that height (the thumb under the palm, say): it goes down from where it is.
                stuck = self.stuck[finger] >= cfg.stuck_frames and miss <= cfg.stuck_reach_m
                if (
                    miss <= tolerance
                    or (down and miss <= cfg.keep_pressing_ratio * tolerance)
                    or stuck
                ):
                    extra = cfg.thumb_extra_depth_m if finger == 0 else 0.0
                    targets[finger, 2] = top - planner.key_depth[key] - extra
                    self.pressing[finger] = True
                    pressed_key[finger] = key
                else:
                    transfer = self.last_key[finger] >= 0 and self.last_key[finger] != key
                    height = cfg.transfer_height_m if transfer else cfg.hover_height_m
                    targets[finger, 2] = top + height
                    hovering[finger] = True
        # A finger keeps its last key while it presses or hovers on its way to the next one.
        self.last_key = np.where(self.pressing, pressed_key, np.where(hovering, self.last_key, -1))
        # Count the steps each hovering finger has stood still.
        still = np.linalg.norm(real_tips - self.last_tips, axis=1) < cfg.still_m
        self.stuck = np.where(hovering & still, self.stuck + 1, 0)
        self.last_tips = real_tips.copy()
        for t in range(lead + 1, hover_end if not self.free[now] else lead + 1):
            if self.free[t] and cfg.hover_stops_at_shift:
                break  # keys past a shift are out of reach from here
            self._hover_over(planner, t, targets, active)
        return targets - origin, active

    def _hover_over(
        self, planner: IKPlanner, frame: int, targets: np.ndarray, active: np.ndarray
    ) -> None:
        """Send each finger without a target yet to hover over its key due at ``frame``
        (world frame, in place)."""
        goal = planner.goal
        height = C.FINGERTIP_CAPSULE_RADIUS_M + planner.config.hover_height_m
        for key in np.flatnonzero(goal.keys[frame] & ~self.skip[frame]):
            finger = planner.fingers[frame, key] - self.finger_offset
            if 0 <= finger < FINGERS_PER_HAND and not active[finger]:
                targets[finger] = self._press_point(planner, int(key), finger)
                targets[finger, 2] = planner.key_top_z[key] + height
                active[finger] = True

    def _press_point(self, planner: IKPlanner, key: int, finger: int) -> np.ndarray:
        point = planner.key_point[key].copy()
        if finger == 0 and not C.BLACK_KEY_MASK[key]:
            point[0] = planner.config.thumb_white_press_x_m
        return point

    def solve(self, m, scratch, targets: np.ndarray, active: np.ndarray, cfg) -> None:
        """Set each finger's joints in ``scratch``: nearest sampled posture, then DLS."""
        for f, finger in enumerate(self.fingers):
            if active[f]:
                finger.angles = finger.samples[finger.nearest(targets[f])].copy()
            else:
                finger.angles = finger.lift.copy()
            finger.set(scratch, finger.angles)
        if not active.any():
            return
        for _ in range(cfg.iterations):
            mujoco.mj_kinematics(m, scratch)
            mujoco.mj_comPos(m, scratch)  # mj_jacSite reads cdof and subtree centres
            origin = scratch.xpos[self.forearm_body]
            for f in np.flatnonzero(active).tolist():
                finger = self.fingers[f]
                error = targets[f] - (scratch.site_xpos[finger.site] - origin)
                mujoco.mj_jacSite(m, scratch, self.jacp, None, finger.site)
                J = finger.jacobian(self.jacp)
                A = J.T @ J + (cfg.damping**2 + cfg.rest_weight) * np.eye(finger.dof)
                step = np.linalg.solve(A, J.T @ error)
                step = np.clip(step, -cfg.step_limit_rad, cfg.step_limit_rad)
                finger.angles = np.clip(finger.angles + step, finger.low, finger.high)
                finger.set(scratch, finger.angles)
        # A pressing finger is commanded further along the joint direction that lowers its
        # tip: the position servos' force grows with that error, and a target out of reach
        # (often the thumb's) leaves the IK at the boundary with too little error to push.
        if not self.pressing.any():
            return
        mujoco.mj_kinematics(m, scratch)
        mujoco.mj_comPos(m, scratch)
        for f in np.flatnonzero(self.pressing).tolist():
            finger = self.fingers[f]
            amount = cfg.thumb_push_rad if f == 0 else cfg.finger_push_rad
            mujoco.mj_jacSite(m, scratch, self.jacp, None, finger.site)
            down = -finger.jacobian(self.jacp)[2]
            norm = np.linalg.norm(down)
            if amount > 0 and norm > 0:
                push = finger.angles + amount * down / norm
                finger.angles = np.clip(push, finger.low, finger.high)

    def finger_controls(self, scratch) -> np.ndarray:
        return np.concatenate([f.angles for f in self.fingers])


class _Finger:
    """The actuated joints of one finger: actuator ids, limits, how to set and differentiate."""

    lift: np.ndarray
    """The lifted posture (dof,), chosen by :meth:`_Hand.choose_lift_posture`."""

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


#: A hand's plan for a song: what ``IKPlanner._plan`` sets (read only once made).
_PLAN_ARRAYS = ("tx_plan", "busy", "skip", "free", "shift_to", "tx_path", "tx_servo")
#: Plans by (goal frames, scene options, config): a new episode of the same environment
#: reuses its plan (up to ~1 s for a minute of music) instead of making it again.
_PLANS: dict[tuple[int, SceneOptions, PlannerConfig], tuple[Any, ...]] = {}
_PLANS_KEPT = 8

#: Posture samples of every finger, (samples (S, dof), fingertips (S, 3)) per finger, keyed by
#: the scene's options (the model is built from them deterministically) and the planner's
#: config: sampling takes ~0.15 s, most of a short episode's reset, and is the same each time.
_Postures = list[tuple[np.ndarray, np.ndarray, scipy.spatial.cKDTree]]
_POSTURES: dict[tuple[SceneOptions, PlannerConfig], _Postures] = {}
_POSTURES_KEPT = 8  # scenes x configs kept per process (~2 MB each)


def _use_postures(
    m, data, hands: list[_Hand], cfg: PlannerConfig, scene_options: SceneOptions
) -> None:
    """Give every finger its posture samples (sampled once per scene and config, see
    :data:`_POSTURES`), then choose each hand's lifted posture."""
    key = (scene_options, cfg)
    samples = _POSTURES.get(key)
    if samples is None:
        # The samples do not depend on the episode: always the same generator seed.
        samples = _sample_postures(m, data, hands, cfg, np.random.default_rng(0))
        if len(_POSTURES) >= _POSTURES_KEPT:
            del _POSTURES[next(iter(_POSTURES))]
        _POSTURES[key] = samples
    fingers = [finger for hand in hands for finger in hand.fingers]
    for finger, (angles, tips, tree) in zip(fingers, samples, strict=True):
        finger.index_samples(angles, tips, tree)
    for hand in hands:
        hand.choose_lift_posture(m, data, cfg)


def _sample_postures(
    m, data, hands: list[_Hand], cfg: PlannerConfig, rng: np.random.Generator
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


class _Servo:
    """A position-servo slide as the linear system ``M q'' = kp (u - q) - c q'``, discretised
    exactly over one control step (the command is held constant through the step)."""

    def __init__(self, m, actuator: int, dof: int, dt: float) -> None:
        kp = m.actuator_gainprm[actuator, 0]
        c = -m.actuator_biasprm[actuator, 2] + m.dof_damping[dof]
        mass = m.dof_M0[dof]
        # Augmented matrix exponential: the transition (2, 2) and the command's effect (2,).
        a = np.zeros((3, 3))
        a[0, 1] = 1.0
        a[1] = [-kp / mass, -c / mass, kp / mass]
        e = scipy.linalg.expm(a * dt)
        phi, gamma = e[:2, :2], e[:2, 2]
        self.phi2 = phi @ phi
        # Two steps' commands (u0, u1) -> state after them: phi gamma u0 + gamma u1.
        self.inverse = np.linalg.inv(np.stack([phi @ gamma, gamma], axis=1))
        self.low, self.high = m.actuator_ctrlrange[actuator]

    def command(self, state: np.ndarray, target: np.ndarray) -> float:
        """This step's command, shape (), to reach ``target`` (position m, velocity m/s) at the
        end of the next step from ``state``: the first of the two commands that get there
        exactly (re-solved every step from the measured state, so it corrects for contacts)."""
        u0, _ = self.inverse @ (target - self.phi2 @ state)
        return float(np.clip(u0, self.low, self.high))


def _actuated_joints(m, actuator: int) -> np.ndarray:
    if m.actuator_trntype[actuator] == mujoco.mjtTrn.mjTRN_TENDON:
        tendon = m.actuator_trnid[actuator, 0]
        start, count = m.tendon_adr[tendon], m.tendon_num[tendon]
        return m.wrap_objid[start : start + count]
    return np.array([m.actuator_trnid[actuator, 0]])


def _actuated_qpos(m, actuator: int) -> np.ndarray:
    return m.jnt_qposadr[_actuated_joints(m, actuator)]


def _rest_angles(m, finger: _Finger) -> np.ndarray:
    """A relaxed playing posture: knuckles bent a little, fingertips pointing down."""
    angles = np.zeros(finger.dof)
    for i, name in enumerate(finger.names):
        if name.endswith("J3") and "TH" not in name:
            angles[i] = 0.6
        elif name.endswith("J0"):
            angles[i] = 1.0
    return np.clip(angles, finger.low, finger.high)


def _note_onsets(keys: np.ndarray) -> np.ndarray:
    """(T, 88) int: the first frame of the note covering each due key (-1 where none)."""
    onset = np.full(keys.shape, -1)
    for t in range(keys.shape[0]):
        started = keys[t] & ~(keys[t - 1] if t else np.zeros_like(keys[t]))
        onset[t] = np.where(started, t, np.where(keys[t], onset[t - 1] if t else -1, -1))
    return onset


def _keep_forearms_apart(a: _Hand, b: _Hand, separation: float) -> None:
    """Shift the forearm plans so the right forearm stays ``separation`` m right of the left.

    A hand with nothing to play yields to the other; when both play, both give way equally.
    """
    right, left = (a, b) if a.side == "right" else (b, a)
    y_right = right.tx_plan + right.root_y
    y_left = left.tx_plan + left.root_y
    short = np.maximum(separation - (y_right - y_left), 0.0)
    right_share = np.where(
        right.busy & ~left.busy, 0.0, np.where(left.busy & ~right.busy, 1.0, 0.5)
    )
    right.tx_plan = np.clip(right.tx_plan + short * right_share, *right.tx_range)
    left.tx_plan = np.clip(left.tx_plan - short * (1 - right_share), *left.tx_range)
