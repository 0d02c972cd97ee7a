"""Each finger's joint angles for its fingertip target: inverse kinematics, wrist held still.

Inputs: the (5, 3) fingertip targets (m, relative to the forearm body) and (5,) bool active
flags from :mod:`targets`, and a scratch ``MjData`` with the forearm and wrist as commanded.
Each active finger starts from its nearest sampled posture (:mod:`postures`), then takes
``iterations`` damped least-squares steps on ``mujoco.mj_jacSite`` over its actuated joints,
clipped to their limits; an inactive one takes its lifted posture. A pressing finger is then
pushed further down (``thumb_push_rad``, ``finger_push_rad``).

Output: every finger's ``angles`` (dof,) rad (also set in the scratch state);
``finger_controls`` concatenates them, thumb to little finger: the hand's finger commands.
"""

from __future__ import annotations

import mujoco
import numpy as np

from pianist.control.planner.postures import Finger


class FingerIK:
    """A hand's per-finger inverse kinematics."""

    # Set by ``Hand.__init__`` (and ``pressing`` by ``FingerTargets.fingertip_targets``).
    fingers: list[Finger]
    forearm_body: int
    jacp: np.ndarray
    pressing: np.ndarray
    unsounded: np.ndarray
    repress: np.ndarray
    wrist_bent_up: float  # set by ``HandPostures.set_wrist`` each step

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
        thumb_weights = np.array([1.0, cfg.thumb_lateral_weight, 1.0])
        damping = cfg.damping**2 + cfg.rest_weight
        limit = cfg.step_limit_rad
        for _ in range(cfg.iterations):
            mujoco.mj_kinematics(m, scratch)
            mujoco.mj_comPos(m, scratch)  # mj_jacSite reads cdof and subtree centres
            origin = scratch.xpos[self.forearm_body]
            for f in np.flatnonzero(active).tolist():
                finger = self.fingers[f]
                error = targets[f] - (scratch.site_xpos[finger.site] - origin)
                mujoco.mj_jacSite(m, scratch, self.jacp, None, finger.site)
                J = finger.jacobian(self.jacp)
                if f == 0:  # the thumb lines up before it goes deep (PlannerConfig)
                    J = J * thumb_weights[:, None]
                    error = error * thumb_weights
                A = J.T @ J + finger.diagonal(damping)
                step = np.linalg.solve(A, J.T @ error)
                # np.minimum / np.maximum: np.clip's result at a fraction of its call's cost.
                step = np.minimum(np.maximum(step, -limit), limit)
                finger.angles = np.minimum(
                    np.maximum(finger.angles + step, finger.low), finger.high
                )
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
            amount = cfg.thumb_push_rad if f == 0 else cfg.finger_push_rad[f - 1]
            if self.unsounded[f] >= cfg.unsounded_steps:  # pressing its key, not sounding it
                amount += cfg.unsounded_push_rad
            if self.repress[f]:  # pressing again the key it let up last step
                amount += cfg.restrike_push_rad[f]
            # The other fingers' keys bend the wrist up and lift this one off its key.
            amount += cfg.bent_wrist_push * self.wrist_bent_up
            mujoco.mj_jacSite(m, scratch, self.jacp, None, finger.site)
            down = -finger.jacobian(self.jacp)[2]
            norm = np.linalg.norm(down)
            if amount > 0 and norm > 0:
                push = finger.angles + amount * down / norm
                finger.angles = np.clip(push, finger.low, finger.high)

    def finger_controls(self, scratch) -> np.ndarray:
        return np.concatenate([f.angles for f in self.fingers])
