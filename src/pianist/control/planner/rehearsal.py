"""Rehearsal: a candidate plan played through once on a private copy of the environment.

Which of the planner's whole-piece plans plays a piece best is decided by playing each one:
the plans' own estimates (the key-frames or the per-step F1 each leaves playable) rank them
well where they differ in reach, and badly where they differ in how they are executed
(the right-hand C major scale's whole-piece plans lift the hand two frames early for the
thumb's crossing and play 0.91-0.93, its step-F1 plan 0.77, where the frame-by-frame plan,
as playable, plays 0.96). The physics
is deterministic, so a rehearsal's score is the score of the performance that follows it
from the same state, and the performance can replay the winner's actions instead of
computing them again (:class:`Replay`), and the environment its steps instead of simulating
them again (the rehearsal's :class:`~pianist.env.tape.StepTape`).

Inputs: an :class:`~pianist.control.planner.IKPlanner` just reset (its plan made), put with
its memory on a :class:`~pianist.control.lookahead.LookAhead` at the reset state, recording
(``look.start(planner, state, memory, record=True)``).
Output: the rehearsal's F1 (the metrics' per-step mean) and its :class:`Replay`.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from pianist.control.lookahead import LookAhead
from pianist.control.planner.hand import FingerMemory
from pianist.control.scoring import step_f1
from pianist.env.handle import ControlHandle
from pianist.env.tape import StepTape, same_state


class Rehearsable(Protocol):
    """What a rehearsal needs of the planner (:class:`~pianist.control.planner.IKPlanner`)."""

    finger_states: np.ndarray
    """(T, 10) the fingers' states per step, as played."""

    def attach(self, handle: ControlHandle) -> None: ...
    def memory(self) -> list[FingerMemory]: ...
    def act(self, observation: object = None) -> np.ndarray: ...


@dataclass
class Replay:
    """A rehearsal's steps, to be played again from the same state.

    Attributes:
        actions: (T, A) the action played at each step.
        tape: the rehearsal's steps as the environment took them (their states, and what
            they returned), for the environment to play back.
        memories: per step, the planner's memory after its action (what acting would have
            left it, so the planner acts on live from any step where the performance leaves
            the rehearsal's path).
        finger_states: (T, 10) the fingers' states as rehearsed.
        f1s: (T,) each step's F1.
        states: the environment's state (an ``EnvState``) before each step asked to be
            kept (``rehearse``'s ``keep``), by step: where a rehearsal of another plan
            that is the same until then can start.
    """

    actions: np.ndarray
    tape: StepTape
    memories: list[list[FingerMemory]]
    finger_states: np.ndarray
    f1s: np.ndarray
    states: dict[int, Any] = field(default_factory=dict)

    def on_path(self, step: int, handle: ControlHandle) -> bool:
        """Whether the environment is where the rehearsal was before ``step``."""
        return step < len(self.actions) and same_state(self.tape.state_before(step), handle.data)


def rehearse(
    planner: Rehearsable,
    look: LookAhead,
    give_up_at: float = np.inf,
    act: Callable[[], np.ndarray] | None = None,
    plan_f1: np.ndarray | None = None,
    keep: Collection[int] = (),
    after: tuple[Replay, int] | None = None,
) -> tuple[float, Replay | None]:
    """Play ``planner``'s current plan through on ``look``'s fork (started with the planner
    at the state it was reset in, recording; it is stepped to the episode's end) and score
    it.

    A plan the same as one rehearsed already up to some step need only be rehearsed from
    there: ``after`` = (that rehearsal, its step k), with ``look`` started at the state the
    rehearsal kept before step k (``Replay.states``) and the memory it left after step
    k - 1. The steps before k are that rehearsal's (their F1, actions, memories and finger
    states), and the replay returned plays them and then this one's.

    The planner acts on the fork while it rehearses; the caller brings it back to its own
    environment with its memory afterwards (``look.back``).

    Args:
        planner: the planner, its plan made.
        look: the look-ahead to rehearse on, started and recording.
        give_up_at: stop as soon as the steps' F1 lost so far (the sum over steps of
            1 - the step's F1), plus what the steps still to come lose at the least, reaches
            this: another plan lost no more over the whole piece.
        act: the planner's step (default ``planner.act(None)``; :class:`IKPlanner` passes
            its own, so that a subclass's ``act`` is not rehearsed).
        plan_f1: (T,) each step's F1 if exactly the plan's playable keys sound, taken as the
            most a step to come scores (default 1). Not a strict bound: a key beyond the reach
            model sometimes sounds (measured on five pieces and three plans each, the steps
            scoring above it add at most 0.015 to an episode's F1, mostly under 0.003), so a
            rehearsal is at times given up that would have won by less than that.
        keep: steps before which to keep the environment's state (``Replay.states``).
        after: the rehearsal this one takes its first k steps from, and k (see above).
    Returns:
        The episode F1 (mean over the steps of each step's F1) and the :class:`Replay`; or,
        given up, the most the F1 could still have reached and None.
    """
    steps = max(look.handle.num_steps, 1)
    # least_lost[t]: the least F1 the steps after step t lose.
    best_case = np.ones(steps) if plan_f1 is None else np.minimum(plan_f1[:steps], 1.0)
    least_lost = np.r_[np.cumsum((1.0 - best_case)[::-1])[::-1][1:], 0.0]
    if look.tape is None:
        raise ValueError("a rehearsal records its steps: start the look-ahead with record=True")
    actions: list[np.ndarray] = []
    memories: list[list[FingerMemory]] = []
    f1s: list[float] = []
    if after is not None:
        head, k = after
        if look.handle.step_index != head.tape.start_step + k:
            raise ValueError(f"a rehearsal after step {k} of another starts at that step")
        actions, memories = list(head.actions[:k]), head.memories[:k]
        f1s = head.f1s[:k].tolist()
        planner.finger_states[:k] = head.finger_states[:k]
    states: dict[int, Any] = {}
    lost, done = float(np.sum(1.0 - np.asarray(f1s))), False
    while not done:
        if look.handle.step_index in keep:
            states[look.handle.step_index] = look.snapshot()
        action = act() if act is not None else planner.act(None)
        terminated, info = look.step(action)
        done = terminated or look.handle.step_index >= look.handle.num_steps
        actions.append(action)
        memories.append(planner.memory())
        f1s.append(float(step_f1(info["active_keys"], info["goal_keys"])))
        lost += 1.0 - f1s[-1]
        bound = lost + least_lost[min(len(f1s) - 1, steps - 1)]
        if bound >= give_up_at and not done:
            return float(1.0 - bound / steps), None
    tape = look.close_tape()
    assert tape is not None  # at least one step was recorded
    if after is not None:
        tape = StepTape.spliced(after[0].tape, after[1], tape)
    f1 = np.array(f1s)
    replay = Replay(np.array(actions), tape, memories, planner.finger_states.copy(), f1, states)
    return float(np.mean(f1)), replay


def f1_lost(f1: float, steps: int) -> float:
    """The steps' F1 lost over an episode of ``steps`` steps with episode F1 ``f1``."""
    return (1.0 - f1) * steps
