"""Segment search: per half second of music, the execution variant that plays it best,
verified with the physics.

The planner's execution stages have settings that help one passage and cost another (a
stiffer wrist holds a chord's last finger on its key but lifts the thumb; a harder push
sounds a weak finger's key and drags a neighbour down), so no single setting is best for a
whole piece. :class:`SegmentSearch` chooses among a few named settings (:data:`VARIANTS`)
while it plays, for each hand apart. At the start of every segment (``segment_steps`` control
steps) it plays each variant, with both hands, from the current state on a fork of the
environment (the full physics state, :meth:`pianist.env.PianoEnv.snapshot` / ``restore``)
for the segment and ``overlap_steps`` beyond it, and scores it by the episode's own metric
(the sum over steps of 1 - F1 of the sounding keys against the due keys). Each look-ahead's
misses are also split between the hands (a due key not sounding: its planned finger's hand; a
key sounding that is not due: the hand of the nearest fingertip), and each hand's best variant
is looked ahead together as one more candidate. The segment is played with the candidate that
lost least. The plain settings come first and win ties, and a plain look-ahead without a loss
ends the search early, so where nothing does better the base plays as it would alone.

It searches over anything that can be run ahead on a fork and brought back (the
:class:`Searchable` protocol): the planner, or the refiner
(:class:`pianist.control.refine.Refiner`), whose per-step look-ahead it then wraps. It costs
about ``(len(variants) + 1) * (segment + overlap) / segment`` times the base's simulated
steps, plus the base's own.

Stages, each a method: :meth:`SegmentSearch._choose` (try each candidate with
:meth:`SegmentSearch._look_ahead`, score) at a segment's start; :meth:`SegmentSearch.act`
(the base with the chosen settings) at every step.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from typing import TYPE_CHECKING, Any, Protocol, cast

import gymnasium as gym
import numpy as np

from pianist.control.base import BaseController, Controller
from pianist.control.lookahead import LookAhead, Rewindable, blame, step_misses
from pianist.control.options import VARIANTS, SearchOptions
from pianist.control.planner.config import FINGERS_PER_HAND
from pianist.control.scoring import step_f1_loss
from pianist.env.handle import control_handle

if TYPE_CHECKING:
    from pianist.control.planner import IKPlanner
    from pianist.env.piano_env import EnvState
    from pianist.env.tape import StepTape
    from pianist.music import Song


class Searchable(Controller, Rewindable, Protocol):
    """A controller the search can run ahead on a fork and bring back
    (:class:`~pianist.control.lookahead.Rewindable`): the planner itself, or a controller
    with the planner as its ``planner`` (whose ``config`` the variants replace). It acts
    without an observation (``act(None)``) on a fork: it reads the simulator."""

    def act(self, observation: Any = None) -> np.ndarray: ...


def _planner(base: Searchable) -> IKPlanner:
    """The planner of ``base`` (the base itself when it is one)."""
    return cast("IKPlanner", getattr(base, "planner", base))


class SegmentSearch(BaseController):
    """A searchable controller (the planner by default), its execution settings chosen per
    segment and per hand by playing each candidate ahead with the physics."""

    def __init__(self, base: Searchable | None = None, options: SearchOptions | None = None):
        if base is None:
            from pianist.control.planner import IKPlanner

            base = IKPlanner()
        self.base = base
        self.options = options or SearchOptions()

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        return _planner(self.base).env_options(song)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self.base.reset(env, seed)
        self.handle = control_handle(env)
        self.look = LookAhead(self.handle)
        self.planner = _planner(self.base)
        own = self.planner.config
        self.configs = [own.with_fields(**VARIANTS[n]) for n in self.options.variants]
        hands = self.planner.hands
        # Whose a key is: the hand of its planned finger (0-9 -> index into hands), and
        # each fingertip's hand (for a wrong key, the hand of the nearest fingertip).
        self.finger_hand = np.zeros(2 * FINGERS_PER_HAND, dtype=int)
        for h, hand in enumerate(hands):
            self.finger_hand[hand.finger_offset : hand.finger_offset + FINGERS_PER_HAND] = h
        self.tip_sites = np.concatenate([hand.sites for hand in hands])
        self.tip_fingers = np.array(
            [hand.finger_offset + i for hand in hands for i in range(FINGERS_PER_HAND)]
        )
        T = self.handle.goal.num_frames
        # (T, hands) the variant (index into options.variants) each hand played each step.
        self.chosen = np.zeros((T, len(hands)), dtype=np.int8)
        # (T,) 1 - F1 of each step as the chosen candidate's look-ahead played it (the steps
        # past a segment are overwritten by the next segment's choice).
        self.predicted_loss = np.zeros(T)
        self._current: tuple[int, ...] = (0,) * len(hands)
        self._segments = 0
        self._seconds = 0.0
        # Each segment's candidates' recorded look-aheads, the winner's played back by the
        # environment (the planner's ``replay_tape``), and the segment's start state.
        self._replay_tape = self.planner.config.plan.replay_tape
        self._tapes: list[StepTape | None] = []
        self._state: EnvState | None = None

    def act(self, observation: Any = None) -> np.ndarray:
        t = self.handle.step_index
        if t % self.options.segment_steps == 0 and t < self.handle.goal.num_frames:
            start = time.perf_counter()
            self._current = self._choose(t)
            self._segments += 1
            self._seconds += time.perf_counter() - start
        if t < self.chosen.shape[0]:
            self.chosen[t] = self._current
        return self.base.act(observation)

    def _choose(self, t: int) -> tuple[int, ...]:
        """The variant of each hand for the segment from step ``t``: every variant is played
        on the fork by both hands from the current state, then each hand's best of them
        together (when they differ); the base is left as it was, with the chosen settings."""
        o = self.options
        # The last segment's start and its tapes' ends are done with (the environment left
        # its tape at this snapshot at the latest): their simulator copies are reused.
        state = self.handle.snapshot(reuse=self._state)
        self._state = state
        spare_ends = [tape.end for tape in self._tapes if tape is not None and tape.end is not None]
        self._tapes = []
        memory = self.base.memory()
        end = min(t + o.segment_steps + o.overlap_steps, self.handle.goal.num_frames)
        n_hands = self.chosen.shape[1]
        tried: list[tuple[int, ...]] = []
        losses: list[np.ndarray] = []  # per candidate, (steps,) 1 - F1
        hand_costs: list[np.ndarray] = []  # per candidate, (hands,) missed + wrong keys
        for variant in range(len(self.configs)):
            candidate = (variant,) * n_hands
            loss, cost = self._look_ahead(candidate, t, end, state, memory, spare_ends)
            tried.append(candidate)
            losses.append(loss)
            hand_costs.append(cost)
            if loss.sum() == 0.0:
                break  # nothing can do better, and the first of equals is chosen anyway
        if len(tried) == len(self.configs) and n_hands > 1:
            costs = np.stack(hand_costs)  # (candidates, hands); the first of equals per hand
            combined = tuple(tried[int(np.argmin(costs[:, h]))][h] for h in range(n_hands))
            if combined not in tried:
                tried.append(combined)
                losses.append(self._look_ahead(combined, t, end, state, memory, spare_ends)[0])
        best = int(np.argmin([loss.sum() for loss in losses]))
        self.predicted_loss[t:end] = losses[best]
        self.look.back(self.base, memory)
        self._use(tried[best])
        winner = self._tapes[best]
        if winner is not None:
            # The segment as the winner played it ahead: the same actions follow from the
            # same state and memory, so the environment plays it back.
            self.look.hand_over(winner)
        return tried[best]

    def _look_ahead(
        self,
        candidate: tuple[int, ...],
        t: int,
        end: int,
        state: EnvState,
        memory: Any,
        spare_ends: list[EnvState],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Play steps ``t`` to ``end`` on the fork from ``state`` with each hand's variant in
        ``candidate``: (steps,) 1 - F1 of each step, and (hands,) the keys each hand is
        answerable for (a due key not sounding: its planned finger's hand; a key sounding
        that is not due: the hand of the fingertip nearest it across the keys).

        The segment's steps (up to ``t + segment_steps``) are recorded; the tape (None if
        the look-ahead ended before the segment did) is appended to ``_tapes``, its end
        taking over one of ``spare_ends`` when there is one."""
        self.look.start(self.base, state, memory, record=self._replay_tape)
        self._use(candidate)
        segment_end = min(t + self.options.segment_steps, end)
        tape = None
        goal = self.handle.goal.keys
        fingers = self.planner.fingers
        key_y = self.planner.key_point[:, 1]
        loss = np.zeros(end - t)
        cost = np.zeros(self.chosen.shape[1])
        for j, step in enumerate(range(t, end)):
            terminated, info = self.look.step(self.base.act(None))
            if step + 1 == segment_end and not terminated:
                tape = self.look.close_tape(spare_ends.pop() if spare_ends else None)
            due, active = goal[step], info["active_keys"]
            loss[j] = step_f1_loss(due, active)
            missed, wrong = step_misses(due, active)
            # The fingertips are read only when a wrong key needs its nearest one.
            tip_y = self.look.tip_y(self.tip_sites) if wrong.size else key_y[:0]
            by_plan, by_tip = blame(missed, wrong, fingers[step], key_y, tip_y, self.tip_fingers)
            np.add.at(cost, self.finger_hand[by_plan], 1.0)
            np.add.at(cost, self.finger_hand[by_tip], 1.0)
            if terminated:
                loss[j + 1 :] = 1.0  # the steps it did not play lose everything
                break
        self._tapes.append(tape)
        return loss, cost

    def _use(self, candidate: tuple[int, ...]) -> None:
        self.planner.set_hand_settings([self.configs[v] for v in candidate])

    def stats(self) -> dict[str, float]:
        played = self.chosen[: self.handle.step_index]
        out = {"search_seconds_per_segment": self._seconds / max(self._segments, 1)}
        for i, name in enumerate(self.options.variants):
            out[f"search_share_{name}"] = float(np.mean(played == i)) if played.size else 0.0
        return {**self.base.stats(), **out}

    def plan_arrays(self) -> dict[str, np.ndarray]:
        """The base's plan, and ``search_variant`` (T, hands) int8: the index (into
        ``SearchOptions.variants``) of the variant each hand (in the planner's order) played
        each step with."""
        return {**self.base.plan_arrays(), "search_variant": self.chosen.copy()}

    def options_dict(self) -> dict[str, Any]:
        return {**self.base.options_dict(), "search": asdict(self.options)}
