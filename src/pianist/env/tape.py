"""A tape of steps: steps recorded on a fork of an environment, played back on the environment
itself without simulating them again.

The physics is deterministic, so steps taken on a :meth:`PianoEnv.fork` from some state are
exactly the steps the environment would take from that state with the same actions. A
controller that has already played a stretch ahead on a fork (a look-ahead,
:mod:`pianist.control.lookahead`: the planner's rehearsal of the piece, the segment search's
winning candidate) can hand the recording to the environment (:meth:`PianoEnv.play_tape`):
from then on each step whose action is the tape's next returns the recorded outputs and sets
the recorded state, at the cost of a copy instead of a control step of physics.

A tape plays only in an environment of the same goal frames and configuration, from the
state it was recorded from (every field of it). While it plays, ``data`` holds each step's
``qpos``, ``qvel``, ``act``, ``ctrl``, ``userdata`` and ``time`` and the poses derived from
them (``mj_kinematics``: what observations and rendering read); its other fields (contacts,
forces, sensors and their history, tendon and actuator lengths, velocities of bodies) are
stale until the tape is left. It is left at the first action that is not the tape's, at a
snapshot or fork, and at its last step (the recorded final state is restored whole), and
dropped at a reset or restore. Leaving it before its end restores its start and simulates
the steps played from it, so the environment is then exactly where simulating every step
would have put it: at worst a tape costs what playing without it does.

The observations are not recorded (they are most of a step's outputs): the environment
makes them again from the recorded state, bit for bit the simulated ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

StepOutputs = tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]
"""What ``PianoEnv.step`` returns: observation, reward, terminated, truncated, info."""
Outcome = tuple[float, bool, bool, dict[str, Any]]
"""A recorded step's reward, terminated, truncated and info."""


class Recordable(Protocol):
    """What a tape records from (a :class:`~pianist.env.PianoEnv`; this module does not
    import it, which imports this one)."""

    data: mujoco.MjData
    config: Any
    goal: Any

    def step(self, action: np.ndarray) -> StepOutputs: ...
    def snapshot(self, reuse: Any = None) -> Any: ...


_STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "userdata")


def physics_state(data: mujoco.MjData) -> tuple[np.ndarray, ...]:
    """Copies of ``data``'s qpos, qvel, act, ctrl, userdata and time (as a (1,) array): the
    state a step starts from, as far as a controller's action depends on it."""
    return (*(getattr(data, name).copy() for name in _STATE_FIELDS), np.array([data.time]))


def same_state(state: tuple[np.ndarray, ...], data: mujoco.MjData) -> bool:
    """Whether ``data`` is bit for bit at the :func:`physics_state` ``state``."""
    now = (*(getattr(data, name) for name in _STATE_FIELDS), np.array([data.time]))
    return all(np.array_equal(x, y) for x, y in zip(state, now, strict=True))


def clean_action(action: Any) -> np.ndarray | None:
    """The action as ``PianoEnv.step`` applies it ((A,) float64, clipped to [-1, 1]), or
    None if it is not finite."""
    action = np.asarray(action, dtype=np.float64)
    if not np.all(np.isfinite(action)):
        return None
    return np.clip(action, -1.0, 1.0)


@dataclass
class StepTape:
    """Steps recorded on an environment from a snapshot of it (:meth:`record`).

    Attributes:
        start: the environment's full state before the first step (an ``EnvState``).
        config: the environment's configuration (``EnvConfig``).
        goal: its goal frames (``GoalFrames``; the tape plays only with this very object).
        actions: per step, the action as applied ((A,) float64, clipped).
        outcomes: per step, what ``step`` returned but the observation (read-only copies).
        states: per step, the :func:`physics_state` after it.
        end: the full state after the last step (None while recording; an ``EnvState``).
    """

    start: Any
    config: Any
    goal: Any
    actions: list[np.ndarray] = field(default_factory=list)
    outcomes: list[Outcome] = field(default_factory=list)
    states: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    end: Any = None

    @classmethod
    def begin(cls, env: Recordable, start: Any = None) -> StepTape:
        """A tape starting at ``env``'s current state; step it with :meth:`record`.

        ``start``: a snapshot of ``env`` taken in that very state that the caller will not
        change (``env`` was just restored to it), to keep instead of taking another."""
        return cls(
            start=env.snapshot() if start is None else start, config=env.config, goal=env.goal
        )

    @classmethod
    def spliced(cls, head: StepTape, steps: int, tail: StepTape) -> StepTape:
        """``head``'s first ``steps`` steps followed by ``tail``, recorded from the state
        ``head`` was in after them (a look-ahead that left ``head``'s path there).

        Raises:
            ValueError: ``tail`` does not start ``steps`` steps after ``head``, or is not
                closed.
        """
        if tail.end is None or tail.start_step != head.start_step + steps or steps > len(head):
            raise ValueError("a spliced tape's tail starts where its head's steps end, closed")
        return cls(
            start=head.start,
            config=head.config,
            goal=head.goal,
            actions=head.actions[:steps] + tail.actions,
            outcomes=head.outcomes[:steps] + tail.outcomes,
            states=head.states[:steps] + tail.states,
            end=tail.end,
        )

    def __len__(self) -> int:
        return len(self.actions)

    @property
    def start_step(self) -> int:
        """The index of the goal frame the tape's first step plays."""
        return self.start.step

    def record(self, env: Recordable, action: np.ndarray) -> StepOutputs:
        """Step ``env`` (the environment the tape began on) with ``action`` and record it."""
        outputs = env.step(action)
        applied = clean_action(action)
        assert applied is not None  # step refuses a non-finite action
        _, reward, terminated, truncated, info = outputs
        kept = dict(info)  # copies: what the caller does with its outputs is its own
        kept["active_keys"] = _frozen(info["active_keys"])
        kept["reward_terms"] = dict(info["reward_terms"])
        self.actions.append(_frozen(applied))
        self.outcomes.append((reward, terminated, truncated, kept))
        self.states.append(tuple(_frozen(x) for x in physics_state(env.data)))
        self.end = None
        return outputs

    def finish(self, env: Recordable, reuse: Any = None) -> StepTape:
        """Close the tape at ``env``'s current state (after its last recorded step);
        ``reuse``: a snapshot done with, whose simulator copy the closing one takes over."""
        self.end = env.snapshot(reuse)
        return self

    def state_before(self, index: int) -> tuple[np.ndarray, ...]:
        """The :func:`physics_state` before the tape's step ``index``."""
        if index == 0:
            return physics_state(self.start.data)
        return self.states[index - 1]

    def matches(self, index: int, action: Any) -> bool:
        """Whether ``action`` is the one the tape's step ``index`` applied."""
        applied = clean_action(action)
        return (
            applied is not None
            and index < len(self.actions)
            and applied.shape == self.actions[index].shape
            and np.array_equal(applied, self.actions[index])
        )

    def set_state(self, index: int, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Put ``data`` at the state after the tape's step ``index``, its positions derived."""
        state = self.states[index]
        for name, value in zip(_STATE_FIELDS, state, strict=False):
            getattr(data, name)[:] = value
        data.time = float(state[-1][0])
        mujoco.mj_kinematics(model, data)

    def outcome(self, index: int) -> Outcome:
        """The reward, flags and info of the tape's step ``index`` (the info's arrays fresh
        copies or views of the goal, as ``step`` returns them)."""
        reward, terminated, truncated, kept = self.outcomes[index]
        info = dict(kept)
        info["active_keys"] = kept["active_keys"].copy()
        info["reward_terms"] = dict(kept["reward_terms"])
        return reward, terminated, truncated, info


def _frozen(array: np.ndarray) -> np.ndarray:
    """A read-only copy of ``array``."""
    out = np.array(array)
    out.setflags(write=False)
    return out
