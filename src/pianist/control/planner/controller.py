"""The controller, :class:`IKPlanner`: its reset (postures, hand plans) and its step.

``reset(env)`` reads the environment through its control handle, sets the keys' press
points and heights (see :class:`PlannerState`), reads the hands' indices (:class:`Hand`),
makes their poses with their posture samples (:mod:`postures`), and plans the hands: frame
by frame, over the whole piece, or the best of those plans (``PlanConfig.hand_planning``),
a :class:`~pianist.control.planner.plans.Plan` kept in :attr:`IKPlanner.cache` (:mod:`plans`)
for the next episode of the same song and scene.

``act()`` returns the action, shape (nu + 1,) float32 in [-1, 1]: the forearm slides'
commands (:mod:`forearm`), the wrist's (:mod:`postures`), each finger's joint angles
(:mod:`targets`, then :mod:`ik`), and the sustain pedal from the goal. Each stage is a
function of the hand, its pose, its plan's arrays and its fingers' memory
(:class:`FingerMemory`, which the controller keeps per hand between steps).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import mujoco
import numpy as np

from pianist.control.base import BaseController
from pianist.control.lookahead import LookAhead
from pianist.control.planner.config import (
    ENV_OPTIONS,
    FINGERS_PER_HAND,
    PAPER_ENV_OPTIONS,
    PLAN_CANDIDATES,
    TURN_FOR_SPANS,
    WHOLE_HAND_POSES,
    PlanKind,
    PlannerConfig,
)
from pianist.control.planner.coverage import (
    Coverage,
    plan_coverage,
    plan_key_classes,
    playable_mask,
)
from pianist.control.planner.forearm import (
    SlideServo,
    clearance,
    command_forearm,
    command_height,
    frame_plan,
    keep_forearms_apart,
    piece_plan,
    plan_commands,
    played_counts,
    reach_model,
)
from pianist.control.planner.hand import FingerMemory, Hand
from pianist.control.planner.hand_order import uncross_hands
from pianist.control.planner.hand_plan import HandPlan
from pianist.control.planner.hand_split import HandReach, SplitCosts, split_hands
from pianist.control.planner.ik import descent_directions, finger_controls, solve_fingers
from pianist.control.planner.plans import PLANS, CachedPlan, Plan, PlanCache
from pianist.control.planner.postures import HandPose, hand_poses, set_wrist
from pianist.control.planner.rehearsal import Replay, f1_lost, rehearse
from pianist.control.planner.strike_prediction import Push, Strike, apply_predictions
from pianist.control.planner.strikes import plan_strikes
from pianist.control.planner.targets import fingertip_targets
from pianist.control.rollout_ahead import RolloutAhead
from pianist.control.scoring import step_f1
from pianist.env.handle import ControlHandle, control_handle
from pianist.sim import constants as C

if TYPE_CHECKING:
    from pianist.music import Song

#: Frames before the first frame at which a candidate plan differs from the first one
#: rehearsed where its own rehearsal starts (the planner's step reads the plan up to
#: ``press_lead_frames`` + ``hover_lead_s`` and a shift's window ahead: ~8 frames).
REHEARSAL_MARGIN_FRAMES = 20


class IKPlanner(BaseController):
    """Plays the song of a :class:`pianist.env.PianoEnv` from its goal frames and fingering.

    Use like any controller: ``reset(env)``, then ``act(observation)`` each step. Needs every
    note fingered and the ``tx`` forearm slide; works with the reduced or the full action
    space and with one or two hands. Without the ``tz`` slide (the paper's scene) the wrist is
    flexed so the fingers reach, but the thumb cannot press a white key at all: it declares
    the slide in :meth:`env_options` (:data:`ENV_OPTIONS`).
    """

    plan_kind: PlanKind
    """How the plan in use was made (:attr:`~pianist.control.planner.plans.Plan.kind`)."""
    hands: list[Hand]
    """The hands' indices, in the scene's order (set up at reset)."""
    poses: list[tuple[HandPose, ...]]
    """Per hand, every pose it may take, the home pose first."""
    plan: Plan
    """The plan being played: each hand's arrays (``plan.hands``, in the order of
    ``hands``) and the fingering."""
    memories: list[FingerMemory]
    """Per hand, what its fingers remember from the last step."""

    def __init__(self, config: PlannerConfig | None = None, cache: PlanCache | None = None) -> None:
        self.config = config or PlannerConfig()
        self.cache = PLANS if cache is None else cache
        """Where the plans made at reset are kept for the next episode of the same song and
        scene (default: the planners' shared :data:`~pianist.control.planner.plans.PLANS`)."""
        self._coverage: Coverage | None = None
        self._whole_hand: dict[str, list[HandReach]] | None = None
        self._planned = False  # a plan is made at reset
        self._replay: Replay | None = None  # the chosen plan's rehearsal, to play again
        self.rehearsed: dict[str, float] = {}
        """The F1 each candidate plan rehearsed to at the last reset, by name: for a rehearsal
        given up once it could no longer win, the most it could still have reached; a
        candidate whose plan is the same as an earlier one's is not rehearsed (absent), and
        without rehearsal the dict is empty."""
        self.rehearsed_from: dict[str, int] = {}
        """The step each rehearsed candidate's rehearsal started from at the last reset (0:
        the start; later: the plan is the first one's until then, whose steps it took)."""

    # ----------------------------------------------------------------------------- set-up

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        """The environment the planner plays in (:data:`ENV_OPTIONS`, or with
        ``paper_embodiment`` the paper's scene), whatever the song."""
        return dict(PAPER_ENV_OPTIONS if self.config.paper_embodiment else ENV_OPTIONS)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self._coverage, self._planned, self._replay, self.rehearsed = None, True, None, {}
        self.rehearsed_from = {}
        self._whole_hand = None
        self.setup(env)
        goal, handle, cfg = self.goal, self.handle, self.config
        cached = self.cache.get(goal, handle.scene.options, cfg)
        if cached is not None:
            # The same song in the same scene (a new episode): the plan is the same, and so
            # is its rehearsal (replayed only while the episode stays on its path).
            self._replay, self.rehearsed = cached.replay, dict(cached.rehearsed)
            self.rehearsed_from = dict(cached.rehearsed_from)
            self._restore(cached.plan)
            self._play_tape()
            return
        if cfg.plan.hand_planning == "best":
            chosen = self._choose_plan(goal, seed)
        else:
            refinger = cfg.plan.hand_planning == "split" or (
                cfg.plan.refinger and cfg.plan.hand_planning == "piece"
            )
            chosen = self._plan(
                goal, PlanKind(cfg.plan.hand_planning, refinger, cfg.plan.hand_plan.objective)
            )
        entry = CachedPlan(chosen, self._replay, dict(self.rehearsed), dict(self.rehearsed_from))
        self.cache.put(goal, handle.scene.options, cfg, entry)
        self._play_tape()

    def _play_tape(self) -> None:
        """Give the environment the chosen rehearsal's steps to play back (``replay_tape``;
        taken only if the episode is where the rehearsal started)."""
        if self._replay is not None and self.config.plan.replay_tape:
            self.handle.play_tape(self._replay.tape)

    def setup(self, env: gym.Env) -> None:
        """The per-episode set-up without the plan: the keys' press points and heights, the
        hands with their posture samples and lifted postures (what the execution stages need;
        :class:`pianist.agents.fingertip` acts with them and no plan).

        Raises:
            ValueError: the song has unfingered notes.
        """
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
        self.key_point[:, 0] = np.where(
            C.BLACK_KEY_MASK, cfg.keys.black_press_x_m, cfg.keys.white_press_x_m
        )
        self.key_depth = np.where(
            C.BLACK_KEY_MASK, cfg.keys.black_press_depth_m, cfg.keys.white_press_depth_m
        )
        self.strikes = plan_strikes(
            goal,
            cfg.strikes.push_below_velocity,
            cfg.strikes.push_lag_frames,
            cfg.strikes.push_speed_scale,
            cfg.strikes.predict_strikes,
        )
        self.key_qpos = handle.scene.key_qpos
        self.key_threshold = (
            np.where(C.BLACK_KEY_MASK, C.BLACK_KEY_MAX_ANGLE_RAD, C.WHITE_KEY_MAX_ANGLE_RAD)
            - C.KEY_ACTIVATION_THRESHOLD_RAD
        )
        self.hands = [Hand.build(m, hand, cfg.full_hand) for hand in handle.scene.hands]
        self.servos = [SlideServo.of(m, hand, self.dt) for hand in self.hands]
        self.memories = [FingerMemory() for _ in self.hands]
        self.hand_settings: list[PlannerConfig | None] = [None for _ in self.hands]
        # (T, 10) each finger's FingerState per step, as played (see plan_arrays).
        self.finger_states = np.zeros((goal.num_frames, 2 * FINGERS_PER_HAND), dtype=np.int8)
        self.poses = hand_poses(m, self.scratch, self.hands, cfg, handle.scene.options)
        self.fingers = goal.fingers

    def _choose_plan(self, goal, seed: int | None) -> Plan:
        """Make each plan of ``best_candidates`` and choose one (``choose_plan``): by
        rehearsal (:meth:`_rehearse_plans`, from the environment's state, or from its reset
        with ``seed`` if it has not started an episode), or the first that leaves playable all but
        ``piece_plan_margin`` of the most key-frames any leaves."""
        cfg = self.config
        plans = []
        for name in cfg.plan.best_candidates:
            plan = self._plan(goal, PLAN_CANDIDATES[name])
            playable = playable_mask(self)
            promise = step_f1(playable, goal.keys)  # (T,) the plan's step F1
            plans.append((name, int(playable.sum()), promise, plan))
        if cfg.plan.choose_plan == "rehearsal" and len(plans) > 1:
            candidates = [(name, promise, plan) for name, _, promise, plan in plans]
            chosen = self._rehearse_plans(candidates, seed)
        else:
            enough = max(p[1] for p in plans) - cfg.plan.piece_plan_margin * goal.keys.sum()
            chosen = next(plan for _, n, _, plan in plans if n >= enough)
        self._restore(chosen)
        return chosen

    def _rehearse_plans(self, plans: list[tuple[str, np.ndarray, Plan]], seed: int | None) -> Plan:
        """The plan of ``plans`` (name, (T,) each step's F1 if exactly its playable keys
        sound, snapshot) that plays best, each played through on a fork of the environment
        in its reset state (:mod:`rehearsal`); its rehearsal is kept for the performance to
        replay.

        The plans are rehearsed in order of their plan F1 (the mean of those, the highest
        first, so the likely winner is found early), a plan the same as one rehearsed
        already is skipped, and a rehearsal is given up once what it has lost, with what
        the steps to come lose even if they score their plan F1, reaches what the best so
        far lost over the whole piece; of equals the first rehearsed wins. A plan the same
        as the first one until some frame is rehearsed from ``REHEARSAL_MARGIN_FRAMES``
        before it, on from the state the first one's rehearsal kept there: the steps before
        are the first one's (a plan that turns a hand for a few bars rehearses those bars
        and what follows, not the whole piece).
        """
        start = self.memory()
        look = LookAhead(self.handle, seed)
        state = look.snapshot()
        order: list[tuple[str, np.ndarray, Plan]] = []
        for name, promise, plan in sorted(plans, key=lambda p: -p[1].mean()):  # stable
            if not any(plan.same_as(other) for _, _, other in order):
                order.append((name, promise, plan))  # else it would play exactly as that one
        first = order[0][2]
        # Where each later plan leaves the first: the first's rehearsal keeps its state there.
        leave = {
            name: first.first_difference(plan) - REHEARSAL_MARGIN_FRAMES
            for name, _, plan in order[1:]
        }
        keep = {k for k in leave.values() if k > 0}
        head: Replay | None = None
        best: tuple[float, Plan, Replay] | None = None
        # IKPlanner's own step: a subclass's (a recorder, a corrector) is not rehearsed.
        act = partial(IKPlanner.act, self, None)
        for name, promise, plan in order:
            self._restore(plan)
            give_up = np.inf if best is None else f1_lost(best[0], look.home.num_steps)
            k = leave.get(name, 0) if head is not None else 0
            f1, replay = np.inf, None
            if k > 0:
                assert head is not None  # the first rehearsal is never given up
                look.start(self, head.states[k], head.memories[k - 1], record=True)
                f1, replay = rehearse(self, look, give_up, act, promise, after=(head, k))
                if replay is not None and not np.array_equal(replay.actions[k], head.actions[k]):
                    f1, replay = np.inf, None  # it left the first's path sooner: from the start
            if not np.isfinite(f1):
                k = 0
                look.start(self, state, start, record=True)
                f1, replay = rehearse(self, look, give_up, act, promise, keep=keep)
            self.rehearsed[name], self.rehearsed_from[name] = f1, k
            if head is None:
                head = replay
            if replay is not None and (best is None or f1 > best[0]):
                best = (f1, plan, replay)
        assert best is not None and head is not None  # the first is never given up
        head.states.clear()  # full simulator states, not needed by the replay
        look.back(self, start)
        self.finger_states[:] = 0
        self._replay = best[2]
        return best[1]

    def _restore(self, plan: Plan) -> None:
        """Play ``plan`` from now on."""
        self.plan, self.plan_kind, self.fingers = plan, plan.kind, plan.fingers

    def stats(self) -> dict[str, float]:
        """What the plan leaves out or lifts for a shift, as shares of the due key-frames, the
        F1 of sounding exactly what it leaves playable, the recall and F1 no controller with
        these hands' reach can pass (:func:`pianist.control.planner.coverage.plan_coverage`:
        the whole hands' and the straight wrists'), and the F1 each candidate plan rehearsed
        to (:attr:`rehearsed`), for metrics.json (none before the first reset)."""
        if not self._planned:
            return {}
        if self._coverage is None:
            self._coverage = plan_coverage(self)
        c = self._coverage
        return {
            "reach_ceiling_recall": c.ceiling_recall,
            "reach_ceiling_f1": c.ceiling_f1,
            "reach_ceiling_straight_f1": c.straight_ceiling_f1,
            "plan_left_out_share": c.share("left_out"),
            "plan_in_shift_share": c.share("in_shift"),
            "plan_f1": c.plan_f1,
            **{f"rehearsed_f1_{name}": f1 for name, f1 in self.rehearsed.items()},
        }

    def whole_hand_reaches(self) -> dict[str, list[HandReach]]:
        """Each hand's reach (by side) in every pose of :data:`WHOLE_HAND_POSES` (after
        reset): what the hands reach with every joint of the action space, for the reach
        ceiling. Posture samples are made for each pose once per process (~0.15 s each)."""
        if self._whole_hand is None:
            cfg = self.config.with_fields(wrist_pose=(0.0, 0.0), reach_poses=WHOLE_HAND_POSES[1:])
            hands = [Hand.build(self.model, h, cfg.full_hand) for h in self.handle.scene.hands]
            data = mujoco.MjData(self.model)
            poses = hand_poses(self.model, data, hands, cfg, self.handle.scene.options)
            self._whole_hand = {
                hand.side: [reach_model(hand, mine, k) for k in range(len(mine))]
                for hand, mine in zip(hands, poses, strict=True)
            }
        return self._whole_hand

    def plan_arrays(self) -> dict[str, np.ndarray]:
        """The plan since ``reset``, per step:

        - ``hand_key_span``: (T, H, 2) the lowest and highest key (index 0-87, fractional:
          between two keys' press points) the fingers of each hand (right first) reach from
          its planned forearm position in its planned pose;
        - ``hand_pose``: (T, H) int, each hand's planned pose (0: the home pose, the wrist
          straight; k: ``PoseConfig.reach_poses[k - 1]``);
        - ``hand_sides``: (H,) "right" / "left", the order of the hands above;
        - ``planned_fingers``: (T, 88) the finger (0-9) the plan gives each due key, -1 none;
        - ``left_out_keys``, ``shift_keys``: (T, 88) bool, the due keys the plan sends no
          finger to, and those it lets go for a shift
          (:func:`pianist.control.planner.coverage.plan_key_classes`);
        - ``finger_states``: (T, 10) int8, each finger's
          :class:`~pianist.control.planner.targets.FingerState` at each step played so far
          (0, lifted, for steps not played; a look-ahead's steps are overwritten by the real
          ones, which always come later).
        """
        key_y = self.key_point[:, 1]
        order = np.argsort(key_y)
        spans = []
        order_of_hands = sorted(range(len(self.hands)), key=lambda i: self.hands[i].side != "right")
        for i in order_of_hands:
            arrays = self.plan.hands[i]
            full = np.stack([pose.full_reach for pose in self.poses[i]])[arrays.pose_plan]
            low = arrays.tx_plan + full[..., 0].min(axis=(1, 2))
            high = arrays.tx_plan + full[..., 1].max(axis=(1, 2))
            span = [np.interp(y, key_y[order], order.astype(float)) for y in (low, high)]
            spans.append(np.stack(span, axis=1))
        planned = np.where(self.goal.keys, self.fingers, -1)
        left_out, in_shift = plan_key_classes(self)
        return {
            "left_out_keys": left_out,
            "shift_keys": in_shift,
            "hand_key_span": np.stack(spans, axis=1),
            "hand_sides": np.array([self.hands[i].side for i in order_of_hands]),
            "hand_pose": np.stack([self.plan.hands[i].pose_plan for i in order_of_hands], axis=1),
            "planned_fingers": planned,
            "finger_states": self.finger_states.copy(),
        }

    def _plan(self, goal, how: PlanKind) -> Plan:
        """Plan the hands' positions, poses, fingers and forearm paths as ``how`` says, and
        play that plan from now on; returns it."""
        cfg = self.config
        plan_cfg = self._plan_config(how)
        if cfg.plan.uncross_hands and len(self.hands) == 2:
            goal = self._uncrossed(goal)
        piece = how.kind in ("piece", "split")
        if how.kind == "split" and len(self.hands) == 2:
            fingers, courses = self._plan_split(goal, plan_cfg)
        elif piece:
            fingers, courses = self._plan_piece(goal, how.refinger, plan_cfg)
        else:
            fingers = goal.fingers.copy()  # the song's
            courses = [
                frame_plan(
                    hand,
                    poses[0],
                    goal,
                    self.key_point,
                    cfg.forearm.lazy_m,
                    cfg.forearm.skip_out_of_reach,
                )
                for hand, poses in zip(self.hands, self.poses, strict=True)
            ]
        if len(self.hands) == 2:
            courses = keep_forearms_apart(self.hands, courses, cfg.forearm.forearm_separation_m)
        # Each hand's commands, the right first: a shift's delay keeps clear of the other
        # forearm as it follows its plan (the first one's as followed, once made).
        held = [course.position for course in courses]
        arrays = []
        for i, (hand, course) in enumerate(zip(self.hands, courses, strict=True)):
            other = (self.hands[1 - i], held[1 - i]) if len(self.hands) == 2 else None
            played = played_counts(fingers, self.goal.keys, hand, course.skip)
            made = plan_commands(hand, course, self.dt, plan_cfg, piece, played, other)
            held[i] = made.tx_held
            arrays.append(made)
        plan = Plan(how, fingers, tuple(arrays))
        self._restore(plan)
        return plan

    def _uncrossed(self, goal):
        """``goal`` with the song's hand crossings given to the hand on that side
        (:func:`pianist.control.planner.hand_order.uncross_hands`); ``goal`` itself if it has none.
        Made once per goal: every candidate plan of a reset asks for it."""
        cached = getattr(self, "_uncrossed_goal", None)
        if cached is not None and cached[0] is goal:
            return cached[1]
        fingers = uncross_hands(goal.keys, goal.fingers, self.key_point[:, 1])
        planned = goal
        if not np.array_equal(fingers, goal.fingers):
            fingers.setflags(write=False)
            planned = dataclasses.replace(goal, fingers=fingers)
        self._uncrossed_goal = (goal, planned)
        return planned

    def _plan_piece(
        self, goal, refinger: bool, plan_cfg: PlannerConfig
    ) -> tuple[np.ndarray, list[HandPlan]]:
        """The whole-piece plan of both hands (:mod:`pianist.control.planner.hand_plan`): the
        fingering (T, 88) (the finger 0-9 of each due key) and each hand's plan, in the order
        of ``hands``.

        The right hand is planned first. With ``share_keys`` (and the plan's fingering), keys
        one hand cannot reach from its plan (an octave, a chord wider than the hand) are
        offered to the other, which plans for its own keys and those, kept clear of the first
        forearm; then the first is planned again the same way. A key both hands would play
        stays with the hand the song gives it.
        """
        cfg = self.config
        order = sorted(range(len(self.hands)), key=lambda i: self.hands[i].side != "right")
        plan = self._piece_planner(goal, refinger, plan_cfg)
        hands = self.hands
        courses: dict[int, HandPlan] = {order[0]: plan(order[0])}
        if len(order) == 2:
            first, second = order
            if refinger and cfg.plan.share_keys:
                courses[second] = plan(
                    second,
                    take=courses[first].skip,
                    extra_cost=clearance(hands[first], courses[first], hands[second], cfg),
                    other_kept=_kept(courses[first]),
                )
                own_second = courses[second].skip & hands[second].own_keys(goal)
                courses[first] = plan(
                    first,
                    take=own_second,
                    extra_cost=clearance(hands[second], courses[second], hands[first], cfg),
                    other_kept=_kept(courses[second]),
                )
                for a, b in ((first, second), (second, first)):
                    # A key both would play stays with the hand the song gives it.
                    both = (courses[a].fingers >= 0) & (courses[b].fingers >= 0)
                    b_loses = both & hands[a].own_keys(goal)
                    courses[b] = dataclasses.replace(
                        courses[b], fingers=np.where(b_loses, -1, courses[b].fingers)
                    )
            else:
                courses[second] = plan(second, other_kept=_kept(courses[first]))
        return self._fingers_of(goal, courses)

    def _fingers_of(self, goal, courses: dict[int, HandPlan]) -> tuple[np.ndarray, list[HandPlan]]:
        """The fingering (T, 88) the hands' whole-piece plans (by index into ``hands``) give,
        and the plans with their ``skip`` the hand's own keys they give no finger."""
        fingers = goal.fingers.copy()
        out = []
        for i, hand in enumerate(self.hands):
            course = courses[i]
            played = course.fingers >= 0
            fingers[played] = course.fingers[played] + hand.finger_offset
            skip = goal.keys & ~played & hand.own_keys(goal)
            out.append(dataclasses.replace(course, skip=skip))
        return fingers, out

    def _plan_config(self, how: PlanKind) -> PlannerConfig:
        """The config with the whole-piece plan's weights of a plan made as ``how`` says (its
        objective, and :data:`TURN_FOR_SPANS`'s for the plan that turns for spans)."""
        costs = dataclasses.replace(
            self.config.plan.hand_plan,
            objective=how.objective,
            **(TURN_FOR_SPANS if how.turn else {}),
        )
        if costs == self.config.plan.hand_plan:
            return self.config
        return self.config.with_fields(hand_plan=costs)

    def _piece_planner(
        self, goal, refinger: bool, plan_cfg: PlannerConfig
    ) -> Callable[..., HandPlan]:
        """:func:`~pianist.control.planner.forearm.piece_plan` with this song's goal, key
        points, step and plan weights: call it with a hand's index and the per-call options
        (``take``, ``drop``, ``extra_cost``, ``other_kept``)."""

        def plan(i: int, **options: Any) -> HandPlan:
            return piece_plan(
                self.hands[i],
                self.poses[i],
                goal=goal,
                key_point=self.key_point,
                dt=self.dt,
                costs=plan_cfg.plan.hand_plan,
                refinger=refinger,
                pose_change_s=self.config.poses.pose_change_s,
                **options,
            )

        return plan

    def _plan_split(self, goal, plan_cfg: PlannerConfig) -> tuple[np.ndarray, list[HandPlan]]:
        """Both hands' whole-piece plans for the keys the joint plan gives each
        (:func:`pianist.control.planner.hand_split.split_hands`), with the plan's fingering: the
        right hand first, then the left clear of it, then the right again clear of the
        left. Returns the fingering and the plans as :meth:`_plan_piece` does."""
        cfg = self.config
        r = 0 if self.hands[0].side == "right" else 1
        right, left = r, 1 - r
        song_hand = np.where(goal.keys, np.where(goal.fingers < FINGERS_PER_HAND, 0, 1), -1)
        costs = SplitCosts(
            separation_m=cfg.forearm.forearm_separation_m,
            clearance_cost=cfg.plan.clearance_cost,
            hand=cfg.plan.hand_plan,
        )
        split = split_hands(
            goal.keys,
            song_hand,
            self.key_point[:, 1],
            C.BLACK_KEY_MASK,
            reach_model(self.hands[right], self.poses[right]),
            reach_model(self.hands[left], self.poses[left]),
            self.dt,
            costs,
        )
        plan = self._piece_planner(goal, True, plan_cfg)
        mine = {right: split == 0, left: split == 1}
        courses: dict[int, HandPlan] = {}
        for i, other in ((right, None), (left, right), (right, left)):
            courses[i] = plan(
                i,
                take=mine[i],
                drop=goal.keys & ~mine[i],
                extra_cost=None
                if other is None
                else clearance(self.hands[other], courses[other], self.hands[i], cfg),
                other_kept=None if other is None else _kept(courses[other]),
            )
        return self._fingers_of(goal, courses)

    # ----------------------------------------------------------------------------- acting

    # ----------------------------------------------------------------------------- look-ahead
    # What :class:`pianist.control.refine.Refiner` needs to run this planner ahead on a fork
    # of the environment and bring it back.

    def memory(self) -> list[FingerMemory]:
        """A copy of what the planner remembers between steps (per hand, per finger)."""
        return [memory.copy() for memory in self.memories]

    def set_memory(self, memory: list[FingerMemory]) -> None:
        """Go back to a :meth:`memory` copy."""
        self.memories = [m.copy() for m in memory]

    def attach(self, handle: ControlHandle) -> None:
        """Act on another environment of the same song and scene from now on (a fork)."""
        self.handle = handle

    def set_hand_settings(self, settings: list[PlannerConfig | None]) -> None:
        """Act with other execution settings per hand (in the order of ``hands``; None: the
        planner's ``config``). Only the fields read while acting take effect: the plan and
        the posture samples were made at reset."""
        if len(settings) != len(self.hands):
            raise ValueError(f"one setting per hand ({len(self.hands)}), not {len(settings)}")
        self.hand_settings = list(settings)
        self._replay = None  # rehearsed with the planner's own settings

    def finger_action_dims(self) -> np.ndarray:
        """(F,) the action dimensions of every finger joint (not the forearms or wrists)."""
        return np.concatenate([hand.finger_actuators for hand in self.hands])

    def _prediction_rollouts(self) -> RolloutAhead:
        """The simulator of the predicted pushes and strikes (:mod:`strike_prediction`), made
        on first use and kept while the model and its substeps stay those of the environment
        acted on."""
        handle, kept = self.handle, getattr(self, "_rollouts", None)
        substeps = handle.config.substeps
        if kept is None or kept.model is not handle.model or kept.substeps != substeps:
            kept = RolloutAhead(handle.model, substeps, self.key_qpos, np.zeros(0, dtype=int))
            self._rollouts = kept
        return kept

    def predicted_action_dims(self) -> np.ndarray:
        """(k,) the action dimensions of the fingers whose commands this step were chosen by
        :mod:`~pianist.control.planner.strike_prediction` (pushing a soft note, or starting
        a strike), after :meth:`act`."""
        dims = [
            hand.fingers[f].actuators
            for hand, memory in zip(self.hands, self.memories, strict=True)
            for f in np.flatnonzero(np.isfinite(memory.push_target) | (memory.strike_key >= 0))
        ]
        return np.concatenate(dims) if dims else np.zeros(0, dtype=np.int64)

    def act(self, observation: object = None) -> np.ndarray:
        cfg, handle, m, scratch = self.config, self.handle, self.model, self.scratch
        T = self.goal.num_frames
        t = min(handle.step_index, T - 1)  # an episode that ran to its end: hold the last frame
        replay = self._replay
        if replay is not None and replay.on_path(handle.step_index, handle):
            # Where the rehearsal was: its action, and the memory acting left it.
            self.set_memory(replay.memories[handle.step_index])
            self.finger_states[t] = replay.finger_states[t]
            return replay.actions[handle.step_index].copy()
        ctrl = np.array(handle.data.ctrl)
        scratch.qpos[:] = handle.data.qpos
        press_frame = min(t + cfg.fingers.press_lead_frames, T - 1)
        hover_end = min(T, press_frame + 1 + round(cfg.fingers.hover_lead_s / self.dt))
        settings = [hand_cfg or cfg for hand_cfg in self.hand_settings]
        poses, bent_up = [], []
        for i, hand in enumerate(self.hands):
            arrays, hand_cfg = self.plan.hands[i], settings[i]
            pose_index = int(arrays.pose_held[t])
            pose = self.poses[i][pose_index]
            poses.append((pose_index, pose))
            command_forearm(ctrl, handle.data, hand, self.servos[i], arrays.tx_path, t)
            command_height(ctrl, handle.data, hand, pose.raise_m, hand_cfg)
            bent_up.append(set_wrist(scratch, ctrl, hand, pose.wrist, pose.ty, hand_cfg))
            # The fingers are solved for where the moving forearm will be a little later:
            # their servos lag behind their commands by about a control step.
            scratch.qpos[hand.tx_qpos] += cfg.forearm.forearm_lead_s * handle.data.qvel[hand.tx_dof]
        mujoco.mj_kinematics(m, scratch)
        pushes: list[Push] = []
        strikes: list[Strike] = []
        for i, hand in enumerate(self.hands):
            (pose_index, pose), hand_cfg = poses[i], settings[i]
            targets, active, memory = fingertip_targets(
                self,
                hand,
                self.plan.hands[i],
                pose.lift_tips,
                self.memories[i],
                t,
                hover_end,
                hand_cfg,
            )
            self.memories[i] = memory
            self.finger_states[t, hand.finger_offset : hand.finger_offset + 5] = memory.state
            angles = solve_fingers(
                m,
                scratch,
                hand,
                pose.batch,
                targets,
                active,
                memory,
                bent_up[i],
                pose_index > 0,
                hand_cfg,
            )
            ctrl[hand.finger_actuators] = finger_controls(hand, angles)
            hand_pushes, hand_strikes = _predicted(m, scratch, hand, memory, self.goal, t)
            pushes += hand_pushes
            strikes += hand_strikes
        if pushes or strikes:
            ctrl = apply_predictions(
                self._prediction_rollouts(),
                handle.data,
                ctrl,
                pushes,
                strikes,
                cfg.strikes.push_offsets_rad,
                cfg.strikes.strike_offsets_rad,
                self.dt,
            )
        action = np.empty(m.nu + 1)
        action[:-1] = handle.ctrl_to_action(ctrl)
        action[-1] = 1.0 if self.goal.sustain[press_frame] else -1.0
        return action.astype(np.float32)


def _predicted(
    m, scratch, hand: Hand, memory: FingerMemory, goal, now: int
) -> tuple[list[Push], list[Strike]]:
    """The hand's fingers whose commands this step are chosen by prediction
    (:mod:`~pianist.control.planner.strike_prediction`): those pushing a soft note toward
    its key's planned angle, and those starting to strike a louder one; ``scratch`` holds
    the hand's solved posture."""
    pushing = np.flatnonzero(np.isfinite(memory.push_target)).tolist()
    striking = np.flatnonzero(memory.strike_key >= 0).tolist()
    if not pushing and not striking:
        return [], []
    directions = descent_directions(m, scratch, hand, pushing + striking)
    pushes = [
        Push(hand.fingers[f].actuators, d, int(memory.push_key[f]), float(memory.push_target[f]))
        for f, d in zip(pushing, directions, strict=False)
    ]
    strikes = []
    for f, d in zip(striking, directions[len(pushing) :], strict=True):
        key, frame = int(memory.strike_key[f]), int(memory.strike_frame[f])
        velocity = int(goal.velocities[frame, key])
        strikes.append(Strike(hand.fingers[f].actuators, d, key, velocity, frame - now))
    return pushes, strikes


def _kept(course: HandPlan) -> np.ndarray:
    """(T,) the keys a hand's whole-piece plan gives its fingers, per frame."""
    return (course.fingers >= 0).sum(axis=1).astype(float)


def forget_plans() -> None:
    """Empty the shared plan cache (:data:`~pianist.control.planner.plans.PLANS`): the next
    reset plans (and rehearses) anew, as a first episode does (for timing one)."""
    PLANS.clear()
