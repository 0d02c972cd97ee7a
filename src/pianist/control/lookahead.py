"""Looking ahead with the physics: a controller played on a private copy of its episode's
environment and brought back, and the scoring of what it played.

Rehearsal (:mod:`pianist.control.planner.rehearsal`), refinement
(:mod:`pianist.control.refine`) and segment search (:mod:`pianist.control.search`) all do the
same four things, each with this module:

1. **fork**: :class:`LookAhead` holds a fork of the episode's environment
   (:meth:`pianist.env.PianoEnv.fork`: the same model, scene and goal, its own simulator);
2. **restore**: :meth:`LookAhead.start` puts the fork at a snapshot of the episode and the
   controller on the fork with a copy of its memory (:class:`Rewindable`), and
   :meth:`LookAhead.back` returns the controller to the episode with the memory it had;
3. **play ahead**: :meth:`LookAhead.step` steps the fork, recording its steps on a
   :class:`~pianist.env.tape.StepTape` when :meth:`LookAhead.start` was asked to, until
   :meth:`LookAhead.close_tape`; a look-ahead the episode then follows is handed to its
   environment to play back instead of simulating it again (:meth:`LookAhead.hand_over`);
4. **score and blame**: :func:`step_misses` gives a step's missed and wrong keys, and
   :func:`blame` the finger answerable for each (a missed key: the finger the plan gives it;
   a wrong key: the fingertip nearest it across the keys), which a caller sums per finger
   (refine) or per hand (search).

The physics is deterministic, so a look-ahead from a snapshot plays exactly what the episode
would play from that state with the same actions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from pianist.env.handle import ControlHandle, control_handle
from pianist.env.tape import StepTape

if TYPE_CHECKING:
    from pianist.env.piano_env import EnvState, PianoEnv


class Rewindable(Protocol):
    """A controller that can be played ahead on a fork and brought back."""

    def attach(self, handle: ControlHandle) -> None:
        """Act on another environment of the same song and scene from now on."""
        ...

    def memory(self) -> Any:
        """A copy of what the controller remembers between steps."""
        ...

    def set_memory(self, memory: Any) -> None:
        """Go back to a :meth:`memory` copy."""
        ...


class LookAhead:
    """A fork of an episode's environment to play a controller ahead on.

    Attributes:
        home: the episode's environment (the handle controllers are brought back to; a
            controller that is itself looked ahead on another fork moves its home there).
        env: the fork.
        handle: the fork's control handle.
        tape: the steps played since :meth:`start` (``record=True``) or None.
    """

    def __init__(self, home: ControlHandle, seed: int | None = None) -> None:
        """Fork ``home`` in its current state (of an environment with no episode started,
        the state its ``reset(seed=seed)`` starts from)."""
        self.home = home
        self.env: PianoEnv = home.fork(seed)
        self.handle = control_handle(self.env)
        self.tape: StepTape | None = None

    def start(
        self, controller: Rewindable, state: EnvState, memory: Any, record: bool = False
    ) -> None:
        """Put the fork at ``state`` (a snapshot of the episode or of the fork) and
        ``controller`` on the fork with ``memory``; with ``record``, record the steps from
        there on a new :attr:`tape` (``state`` kept as its start: not to be changed)."""
        self.env.restore(state)
        controller.attach(self.handle)
        controller.set_memory(memory)
        self.tape = StepTape.begin(self.env, start=state) if record else None

    def close_tape(self, reuse: EnvState | None = None) -> StepTape | None:
        """End the recording at the fork's state now and return the tape (None if nothing
        was recorded); the look-ahead's later steps are not on it. ``reuse``: a snapshot done
        with, whose simulator copy the tape's end takes over."""
        tape, self.tape = self.tape, None
        if tape is None or len(tape) == 0:
            return None
        return tape.finish(self.env, reuse)

    def hand_over(self, tape: StepTape) -> bool:
        """Give ``tape`` to the episode's environment to play back while the episode's
        actions are the tape's (:meth:`pianist.env.PianoEnv.play_tape`); whether it was
        taken (only from the state it was recorded from)."""
        return self.home.play_tape(tape)

    def back(self, controller: Rewindable, memory: Any) -> None:
        """Put ``controller`` back on the episode's environment with ``memory``."""
        controller.attach(self.home)
        controller.set_memory(memory)

    def step(self, action: np.ndarray) -> tuple[bool, dict[str, Any]]:
        """Step the fork with ``action`` (on the :attr:`tape` if one is recording): whether
        the episode ended there (terminated), and the step's info."""
        if self.tape is not None:
            _, _, terminated, _, info = self.tape.record(self.env, action)
        else:
            _, _, terminated, _, info = self.env.step(action)
        return terminated, info

    def snapshot(self, reuse: EnvState | None = None) -> EnvState:
        """The fork's state now (``reuse``: a snapshot done with, whose simulator copy is
        taken over)."""
        return self.env.snapshot(reuse)

    def tip_y(self, sites: np.ndarray) -> np.ndarray:
        """(len(sites),) the fork's fingertip sites' positions across the keys (m)."""
        return self.handle.data.site_xpos[sites, 1]


def step_misses(due: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The keys of one step: (missed,) due and not sounding, and (wrong,) sounding and not
    due, from its (88,) bool ``due`` and ``active`` keys."""
    return np.flatnonzero(due & ~active), np.flatnonzero(active & ~due)


def blame(
    missed: np.ndarray,
    wrong: np.ndarray,
    planned: np.ndarray,
    key_y: np.ndarray,
    tip_y: np.ndarray,
    tip_fingers: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The fingers (0-9) answerable for a step's misses.

    Args:
        missed, wrong: the step's missed and wrong keys (:func:`step_misses`).
        planned: (88,) the finger the plan gives each key this step (-1: none).
        key_y: (88,) each key's press point across the keyboard (m).
        tip_y: (F,) the fingertips' positions across the keyboard (m).
        tip_fingers: (F,) the finger (0-9) of each fingertip.
    Returns:
        The finger of each missed key that has one (its planned finger), and of each wrong
        key (the fingertip nearest it across the keys).
    """
    owners = planned[missed]
    by_tip = tip_fingers[:0]
    if wrong.size:
        nearest = np.argmin(np.abs(key_y[wrong, None] - tip_y[None, :]), axis=1)
        by_tip = tip_fingers[nearest]
    return owners[owners >= 0], by_tip
