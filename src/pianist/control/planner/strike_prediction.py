"""Predicted strikes: each step of a soft note's push, and the first step of every other
strike, chosen by simulating the steps ahead.

**Pushes.** A pushed key (:mod:`strikes`) should end every control step on its planned
descent. A depth fed back from the key's angle now lags the key by a step, and a key that
breaks away covers most of its travel within that step: pushed notes sounded anywhere from
33 to 87 for a target of 50 (docs/notes/2026-12-07-pushed-strikes.md). Here the step is
predicted instead. The finger is sent to the key's breakaway depth, and then along its
descent direction (the actuator angles that lower its fingertip fastest) by one of a few
offsets: each offset's control step is simulated from the present state with the
environment's own model, and the offset whose predicted key angle at the step's end meets
the planned angle is interpolated from them.

**Strikes.** A louder note's key is struck from above in the step before its frame and
sounds early in the next. How loud it reads (:func:`pianist.env.loudness.strike_speeds`)
depends on how far the key has gone when that next step starts: a key already near its
sounding angle reads the slow mean of the step before, one caught mid-travel reads its speed
then. So the strike's first step is tried with a few offsets along the finger's descent
direction, each simulated for that step and the next (the commands held), and the offset
whose strike sounds in the note's step nearest its velocity is played (0, the planner's own
command, if none sounds then). One finger's strikes read ~80-110 this way.

Offset j of every pushing and striking finger of both hands is simulated in row j at once,
and each finger reads its own key (the fingers barely move each other's keys): all rows in
one :func:`mujoco.rollout.rollout` call on two threads
(:class:`~pianist.control.rollout_ahead.RolloutAhead`), and only steps with a push or a
strike pay it.

Inputs: the live ``MjData``, the step's commands (``ctrl``), and per finger its actuators,
descent direction, key and target (angle or velocity). Output: the commands with the
chosen offsets applied.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from pianist.control.planner.strikes import SOUND_ANGLE_RAD
from pianist.control.rollout_ahead import RolloutAhead
from pianist.env.loudness import speed_to_velocity, strike_speeds


@dataclass(frozen=True)
class PredictedFinger:
    """A finger whose command this step is chosen by prediction.

    Attributes:
        actuators: (dof,) int, the finger's actuator indices into ``ctrl``.
        direction: (dof,) unit actuator-angle direction that lowers its fingertip.
        key: its key (0-87).
    """

    actuators: np.ndarray
    direction: np.ndarray
    key: int


@dataclass(frozen=True)
class Push(PredictedFinger):
    """A finger pushing its key this step; ``target_rad``: the key's planned angle (rad, 0
    up) at the end of this step."""

    target_rad: float


@dataclass(frozen=True)
class Strike(PredictedFinger):
    """A finger starting to strike its key this step; ``velocity``: the note's MIDI
    velocity; ``sound_step``: the step, counted from this one (0), in which the key should
    sound."""

    velocity: int
    sound_step: int


def predicted_velocity(
    start_rad: float, path: np.ndarray, key: int, substeps: int, dt: float
) -> tuple[int, int] | None:
    """The MIDI velocity and step a key simulated along ``path`` sounds at, read as the
    metrics read a performance's (:func:`pianist.env.loudness.strike_speeds`).

    Args:
        start_rad: the key's angle now.
        path: (H * substeps,) its angle after each substep of the next H control steps.
        key: the key (0-87); ``dt``: the control step (s).
    Returns:
        (velocity, step) of its first sounding, or None if it does not sound.
    """
    threshold = SOUND_ANGLE_RAD[key]
    crossed = np.flatnonzero(path >= threshold)
    if start_rad >= threshold or not crossed.size:
        return None
    first = int(crossed[0])
    steps = len(path) // substeps
    angles = np.zeros((steps + 1, len(SOUND_ANGLE_RAD)))
    angles[0, key] = start_rad
    angles[1:, key] = path[substeps - 1 :: substeps]
    event = np.array([[(first + 1) * dt / substeps, key, 1.0]])
    speed = strike_speeds(event, angles, dt, SOUND_ANGLE_RAD)[0]
    return int(speed_to_velocity(np.array([speed]))[0]), first // substeps


def chosen_strike_offsets(
    velocities: list[list[tuple[int, int] | None]],
    offsets: Sequence[float],
    strikes: Sequence[Strike],
) -> np.ndarray:
    """(K,) per strike, the offset whose predicted strike sounds in its step nearest its
    velocity (of equals, the one nearer 0; 0 where none sounds in its step).

    Args:
        velocities: per offset tried (J), per strike (K), :func:`predicted_velocity`'s answer.
        offsets: (J,) the offsets tried.
        strikes: the strikes.
    """
    chosen = np.zeros(len(strikes))
    for k, strike in enumerate(strikes):
        best = None
        for j, offset in enumerate(offsets):
            answer = velocities[j][k]
            if answer is None or answer[1] != strike.sound_step:
                continue
            cost = (abs(answer[0] - strike.velocity), abs(offset))
            if best is None or cost < best[0]:
                best = (cost, offset)
        chosen[k] = 0.0 if best is None else best[1]
    return chosen


def chosen_offsets(angles: np.ndarray, offsets: Sequence[float], targets: np.ndarray) -> np.ndarray:
    """(P,) rad: per push, the offset whose predicted angle meets its target.

    Args:
        angles: (J, P) each pushed key's predicted angle at the step's end, per offset.
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


def apply_predictions(
    rollouts: RolloutAhead,
    data: mujoco.MjData,
    ctrl: np.ndarray,
    pushes: Sequence[Push],
    strikes: Sequence[Strike],
    push_offsets: Sequence[float],
    strike_offsets: Sequence[float],
    dt: float,
) -> np.ndarray:
    """``ctrl`` (nu,) with each push's and each strike's chosen offset applied along its
    direction (a new array; ``ctrl`` itself is left alone).

    Offset j of every push and every strike is simulated in row j (``push_offsets`` and
    ``strike_offsets`` have one length): one control step ahead, and when there are strikes a
    second with ``ctrl`` itself, no offset (a strike sounds in the step after the one it
    starts in; one due later than that keeps the planner's command)."""
    out = ctrl.copy()
    if not pushes and not strikes:
        return out
    low, high = rollouts.model.actuator_ctrlrange.T
    horizon = 2 if strikes else 1
    commands = np.repeat(np.repeat(ctrl[None, None, :], len(push_offsets), axis=0), horizon, 1)
    for j in range(len(push_offsets)):
        for push in pushes:
            commands[j, 0, push.actuators] += push_offsets[j] * push.direction
        for strike in strikes:
            commands[j, 0, strike.actuators] += strike_offsets[j] * strike.direction
    paths = rollouts.key_paths(data, np.minimum(np.maximum(commands, low), high))
    substeps = rollouts.substeps
    if pushes:
        angles = paths[:, substeps - 1, [p.key for p in pushes]]
        targets = np.array([p.target_rad for p in pushes])
        for push, offset in zip(pushes, chosen_offsets(angles, push_offsets, targets), strict=True):
            out[push.actuators] += offset * push.direction
    if strikes:
        key_now = data.qpos[rollouts.key_qpos]
        answers = [
            [
                predicted_velocity(key_now[s.key], paths[j, :, s.key], s.key, substeps, dt)
                for s in strikes
            ]
            for j in range(len(strike_offsets))
        ]
        for strike, offset in zip(
            strikes, chosen_strike_offsets(answers, strike_offsets, strikes), strict=True
        ):
            out[strike.actuators] += offset * strike.direction
    return out
