"""Each step, every fingertip's target: the per-finger press, hover and lift decisions.

Inputs (:func:`fingertip_targets`): the planner's episode data (:class:`PlannerState`: goal
frames and fingering, the keys' press points (88, 3) m, tops (88,) m and press depths (88,)
m, the simulator state), the hand's indices (:class:`~pianist.control.planner.hand.Hand`),
its plan (``free``, ``shift_to``, ``skip``: :class:`~pianist.control.planner.plans.HandPlanArrays`),
its lifted fingertips ``lift_tips`` (5, 3) m in the pose it is in
(:class:`~pianist.control.planner.postures.HandPose`), and its fingers' memory
(:class:`~pianist.control.planner.hand.FingerMemory`).

Output: (5, 3) fingertip targets in m relative to the forearm body, (5,) bool: which
fingers have a target (the IK starts the others from their lifted posture), and the fingers'
memory after the step (the one given is not changed).
"""

from __future__ import annotations

from enum import IntEnum
from typing import TYPE_CHECKING

import numpy as np

from pianist.control.planner.config import FINGERS_PER_HAND, PlannerConfig, PlannerState
from pianist.control.planner.hand import FingerMemory, Hand
from pianist.control.planner.strikes import PUSH_SOUND_MARGIN, planned_angle
from pianist.sim import constants as C

if TYPE_CHECKING:
    from pianist.control.planner.plans import HandPlanArrays


class FingerState(IntEnum):
    """What a finger does in a step, as :func:`fingertip_targets` decides it
    (recorded per step in :meth:`IKPlanner.plan_arrays` as ``finger_states``)."""

    LIFTED = 0
    """No key due soon: the lifted posture (``lift_tips``)."""
    HOVERING = 1
    """Over a key due later, or due now but not lined up with it yet (``hover_height_m``,
    ``transfer_height_m`` coming from another key)."""
    PRESSING = 2
    """Sent ``key_depth`` below its key's top, so the servo holds the key down."""
    PUSHING = 3
    """Pressing, and pushed further down: the key has not sounded for ``unsounded_steps``, or
    the finger presses again the key it let up the step before (``restrike_push_rad``)."""
    RESTRIKING = 4
    """Its key is still down and is due again: let up first (``release_height_m``)."""
    TRAVELLING = 5
    """The hand is shifting: over the key it moves for, or lifted clear for a long jump."""


def fingertip_targets(
    planner: PlannerState,
    hand: Hand,
    plan: HandPlanArrays,
    lift_tips: np.ndarray,
    memory: FingerMemory,
    now: int,
    hover_end: int,
    cfg: PlannerConfig | None = None,
) -> tuple[np.ndarray, np.ndarray, FingerMemory]:
    """(5, 3) fingertip targets relative to the forearm, which fingers have one (5,) bool,
    and the fingers' memory after this step (``memory`` itself is left as it was).

    Keys scored at the end of this step (frame ``now``) are held down to its end; keys
    due at the next frame are pressed already (the servos lag about a frame), except a key
    that is still down and must sound again: it is let up for this step first. Fingers due
    later hover over their keys; the rest take their lifted posture. ``plan``: the hand's
    plan (``free``, ``shift_to``, ``skip``); ``lift_tips`` (5, 3) m: its lifted fingertips
    relative to the forearm in the pose it is in; ``hover_end``: the frame (exclusive) up
    to which fingers hover over keys due later; ``cfg``: this hand's settings (default: the
    planner's).
    """
    cfg = cfg or planner.config
    mem = memory.copy()
    goal = planner.goal
    radius = C.FINGERTIP_CAPSULE_RADIUS_M
    origin = planner.scratch.xpos[hand.forearm_body]
    real_tips = planner.handle.data.site_xpos[hand.sites]
    targets = lift_tips + origin
    active = np.zeros(FINGERS_PER_HAND, dtype=bool)
    mem.pressing = np.zeros(FINGERS_PER_HAND, dtype=bool)
    mem.push_target = np.full(FINGERS_PER_HAND, np.nan)
    mem.strike_key = np.full(FINGERS_PER_HAND, -1)
    mem.strike_frame = np.full(FINGERS_PER_HAND, -1)
    let_up = mem.state == FingerState.RESTRIKING  # last step's states
    mem.state = np.full(FINGERS_PER_HAND, FingerState.LIFTED, dtype=np.int8)
    if plan.free[now]:
        mem.last_key[:] = -1
    if plan.free[now] and cfg.fingers.hover_in_shift:
        # The hand is moving: the fingers of the note it moves for travel with it just
        # above their keys, the others stay lifted.
        _hover_over(planner, hand, plan.skip, mem, plan.shift_to[now], targets, active, cfg, None)
        # A finger still on the keys with far to go comes up first (``jump_lift_m``).
        low = real_tips[:, 2] < C.WHITE_KEY_HEIGHT_M + radius + cfg.fingers.jump_low_m
        far = active & low & (np.abs(targets[:, 1] - real_tips[:, 1]) > cfg.fingers.jump_lift_m)
        mem.state[active] = FingerState.TRAVELLING
        active[far] = False
        targets[far] = lift_tips[far] + origin
        mem.active = active.copy()
        return targets - origin, active, mem
    lead = min(now + cfg.fingers.press_lead_frames, goal.num_frames - 1)
    key_down = planner.handle.data.qpos[planner.key_qpos] >= planner.key_threshold
    hovering = np.zeros(FINGERS_PER_HAND, dtype=bool)
    pressed_key = np.full(FINGERS_PER_HAND, -1)
    # Fingers pushing a soft note, until push_grace_frames after it should have sounded:
    # not pushed harder for not sounding it yet.
    gentle = np.zeros(FINGERS_PER_HAND, dtype=bool)
    for frame in (now, lead):
        for key in np.flatnonzero(goal.keys[frame] & ~plan.skip[frame]):
            finger = planner.fingers[frame, key] - hand.finger_offset
            if not 0 <= finger < FINGERS_PER_HAND or active[finger]:
                continue
            point = press_point(planner, int(key), finger, cfg)
            top = planner.key_top_z[key] + radius
            targets[finger] = point
            active[finger] = True
            if frame != now and key_down[key]:
                targets[finger, 2] = top + cfg.fingers.release_height_m  # re-strike: up first
                mem.state[finger] = FingerState.RESTRIKING
                continue
            if plan.free[frame]:
                # The hand is moving: its fingers stay clear, or they catch on keys.
                targets[finger] = lift_tips[finger] + origin
                mem.state[finger] = FingerState.TRAVELLING
                continue
            black = C.BLACK_KEY_MASK[key]
            tolerance = (
                cfg.fingers.black_align_tolerance_m if black else cfg.fingers.align_tolerance_m
            )
            # Across the keys is what matters; along a key a few mm either way still press,
            # but a finger too far back over a white key would land on a black one.
            miss = abs(real_tips[finger, 1] - point[1])
            if finger and not black and real_tips[finger, 0] < point[0] - cfg.fingers.align_along_m:
                miss = np.inf
            if black and real_tips[finger, 0] > point[0] + cfg.fingers.black_front_m:
                miss = np.inf  # still over the white key in front
            down = real_tips[finger, 2] < top
            # A pressing finger keeps pressing while it stays roughly on its key; one that
            # slid off (beside a black key, say) comes up to try again.
            # A finger that hovers off its key and no longer moves cannot get closer at
            # that height (the thumb under the palm, say): it goes down from where it is.
            stuck = (
                mem.stuck[finger] >= cfg.fingers.stuck_frames and miss <= cfg.fingers.stuck_reach_m
            )
            # A finger holding its key down keeps it, however far across the keys its tip
            # slid (not one too far along it: that one is over another key).
            holding = (
                cfg.fingers.keep_sounding
                and mem.last_key[finger] == key
                and key_down[key]
                and np.isfinite(miss)
            )
            if (
                miss <= tolerance
                or (down and miss <= cfg.fingers.keep_pressing_ratio * tolerance)
                or stuck
                or holding
            ):
                extra = cfg.keys.thumb_extra_depth_m if finger == 0 else 0.0
                targets[finger, 2] = top - planner.key_depth[key] - extra
                if planner.strikes.predicted[frame, key] and not key_down[key]:
                    # A struck note (not pushed): its force is chosen by prediction.
                    mem.strike_key[finger], mem.strike_frame[finger] = key, frame
                if planner.strikes.rate[frame, key] and not key_down[key]:
                    # A pushed note not sounded yet: its own depth (strikes.py).
                    targets[finger, 2] = _push(planner, hand, mem, frame, int(key), now, cfg)
                    gentle[finger] = (
                        now <= planner.strikes.sound[frame, key] + cfg.strikes.push_grace_frames
                    )
                mem.pressing[finger] = True
                mem.state[finger] = FingerState.PRESSING
                pressed_key[finger] = key
            else:
                transfer = mem.last_key[finger] >= 0 and mem.last_key[finger] != key
                height = cfg.fingers.transfer_height_m if transfer else cfg.fingers.hover_height_m
                if planner.strikes.rate[frame, key]:
                    height = min(height, cfg.strikes.push_rest_m)
                targets[finger, 2] = top + height
                if cfg.fingers.unwedge and mem.stuck[finger] >= cfg.fingers.stuck_frames and down:
                    # Wedged below the key's top against its side: up and clear first.
                    targets[finger] = lift_tips[finger] + origin
                hovering[finger] = True
                mem.state[finger] = FingerState.HOVERING
    mem.unsounded, pushed = count_unsounded(
        mem.unsounded, mem.pressing, pressed_key, mem.last_key, key_down, cfg
    )
    mem.repress = mark_represses(mem.pressing, let_up, cfg)
    mem.unsounded[gentle] = np.minimum(mem.unsounded[gentle], cfg.ik.unsounded_steps - 1)
    mem.repress &= ~gentle
    pushed &= ~gentle
    mem.state[pushed | mem.repress] = FingerState.PUSHING
    # A finger keeps its last key while it presses or hovers on its way to the next one.
    mem.last_key = np.where(mem.pressing, pressed_key, np.where(hovering, mem.last_key, -1))
    # Count the steps each hovering finger has stood still.
    still = np.linalg.norm(real_tips - mem.last_tips, axis=1) < cfg.fingers.still_m
    mem.stuck = np.where(hovering & still, mem.stuck + 1, 0)
    mem.last_tips = real_tips.copy()
    for t in range(lead + 1, hover_end if not plan.free[now] else lead + 1):
        if plan.free[t] and cfg.fingers.hover_stops_at_shift:
            break  # keys past a shift are out of reach from here
        _hover_over(planner, hand, plan.skip, mem, t, targets, active, cfg, now)
    mem.state[active & (mem.state == FingerState.LIFTED)] = FingerState.HOVERING
    mem.active = active.copy()
    return targets - origin, active, mem


def mark_represses(pressing: np.ndarray, let_up: np.ndarray, cfg) -> np.ndarray:
    """(5,) bool ``repress``: the fingers pressing now (``pressing`` (5,) bool) that let their
    key up last step (``let_up`` (5,) bool). A re-strike has one step to bring its key
    down again, so the IK pushes it from the first (``restrike_push_rad``)."""
    return pressing & let_up & (np.asarray(cfg.ik.restrike_push_rad) > 0)


def count_unsounded(
    unsounded: np.ndarray,
    pressing: np.ndarray,
    pressed_key: np.ndarray,
    last_key: np.ndarray,
    key_down: np.ndarray,
    cfg,
) -> tuple[np.ndarray, np.ndarray]:
    """Count the steps each finger has pressed the same key without it sounding (a finger
    too weak for it, on the top of the key: the IK pushes such a finger harder).

    Args:
        unsounded: (5,) int, the count so far.
        pressing: (5,) bool, the fingers pressing this step.
        pressed_key: (5,) int, the key each finger presses this step (-1: none).
        last_key: (5,) int, the key each pressed last step.
        key_down: (88,) bool, which keys are down now.
    Returns:
        (5,) int the count after this step, and (5,) bool the fingers to push harder this
        step.
    """
    again = pressing & (pressed_key == last_key)
    sounding = key_down[np.maximum(pressed_key, 0)] & (pressed_key >= 0)
    # Once pushed harder, a finger keeps that push while it holds the key: the key's
    # sounding band is the last 0.5 degrees of its travel, and a finger that eased off
    # as soon as the key sounded would let it flicker in and out of it.
    latched = again & (unsounded >= cfg.ik.unsounded_steps) & cfg.ik.unsounded_latch
    unsounded = np.where(again & ~sounding, unsounded + 1, 0)
    unsounded = np.where(latched, np.maximum(unsounded, cfg.ik.unsounded_steps), unsounded)
    return unsounded, pressing & (unsounded >= cfg.ik.unsounded_steps)  # see ik.py


def _hover_over(
    planner: PlannerState,
    hand: Hand,
    skip: np.ndarray,
    mem: FingerMemory,
    frame: int,
    targets: np.ndarray,
    active: np.ndarray,
    cfg: PlannerConfig,
    now: int | None,
) -> None:
    """Send each finger of ``hand`` without a target yet to hover over its key due at
    ``frame`` and not in ``skip`` (T, 88) (``targets`` world frame, changed in place with
    ``active``); at step ``now`` a pushed note's finger rests on its key or pushes it
    (``now`` None: the hand is shifting, no push; ``mem`` keeps the push's progress)."""
    goal = planner.goal
    height = C.FINGERTIP_CAPSULE_RADIUS_M + cfg.fingers.hover_height_m
    for key in np.flatnonzero(goal.keys[frame] & ~skip[frame]):
        finger = planner.fingers[frame, key] - hand.finger_offset
        if 0 <= finger < FINGERS_PER_HAND and not active[finger]:
            targets[finger] = press_point(planner, int(key), finger, cfg)
            targets[finger, 2] = planner.key_top_z[key] + height
            if now is not None and planner.strikes.rate[frame, key]:
                targets[finger, 2] = _push(planner, hand, mem, frame, int(key), now, cfg)
            active[finger] = True


def _push(
    planner: PlannerState,
    hand: Hand,
    mem: FingerMemory,
    frame: int,
    key: int,
    now: int,
    cfg: PlannerConfig,
) -> float:
    """The fingertip's target height (m) at step ``now`` for the pushed note of ``key``
    due at ``frame``, not sounded yet: resting on the key until its push starts, then at
    the key's breakaway depth, with the angle the key should reach by the step's end kept
    in ``mem.push_target`` (:mod:`strike_prediction` pushes the finger on from there)."""
    finger = int(planner.fingers[frame, key]) - hand.finger_offset
    top = planner.key_top_z[key] + C.FINGERTIP_CAPSULE_RADIUS_M
    plan = planner.strikes
    if now < plan.start[frame, key]:
        return top + cfg.strikes.push_rest_m
    # The planned line is raised by a margin so that the key sounds within its step and not
    # just after it.
    angle = planned_angle(plan, frame, key, now) + PUSH_SOUND_MARGIN * plan.rate[frame, key]
    mem.push_key[finger] = key
    mem.push_target[finger] = min(angle, C.KEY_MAX_ANGLE_RAD[key])
    share = cfg.strikes.push_breakaway_share[int(C.BLACK_KEY_MASK[key])]
    return top - share * float(planner.key_depth[key])


def press_point(
    planner: PlannerState, key: int, finger: int, cfg: PlannerConfig | None = None
) -> np.ndarray:
    """(3,) m: where ``finger`` (0-4) presses ``key`` (world frame): the key's press point,
    nearer the front edge for the thumb on a white key."""
    point = planner.key_point[key].copy()
    if finger == 0 and not C.BLACK_KEY_MASK[key]:
        point[0] = (cfg or planner.config).keys.thumb_white_press_x_m
    return point
