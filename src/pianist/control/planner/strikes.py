"""How fast each key is struck: a note's loudness turned into its key's descent.

A key sounds as loud as it is struck fast: the speed of its front edge as it reaches the
depth where it sounds, mapped to MIDI velocity by :func:`pianist.env.loudness.speed_to_velocity`.
A finger sent far below its key from above strikes it as fast as its servo goes: MIDI
velocity ~80-110 whatever the press depth or hover height
(docs/notes/2026-12-07-strike-loudness.md). So a softer note is *pushed* along a planned
descent of its key:

1. **Plan** (:func:`plan_strikes`): the note's velocity gives the key's speed
   (:func:`pianist.env.loudness.velocity_to_speed`), so an angular rate; the key's planned
   angle rises at that rate along a line through the angle where it sounds at the end of the
   note's step (its frame less the servo's lag), from rest to the bottom of its travel. The
   push starts at the step where that line leaves rest.
2. **Execute** (:mod:`strike_prediction`, each step): the fingers are position servos that
   fall well short of their targets under a key's preloaded spring, and a key that breaks
   away covers most of its travel within a control step, so the finger's depth is chosen by
   predicting the step: the finger is sent to the breakaway depth (a finger resting on a
   key starts moving it only once sent ~70 % of the press depth below its top, ~50 % on a
   black key) and pushed on along its descent direction by the offset whose simulated step
   ends nearest the planned angle. Before its push the finger rests on the key; once the
   key has sounded it holds it at the full press depth like any other finger.

Louder notes than ``StrikeConfig.push_below_velocity`` are struck, and so are the notes a
push could not start early enough for (the episode's first steps, while the hands arrive).
How loud a strike reads depends on how far its key has gone when the next control step
starts, and whether it sounds in its own step on how hard it is struck, so the first step
of each strike is predicted too (``predict_strikes``, :mod:`strike_prediction`): its force
is chosen to sound in the note's step, nearest its velocity. No note of a song of one
velocity throughout is pushed.

Inputs: the goal frames (keys and velocities), each key's lever and angles, the control step.
Output: a :class:`StrikePlan`, (T, 88) arrays read by the fingertip targets (:mod:`targets`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pianist.env.loudness import KEY_LEVER_M, velocity_to_speed
from pianist.music import GoalFrames
from pianist.sim import constants as C

#: (88,) rad: the angle at which each key sounds (its activation threshold).
SOUND_ANGLE_RAD = C.KEY_MAX_ANGLE_RAD - C.KEY_ACTIVATION_THRESHOLD_RAD
#: A predicted push aims its key this share of a step's planned rise above its planned line,
#: so that it crosses the angle where it sounds within its step and not just after it.
PUSH_SOUND_MARGIN = 0.3
#: The first step a push may start at: before it the hands are still arriving at the keys.
FIRST_PUSH_STEP = 2


@dataclass(frozen=True)
class StrikePlan:
    """Per goal frame and key, how the note due there is struck.

    Attributes:
        rate: (T, 88) rad per control step the key's planned angle rises while it is
            pushed (0: struck at full speed, or not due).
        sound: (T, 88) int, the step at whose end the key should reach the angle where it
            sounds (meaningful where ``rate`` is not 0).
        start: (T, 88) int, the first step of the push.
        predicted: (T, 88) bool, notes struck with the force whose predicted strike sounds
            in their step nearest their velocity (:mod:`strike_prediction`): with
            ``predict_strikes`` (in its songs), every due note not pushed.
    """

    rate: np.ndarray
    sound: np.ndarray
    start: np.ndarray
    predicted: np.ndarray

    @property
    def pushed(self) -> bool:
        """Whether any note is pushed."""
        return bool(self.rate.any())


def plan_strikes(
    goal: GoalFrames,
    push_below: int,
    lag_frames: int,
    speed_scale: float = 1.0,
    predict_strikes: str = "never",
) -> StrikePlan:
    """The planned descent of every due note's key from its MIDI velocity.

    Args:
        goal: the goal frames; a note is a run of frames its key is due (a new run starts
            where the key was not due the frame before).
        push_below: notes softer than this MIDI velocity are pushed (0: none); none is in a
            song whose notes all have one velocity.
        lag_frames: frames before its note's frame a key should sound (the servo's lag).
        speed_scale: the key speeds asked for, as a share of those the velocities map to (a
            calibration of what the execution achieves).
        predict_strikes: where the notes not pushed are struck with a predicted force
            (:mod:`strike_prediction`): ``"dynamics"`` in a song whose notes' velocities
            differ, ``"always"`` in any song, ``"never"``.
    Returns:
        The :class:`StrikePlan`.
    """
    keys = goal.keys
    T = keys.shape[0]
    starts = keys & ~np.vstack([np.zeros((1, keys.shape[1]), dtype=bool), keys[:-1]])
    # The frame each due key's note began: the last start at or before it.
    onset = np.maximum.accumulate(np.where(starts, np.arange(T)[:, None], -1), axis=0)
    rate = np.zeros(keys.shape)
    predicted = np.zeros(keys.shape, dtype=bool)
    velocities = goal.velocities[keys]
    if push_below > 0 and velocities.size and velocities.min() != velocities.max():
        pushed = keys & (goal.velocities < push_below)
        speed = speed_scale * velocity_to_speed(goal.velocities)  # m/s at the front edge
        per_step = speed * goal.dt / KEY_LEVER_M[None, :]
        rate[pushed] = per_step[pushed]
    sound = np.where(keys, onset - lag_frames, 0)
    # The first step whose end the planned angle is above rest.
    lead = SOUND_ANGLE_RAD[None, :] / np.where(rate > 0, rate, np.inf)
    start = sound - np.ceil(lead - 1e-9).astype(np.int64) + 1
    # A push that would start while the hands are still arriving at the first keys (the
    # episode's first steps) is struck instead: it could not rest on its key first.
    early = start < FIRST_PUSH_STEP
    rate[early & (rate > 0)] = 0.0
    varied = bool(velocities.size) and velocities.min() != velocities.max()
    if predict_strikes == "always" or (predict_strikes == "dynamics" and varied):
        predicted = keys & (rate == 0)
    return StrikePlan(
        rate=rate, sound=sound, start=np.where(rate > 0, start, sound), predicted=predicted
    )


def planned_angle(plan: StrikePlan, frame: int, key: int, step: int) -> float:
    """The pushed key's planned angle (rad) at the end of ``step``: on the line through the
    angle where it sounds at the end of its ``sound`` step, from rest to the bottom."""
    angle = SOUND_ANGLE_RAD[key] + plan.rate[frame, key] * (step - plan.sound[frame, key])
    return float(min(max(angle, 0.0), C.KEY_MAX_ANGLE_RAD[key]))
