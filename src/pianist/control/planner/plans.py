"""The planner's plans as data, and the cache that keeps them between episodes.

- :class:`HandPlanArrays`: one hand's plan for a song, made at reset and read only after;
- :class:`Plan`: a candidate plan, both hands' arrays and the fingering;
- :class:`PlanCache`: plans, their rehearsals and rehearsed scores by their inputs (the goal
  frames' content, the scene's options, the planner's config), so that a new episode of the
  same song in the same scene plans nothing again; :data:`PLANS` is the planners' shared one.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from pianist.control.planner.config import PlanKind, PlannerConfig

if TYPE_CHECKING:
    from pianist.control.planner.rehearsal import Replay
    from pianist.music import GoalFrames
    from pianist.sim.scene import SceneOptions


@dataclass(frozen=True)
class HandPlanArrays:
    """One hand's plan for a song of T frames, as it plays it
    (:func:`pianist.control.planner.forearm.plan_commands` makes it from the hand's plan; the
    execution stages are given it)."""

    tx_plan: np.ndarray
    """(T,) m: the forearm slide's planned position at each frame."""
    tx_held: np.ndarray
    """(T,) m: the plan as followed, each shift's old position held until it leaves."""
    busy: np.ndarray
    """(T,) bool: the hand has keys due."""
    skip: np.ndarray
    """(T, 88) bool: the hand's keys the plan leaves out."""
    free: np.ndarray
    """(T,) bool: the hand's fingers are lifted for a shift."""
    shift_to: np.ndarray
    """(T,) int: during a shift, the frame it moves for."""
    tx_path: np.ndarray
    """(T + 2, 2): the slide's reference position (m) and velocity (m/s) after each step."""
    pose_plan: np.ndarray
    """(T,) int: the hand's planned pose at each frame (0: home)."""
    pose_held: np.ndarray
    """(T,) int: the pose commanded at each step (each turn made in its shift's frames)."""

    def same_as(self, other: HandPlanArrays) -> bool:
        """Whether the two plans are equal array for array."""
        return all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in fields(self)
        )


@dataclass(frozen=True)
class Plan:
    """A candidate plan of both hands."""

    kind: PlanKind
    """How it was made (``PLAN_CANDIDATES``)."""
    fingers: np.ndarray
    """(T, 88) int: the finger 0-9 of each due key."""
    hands: tuple[HandPlanArrays, ...]
    """Each hand's arrays, in the planner's order of hands."""

    def same_as(self, other: Plan) -> bool:
        """Whether the two give the same fingers and hand arrays (their kinds may differ)."""
        return np.array_equal(self.fingers, other.fingers) and all(
            a.same_as(b) for a, b in zip(self.hands, other.hands, strict=True)
        )

    def first_difference(self, other: Plan) -> int:
        """The first frame at which the two plans differ in any per-frame array (the
        fingering, or a hand's arrays; a path's rows count as frames), or the number of
        frames if they never do. Before it the two plans' arrays are the same row for row."""
        T = self.fingers.shape[0]
        pairs = [(self.fingers, other.fingers)]
        for a, b in zip(self.hands, other.hands, strict=True):
            pairs += [(getattr(a, f.name), getattr(b, f.name)) for f in fields(a)]
        first = T
        for x, y in pairs:
            rows = (np.asarray(x) != np.asarray(y)).reshape(len(x), -1).any(axis=1)
            differ = np.flatnonzero(rows)
            if differ.size:
                first = min(first, int(differ[0]))
        return first


@dataclass(frozen=True)
class CachedPlan:
    """What a reset made for a song: the chosen plan, its rehearsal to replay (None without
    rehearsal) and each candidate's rehearsed F1."""

    plan: Plan
    replay: Replay | None
    rehearsed: dict[str, float]
    rehearsed_from: dict[str, int]


def goal_digest(goal: GoalFrames) -> str:
    """A digest of the goal frames' content a plan and its rehearsal depend on: keys,
    fingers, pedal, velocities (the pushed strikes, ``push_below_velocity``), step."""
    h = hashlib.blake2b(digest_size=16)
    for array in (goal.keys, goal.fingers, goal.sustain, goal.velocities):
        h.update(str(array.shape).encode())
        h.update(np.ascontiguousarray(array).tobytes())
    h.update(repr(float(goal.dt)).encode())
    return h.hexdigest()


class PlanCache:
    """Plans by their inputs: the goal frames' content (:func:`goal_digest`), the scene's
    options and the planner's config; the ``kept`` most recently made are kept (a rehearsal
    holds its episode's states: a few MB a minute of music)."""

    def __init__(self, kept: int = 8) -> None:
        if kept < 1:
            raise ValueError(f"a plan cache keeps at least 1 plan, not {kept}")
        self.kept = kept
        self._entries: OrderedDict[tuple[str, SceneOptions, PlannerConfig], CachedPlan] = (
            OrderedDict()
        )

    def get(
        self, goal: GoalFrames, options: SceneOptions, config: PlannerConfig
    ) -> CachedPlan | None:
        """The plan made for these inputs, or None."""
        return self._entries.get((goal_digest(goal), options, config))

    def put(
        self, goal: GoalFrames, options: SceneOptions, config: PlannerConfig, entry: CachedPlan
    ) -> None:
        """Keep ``entry`` for these inputs (the oldest entry goes when the cache is full)."""
        key = (goal_digest(goal), options, config)
        self._entries.pop(key, None)
        while len(self._entries) >= self.kept:
            self._entries.popitem(last=False)
        self._entries[key] = entry

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)


#: The planners' shared cache (``IKPlanner(cache=...)`` gives one its own).
PLANS = PlanCache()
