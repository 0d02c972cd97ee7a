"""An inverse-kinematics planner: plays a song whose notes have hands, with no training.

At reset it plans where each forearm will be along the keyboard over the whole piece, either
frame by frame with the song's fingering (the hand goes where the assigned fingers reach
their keys, and stays while they still do) or over the whole piece at once
(:mod:`pianist.control.planner.hand_plan`: a dynamic programme that also chooses the fingers the
Shadow hand can actually span, and shares keys one hand cannot reach with the other, counting
either lost key-frames or the per-step F1 the metric scores), and keeps the plan that plays
best when each is rehearsed once on a copy of the environment (``PlanConfig.hand_planning``,
``choose_plan``); the performance replays the winner's rehearsal while it stays on its path.
Then each control step it

1. steers each forearm's slide along that plan: a quick move that ends as the note starts
   (a jump takes the steps the slide's servo needs, on a minimum-jerk path), in closed loop
   through the servo's exact dynamics; for a large move the fingers let go of their keys and
   travel just above the next ones; with the optional height slide (``tz``) the forearm is
   held low enough for the thumb to reach a key's bottom, pushed down harder when the keys
   lift it;
2. gives every fingertip a target from the finger's state in that step
   (:class:`~pianist.control.planner.targets.FingerState`: lifted, hovering, pressing,
   pushing, re-striking, travelling): the assigned fingertip pressed below the top of each
   key due at the coming frame (once it is over the key), fingers due soon hovering above
   their keys, the others lifted to a fixed posture clear of the keyboard;
3. solves each finger's inverse kinematics with the wrist held still, so the five fingers are
   independent small problems: the nearest of a few thousand sampled postures of that finger
   (computed once at reset, which avoids the local minima the thumb falls into), then a few
   damped least-squares iterations on ``mujoco.mj_jacSite`` over the finger's actuated joints
   (a J1+J2 tendon counts as one joint, its angle split evenly), clipped to the joint limits;
4. sends those angles as the position-servo controls; the pedal follows the goal.

The stages, one module each (read in this order), are functions of the hand's indices, its
pose, its plan's arrays and its fingers' memory; none keeps state of its own:

- :mod:`~pianist.control.planner.config`: :class:`PlannerConfig`, :data:`ENV_OPTIONS`;
- :mod:`~pianist.control.planner.hand`: one hand's indices into the model (:class:`Hand`,
  each finger's joints) and what its fingers remember between steps (:class:`FingerMemory`);
- :mod:`~pianist.control.planner.postures`: the hand's poses (wrist straight or turned),
  and per pose the sampled postures, lifted posture and reach; the wrist's command;
- :mod:`~pianist.control.planner.forearm`: the forearm's plan along the keyboard and its
  path, steered in closed loop (step 1);
- :mod:`~pianist.control.planner.targets`: each fingertip's target (step 2);
- :mod:`~pianist.control.planner.ik`: each finger's inverse kinematics (step 3);
- :mod:`~pianist.control.planner.hand_plan`, :mod:`~pianist.control.planner.hand_split`,
  :mod:`~pianist.control.planner.hand_order`: the whole-piece plans (arrays in, arrays out);
- :mod:`~pianist.control.planner.coverage`: the reach ceiling and a plan's bound;
- :mod:`~pianist.control.planner.plans`: a plan as data, and the cache of plans by their
  inputs;
- :mod:`~pianist.control.planner.rehearsal`: a candidate plan played through on a fork of
  the environment, and its replay;
- :mod:`~pianist.control.planner.controller`: :class:`IKPlanner`, the plan choice and the
  step (step 4).
"""

from pianist.control.planner.config import (
    ENV_OPTIONS,
    FingerConfig,
    ForearmConfig,
    IKConfig,
    KeyPressConfig,
    PlanConfig,
    PlannerConfig,
    PoseConfig,
    StrikeConfig,
)
from pianist.control.planner.controller import IKPlanner, forget_plans
from pianist.control.planner.targets import FingerState

__all__ = [
    "ENV_OPTIONS",
    "FingerConfig",
    "FingerState",
    "ForearmConfig",
    "IKConfig",
    "IKPlanner",
    "KeyPressConfig",
    "PlanConfig",
    "PlannerConfig",
    "PoseConfig",
    "StrikeConfig",
    "forget_plans",
]
