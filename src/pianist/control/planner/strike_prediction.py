"""Predicted pushes: each step of a soft note's push chosen by simulating the step ahead.

A pushed key (:mod:`strikes`) should end every control step on its planned descent. A depth
fed back from the key's angle now lags the key by a step, and a key that breaks away covers
most of its travel within that step: pushed notes sounded anywhere from 33 to 87 for a
target of 50 (docs/notes/2026-12-07-pushed-strikes.md). Here the step is predicted instead.
The finger is sent to the key's breakaway depth, and then along its descent direction (the
actuator angles that lower its fingertip fastest) by one of a few offsets: each offset's
control step is simulated from the present state with the environment's own model, and the
offset whose predicted key angle at the step's end meets the planned angle is interpolated
from them.

Every pushing finger of both hands is tried at once: offset j is applied to all of them in
the j-th simulated step, and each finger reads its own key's response (the fingers barely
move each other's keys). A step costs one simulated control step per offset, all of them in
one :func:`mujoco.rollout.rollout` call on two threads
(:class:`~pianist.control.rollout_ahead.RolloutAhead`), and only steps with a push pay it.

Inputs: the live ``MjData``, the step's commands (``ctrl``), and per pushing finger its
actuators, descent direction, key and target angle. Output: the commands with the pushes'
offsets applied.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from pianist.control.rollout_ahead import RolloutAhead


@dataclass(frozen=True)
class Push:
    """One finger pushing its key this step.

    Attributes:
        actuators: (dof,) int, the finger's actuator indices into ``ctrl``.
        direction: (dof,) unit actuator-angle direction that lowers its fingertip.
        key: its key (0-87).
        target_rad: the key's planned angle (rad, 0 up) at the end of this step.
    """

    actuators: np.ndarray
    direction: np.ndarray
    key: int
    target_rad: float


def predicted_angles(
    rollouts: RolloutAhead,
    data: mujoco.MjData,
    ctrl: np.ndarray,
    pushes: Sequence[Push],
    offsets: Sequence[float],
) -> np.ndarray:
    """(len(offsets), len(pushes)) rad: each pushed key's angle at the end of a control step
    simulated from ``data`` (left alone) with every push offset by ``offsets[j]`` rad along
    its direction in row j, the rows simulated at once on ``rollouts``' threads."""
    low, high = rollouts.model.actuator_ctrlrange.T
    commands = np.repeat(ctrl[None, None, :], len(offsets), axis=0)  # (J, 1, nu)
    for j, offset in enumerate(offsets):
        for push in pushes:
            commands[j, 0, push.actuators] += offset * push.direction
    keys, _ = rollouts.run_ctrl(data, np.minimum(np.maximum(commands, low), high))
    return keys[:, 0, [p.key for p in pushes]]


def chosen_offsets(angles: np.ndarray, offsets: Sequence[float], targets: np.ndarray) -> np.ndarray:
    """(P,) rad: per push, the offset whose predicted angle meets its target.

    Args:
        angles: (J, P) the predicted angles (:func:`predicted_angles`).
        offsets: (J,) ascending offsets tried.
        targets: (P,) target angles.
    Returns:
        Per push, linear interpolation of the offsets at its target along its predicted
        angles (made non-decreasing: pushing further never lifts a key); the smallest offset
        if even that goes past the target, the largest if none reaches it.
    """
    tried = np.asarray(offsets, dtype=np.float64)
    chosen = np.empty(angles.shape[1])
    for p in range(angles.shape[1]):
        response = np.maximum.accumulate(angles[:, p])
        if targets[p] <= response[0]:
            chosen[p] = tried[0]
        elif targets[p] >= response[-1]:
            chosen[p] = tried[-1]
        else:
            # First offset that reaches the target, and the one before it.
            hi = int(np.searchsorted(response, targets[p], side="left"))
            a, b = response[hi - 1], response[hi]
            share = (targets[p] - a) / (b - a) if b > a else 1.0
            chosen[p] = tried[hi - 1] + share * (tried[hi] - tried[hi - 1])
    return chosen


def apply_pushes(
    rollouts: RolloutAhead,
    data: mujoco.MjData,
    ctrl: np.ndarray,
    pushes: Sequence[Push],
    offsets: Sequence[float],
) -> np.ndarray:
    """``ctrl`` (nu,) with each push's chosen offset applied along its direction (a new
    array; ``ctrl`` itself is left alone)."""
    out = ctrl.copy()
    if not pushes:
        return out
    angles = predicted_angles(rollouts, data, ctrl, pushes, offsets)
    targets = np.array([p.target_rad for p in pushes])
    for push, offset in zip(pushes, chosen_offsets(angles, offsets, targets), strict=True):
        out[push.actuators] += offset * push.direction
    return out
