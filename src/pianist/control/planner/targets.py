"""Each step, every fingertip's target: the per-finger press, hover and lift decisions.

Inputs: the planner's episode data (:class:`PlannerState`: goal frames and fingering, the
keys' press points (88, 3) m, tops (88,) m and press depths (88,) m, the simulator state),
the hand's plan (``free``, ``shift_to``, ``skip`` from :mod:`forearm`), its lifted fingertips
``lift_tips`` (5, 3) m (from :mod:`postures`), and its per-finger memory (``pressing``,
``last_key``, ``stuck``, ``last_tips``), which ``fingertip_targets`` updates.

Output: (5, 3) fingertip targets in m relative to the forearm body, and (5,) bool: which
fingers have a target (the IK starts the others from their lifted posture).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from pianist.control.planner.config import FINGERS_PER_HAND, PlannerConfig, PlannerState
from pianist.control.planner.strikes import push_depth
from pianist.sim import constants as C


class FingerState(IntEnum):
    """What a finger does in a step, as :meth:`FingerTargets.fingertip_targets` decides it
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


class FingerTargets:
    """A hand's fingertip targets, and what the fingers remember between steps."""

    # Set by ``Hand.__init__``.
    sites: np.ndarray
    forearm_body: int
    finger_offset: int
    # Set by ``HandPostures.use_pose`` and the forearm plan.
    lift_tips: np.ndarray
    free: np.ndarray
    shift_to: np.ndarray
    skip: np.ndarray
    # Per-finger memory, (5,), kept here between steps.
    push_key: np.ndarray
    push_sound: np.ndarray
    push_depth: np.ndarray
    pressing: np.ndarray
    stuck: np.ndarray
    last_tips: np.ndarray
    last_key: np.ndarray
    unsounded: np.ndarray
    repress: np.ndarray
    """(5,) bool: fingers pressing again this step the key they let up the step before (a
    re-strike); the IK pushes them harder (``restrike_push_rad``)."""
    state: np.ndarray
    """(5,) the :class:`FingerState` of each finger this step."""
    active: np.ndarray
    """(5,) bool: which fingers had a target this step (the others took their lifted
    posture)."""

    def fingertip_targets(
        self, planner: PlannerState, now: int, hover_end: int, cfg: PlannerConfig | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(5, 3) fingertip targets relative to the forearm, and which fingers have one.

        Keys scored at the end of this step (frame ``now``) are held down to its end; keys
        due at the next frame are pressed already (the servos lag about a frame), except a key
        that is still down and must sound again: it is let up for this step first. Fingers due
        later hover over their keys; the rest take their lifted posture. ``cfg``: this hand's
        settings (default: the planner's).
        """
        cfg = cfg or planner.config
        goal = planner.goal
        radius = C.FINGERTIP_CAPSULE_RADIUS_M
        origin = planner.scratch.xpos[self.forearm_body]
        real_tips = planner.handle.data.site_xpos[self.sites]
        targets = self.lift_tips + origin
        active = np.zeros(FINGERS_PER_HAND, dtype=bool)
        self.pressing = np.zeros(FINGERS_PER_HAND, dtype=bool)
        let_up = self.state == FingerState.RESTRIKING  # last step's states
        self.state = np.full(FINGERS_PER_HAND, FingerState.LIFTED, dtype=np.int8)
        if self.free[now]:
            self.last_key[:] = -1
        if self.free[now] and cfg.hover_in_shift:
            # The hand is moving: the fingers of the note it moves for travel with it just
            # above their keys, the others stay lifted.
            self._hover_over(planner, self.shift_to[now], targets, active, cfg, None)
            # A finger still on the keys with far to go comes up first (``jump_lift_m``).
            low = real_tips[:, 2] < C.WHITE_KEY_HEIGHT_M + radius + cfg.jump_low_m
            far = active & low & (np.abs(targets[:, 1] - real_tips[:, 1]) > cfg.jump_lift_m)
            self.state[active] = FingerState.TRAVELLING
            active[far] = False
            targets[far] = self.lift_tips[far] + origin
            self.active = active.copy()
            return targets - origin, active
        lead = min(now + cfg.press_lead_frames, goal.num_frames - 1)
        key_down = planner.handle.data.qpos[planner.key_qpos] >= planner.key_threshold
        hovering = np.zeros(FINGERS_PER_HAND, dtype=bool)
        pressed_key = np.full(FINGERS_PER_HAND, -1)
        # Fingers pushing a soft note, until push_grace_frames after it should have sounded:
        # not pushed harder for not sounding it yet.
        gentle = np.zeros(FINGERS_PER_HAND, dtype=bool)
        for frame in (now, lead):
            for key in np.flatnonzero(goal.keys[frame] & ~self.skip[frame]):
                finger = planner.fingers[frame, key] - self.finger_offset
                if not 0 <= finger < FINGERS_PER_HAND or active[finger]:
                    continue
                point = self._press_point(planner, int(key), finger, cfg)
                top = planner.key_top_z[key] + radius
                targets[finger] = point
                active[finger] = True
                if frame != now and key_down[key]:
                    targets[finger, 2] = top + cfg.release_height_m  # re-strike: up first
                    self.state[finger] = FingerState.RESTRIKING
                    continue
                if self.free[frame]:
                    # The hand is moving: its fingers stay clear, or they catch on keys.
                    targets[finger] = self.lift_tips[finger] + origin
                    self.state[finger] = FingerState.TRAVELLING
                    continue
                black = C.BLACK_KEY_MASK[key]
                tolerance = cfg.black_align_tolerance_m if black else cfg.align_tolerance_m
                # Across the keys is what matters; along a key a few mm either way still press,
                # but a finger too far back over a white key would land on a black one.
                miss = abs(real_tips[finger, 1] - point[1])
                if finger and not black and real_tips[finger, 0] < point[0] - cfg.align_along_m:
                    miss = np.inf
                if black and real_tips[finger, 0] > point[0] + cfg.black_front_m:
                    miss = np.inf  # still over the white key in front
                down = real_tips[finger, 2] < top
                # A pressing finger keeps pressing while it stays roughly on its key; one that
                # slid off (beside a black key, say) comes up to try again.
                # A finger that hovers off its key and no longer moves cannot get closer at
                # that height (the thumb under the palm, say): it goes down from where it is.
                stuck = self.stuck[finger] >= cfg.stuck_frames and miss <= cfg.stuck_reach_m
                # A finger holding its key down keeps it, however far across the keys its tip
                # slid (not one too far along it: that one is over another key).
                holding = (
                    cfg.keep_sounding
                    and self.last_key[finger] == key
                    and key_down[key]
                    and np.isfinite(miss)
                )
                if (
                    miss <= tolerance
                    or (down and miss <= cfg.keep_pressing_ratio * tolerance)
                    or stuck
                    or holding
                ):
                    extra = cfg.thumb_extra_depth_m if finger == 0 else 0.0
                    targets[finger, 2] = top - planner.key_depth[key] - extra
                    if planner.strikes.rate[frame, key] and not key_down[key]:
                        # A pushed note not sounded yet: its own depth (strikes.py).
                        targets[finger, 2] = self._push(planner, frame, int(key), now, cfg)
                        gentle[finger] = (
                            now <= planner.strikes.sound[frame, key] + cfg.push_grace_frames
                        )
                    self.pressing[finger] = True
                    self.state[finger] = FingerState.PRESSING
                    pressed_key[finger] = key
                else:
                    transfer = self.last_key[finger] >= 0 and self.last_key[finger] != key
                    height = cfg.transfer_height_m if transfer else cfg.hover_height_m
                    if planner.strikes.rate[frame, key]:
                        height = min(height, cfg.push_rest_m)
                    targets[finger, 2] = top + height
                    if cfg.unwedge and self.stuck[finger] >= cfg.stuck_frames and down:
                        # Wedged below the key's top against its side: up and clear first.
                        targets[finger] = self.lift_tips[finger] + origin
                    hovering[finger] = True
                    self.state[finger] = FingerState.HOVERING
        pushed = self.count_unsounded(pressed_key, key_down, cfg)
        self.mark_represses(let_up, cfg)
        self.unsounded[gentle] = np.minimum(self.unsounded[gentle], cfg.unsounded_steps - 1)
        self.repress &= ~gentle
        pushed &= ~gentle
        self.state[pushed | self.repress] = FingerState.PUSHING
        # A finger keeps its last key while it presses or hovers on its way to the next one.
        self.last_key = np.where(self.pressing, pressed_key, np.where(hovering, self.last_key, -1))
        # Count the steps each hovering finger has stood still.
        still = np.linalg.norm(real_tips - self.last_tips, axis=1) < cfg.still_m
        self.stuck = np.where(hovering & still, self.stuck + 1, 0)
        self.last_tips = real_tips.copy()
        for t in range(lead + 1, hover_end if not self.free[now] else lead + 1):
            if self.free[t] and cfg.hover_stops_at_shift:
                break  # keys past a shift are out of reach from here
            self._hover_over(planner, t, targets, active, cfg, now)
        self.state[active & (self.state == FingerState.LIFTED)] = FingerState.HOVERING
        self.active = active.copy()
        return targets - origin, active

    def mark_represses(self, let_up: np.ndarray, cfg) -> None:
        """Set ``repress`` (5,) bool: the fingers pressing now (``pressing``) that let their
        key up last step (``let_up`` (5,) bool). A re-strike has one step to bring its key
        down again, so the IK pushes it from the first (``restrike_push_rad``)."""
        self.repress = self.pressing & let_up & (np.asarray(cfg.restrike_push_rad) > 0)

    def count_unsounded(self, pressed_key: np.ndarray, key_down: np.ndarray, cfg) -> np.ndarray:
        """Count the steps each finger has pressed the same key without it sounding (a finger
        too weak for it, on the top of the key: the IK pushes such a finger harder).

        Args:
            pressed_key: (5,) int, the key each finger presses this step (-1: none); the
                fingers' ``pressing`` flags are set, ``last_key`` is still last step's.
            key_down: (88,) bool, which keys are down now.
        Returns:
            (5,) bool: the fingers to push harder this step (``unsounded`` updated).
        """
        again = self.pressing & (pressed_key == self.last_key)
        sounding = key_down[np.maximum(pressed_key, 0)] & (pressed_key >= 0)
        # Once pushed harder, a finger keeps that push while it holds the key: the key's
        # sounding band is the last 0.5 degrees of its travel, and a finger that eased off
        # as soon as the key sounded would let it flicker in and out of it.
        latched = again & (self.unsounded >= cfg.unsounded_steps) & cfg.unsounded_latch
        self.unsounded = np.where(again & ~sounding, self.unsounded + 1, 0)
        self.unsounded = np.where(
            latched, np.maximum(self.unsounded, cfg.unsounded_steps), self.unsounded
        )
        return self.pressing & (self.unsounded >= cfg.unsounded_steps)  # see ik.py

    def _hover_over(
        self,
        planner: PlannerState,
        frame: int,
        targets: np.ndarray,
        active: np.ndarray,
        cfg: PlannerConfig,
        now: int | None,
    ) -> None:
        """Send each finger without a target yet to hover over its key due at ``frame``
        (world frame, in place); at step ``now`` a pushed note's finger rests on its key or
        pushes it (``now`` None: the hand is shifting, no push)."""
        goal = planner.goal
        height = C.FINGERTIP_CAPSULE_RADIUS_M + cfg.hover_height_m
        for key in np.flatnonzero(goal.keys[frame] & ~self.skip[frame]):
            finger = planner.fingers[frame, key] - self.finger_offset
            if 0 <= finger < FINGERS_PER_HAND and not active[finger]:
                targets[finger] = self._press_point(planner, int(key), finger, cfg)
                targets[finger, 2] = planner.key_top_z[key] + height
                if now is not None and planner.strikes.rate[frame, key]:
                    targets[finger, 2] = self._push(planner, frame, int(key), now, cfg)
                active[finger] = True

    def _push(
        self, planner: PlannerState, frame: int, key: int, now: int, cfg: PlannerConfig
    ) -> float:
        """The fingertip's target height (m) at step ``now`` for the pushed note of ``key``
        due at ``frame``, not sounded yet: resting on the key until its push starts, then
        :func:`~pianist.control.planner.strikes.push_depth` below its top (the push's
        progress kept per finger in ``push_key``, ``push_sound``, ``push_depth``)."""
        finger = int(planner.fingers[frame, key]) - self.finger_offset
        top = planner.key_top_z[key] + C.FINGERTIP_CAPSULE_RADIUS_M
        plan = planner.strikes
        if now < plan.start[frame, key]:
            return top + cfg.push_rest_m
        sound = int(plan.sound[frame, key])
        same = self.push_key[finger] == key and self.push_sound[finger] == sound
        depth = push_depth(
            plan,
            frame,
            key,
            now,
            float(planner.handle.data.qpos[planner.key_qpos[key]]),
            float(self.push_depth[finger]) if same else np.nan,
            float(planner.key_depth[key]),
            cfg.push_breakaway_share[int(C.BLACK_KEY_MASK[key])],
            float(planner.key_point[key, 0] + C.WHITE_KEY_LENGTH_M / 2),
            cfg.push_gain,
        )
        self.push_key[finger], self.push_sound[finger], self.push_depth[finger] = key, sound, depth
        return top - depth

    def _press_point(
        self, planner: PlannerState, key: int, finger: int, cfg: PlannerConfig | None = None
    ) -> np.ndarray:
        point = planner.key_point[key].copy()
        if finger == 0 and not C.BLACK_KEY_MASK[key]:
            point[0] = (cfg or planner.config).thumb_white_press_x_m
        return point
