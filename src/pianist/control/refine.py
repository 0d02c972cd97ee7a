"""Refinement with the physics: the planner's actions, improved by looking ahead.

At every step the planner (:class:`pianist.control.planner.IKPlanner`) proposes its action.
The refiner then tries ``candidates`` random perturbations of the fingers' part of it (with
``arm_sigma``, of the forearms' slides too), each held for ``horizon_steps`` steps while
the planner goes on acting in closed loop, on a fork of the environment restored to the
current state for every candidate (the full physics: :meth:`pianist.env.PianoEnv.fork` and
:meth:`~pianist.env.PianoEnv.restore`). It plays the
proposal plus the perturbation whose look-ahead left the fewest due keys unsounded and
sounded the fewest others; the perturbation chosen at one step is among the next step's
candidates (a finger that needed more push usually needs it for a few steps). The
unperturbed proposal is candidate 0 and wins ties, so where looking ahead finds nothing
better the planner plays as it would alone.

Keys the plan leaves out (no finger is sent to them: a chord wider than the hand) are not
counted in a look-ahead's cost: no perturbation of the fingers plays them, and a look-ahead
that misses only them ends the search as a perfect one does.

Each look-ahead's cost is also split among the fingers (a missed key is its planned
finger's, a wrong key the nearest fingertip's), and each finger's part of the perturbation
that cost it least is combined into one more candidate (``per_finger``). A look-ahead step
that ends with two neighbouring fingers crossed costs ``crossing_cost``: caught on each
other, they stay stuck longer than the look-ahead sees.

This is predictive sampling (the paper's MPC baseline) around the planner instead of around
a spline: the planner supplies the motion, the samples only correct what the physics does to
it (a finger that slides off, a key that flickers at the bottom of its travel, a late
strike). It costs up to ``(candidates + 2) * horizon_steps`` simulated steps per step, and
one where the planner's own action is played and its look-ahead finds nothing to correct:
the unperturbed look-ahead of the step before is then continued by one step
(``continue_look_ahead``).

With ``open_loop`` the perturbed candidates are not stepped with the planner in the loop:
each replays the unperturbed look-ahead's actions plus its offset, all of them at once in
MuJoCo's own threads (:mod:`pianist.control.rollout_ahead`), and the one that costs least
(and the per-finger combination) is then looked ahead in closed loop to be compared with the
planner's own: faster on two cores, a little less F1
(docs/notes/2026-12-07-planner-refine.md).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from pianist.control.base import BaseController
from pianist.control.lookahead import LookAhead, blame, step_misses
from pianist.control.options import RefineOptions
from pianist.env.handle import ControlHandle, control_handle
from pianist.env.tape import physics_state, same_state
from pianist.sim import constants as C

if TYPE_CHECKING:
    from pianist.control.planner import IKPlanner
    from pianist.control.planner.hand import FingerMemory
    from pianist.control.rollout_ahead import RolloutAhead
    from pianist.env.piano_env import EnvState
    from pianist.music import Song


@dataclass
class _Trace:
    """The unperturbed look-ahead of one step, per look-ahead step j (kept to be continued)."""

    step: int
    """The episode step it started from."""
    costs: list[float]
    per_finger: list[np.ndarray]
    """(10,) per step."""
    actions: list[np.ndarray]
    """The action played at each step (the planner's own)."""
    states: list[tuple[np.ndarray, ...]]
    """qpos, qvel, act and ctrl after each step."""
    end: EnvState | None = None
    """The fork's state after the last step, and the planner's memory then."""
    memory: list[FingerMemory] | None = None

    def total(self) -> tuple[float, np.ndarray]:
        """The look-ahead's cost, and (10,) each finger's part of it."""
        per_finger = np.zeros(10)
        for part in self.per_finger:
            per_finger += part
        return float(sum(self.costs)), per_finger


class Refiner(BaseController):
    """The planner, each action refined by looking ahead with the physics."""

    def __init__(self, planner: IKPlanner | None = None, options: RefineOptions | None = None):
        if planner is None:
            from pianist.control.planner import IKPlanner

            planner = IKPlanner()
        self.planner = planner
        self.options = options or RefineOptions()

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        return self.planner.env_options(song)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        self.planner.reset(env, seed)
        self.handle = control_handle(env)
        self.look = LookAhead(self.handle)
        self.rng = np.random.default_rng(0 if seed is None else seed)
        self.dims = self.planner.finger_action_dims()
        self.arm_dims = np.array([hand.tx_actuator for hand in self.planner.hands])
        # Each finger's (0-9) action dimensions and fingertip site, for the per-finger choice.
        hands = self.planner.hands
        self.finger_dims = {
            hand.finger_offset + i: finger.actuators
            for hand in hands
            for i, finger in enumerate(hand.fingers)
        }
        self.tip_fingers = np.array([hand.finger_offset + i for hand in hands for i in range(5)])
        self.tip_sites = np.concatenate([hand.sites for hand in hands])
        # (H,) per hand, +1 if its fingers go up the keyboard from thumb to little finger.
        self.hand_direction = np.array([1.0 if hand.side == "right" else -1.0 for hand in hands])
        # (T, 88) the due keys the plan gives a finger. The others (a chord wider than the
        # hand) no perturbation plays, so they are left out of a look-ahead's cost: a
        # look-ahead that misses only them ends the search as a perfect one does.
        goal = self.handle.goal
        self.planned = np.zeros_like(goal.keys)
        for hand, arrays in zip(hands, self.planner.plan.hands, strict=True):
            local = self.planner.fingers - hand.finger_offset
            self.planned |= goal.keys & ~arrays.skip & (local >= 0) & (local < len(hand.fingers))
        self._steps = self._refined = 0
        self._previous: np.ndarray | None = None
        self._seconds = 0.0
        self._state: EnvState | None = None
        # Steps simulated on the fork, all told (not rewound by ``set_memory``: a search's
        # look-aheads of the refiner cost them too).
        self.simulated_steps = 0
        self._trace: _Trace | None = None
        self._batched: RolloutAhead | None = None
        if self.options.open_loop and self.options.candidates > 0:
            self._batched = self._rollout_ahead()
            scene = self.handle.scene
            self._threshold = scene.key_max_angle_rad - C.KEY_ACTIVATION_THRESHOLD_RAD

    def _rollout_ahead(self) -> RolloutAhead:
        """The open-loop look-ahead of this episode's model: the last reset's if it was of the
        same model and scene (its thread pool and simulator copies are reused), else a new
        one."""
        from pianist.control.rollout_ahead import RolloutAhead

        h = self.handle
        kept = getattr(self, "_kept_rollout", None)
        if (
            kept is None
            or kept.model is not h.model
            or kept.substeps != h.config.substeps
            or not np.array_equal(kept.sites, self.tip_sites)
        ):
            kept = RolloutAhead(
                h.model, h.config.substeps, h.scene.key_qpos, self.tip_sites, self.options.threads
            )
            self._kept_rollout = kept
        return kept

    def act(self, observation: Any = None) -> np.ndarray:
        proposal = self.planner.act(observation)
        o = self.options
        if o.candidates == 0:
            return proposal
        start = time.perf_counter()
        memory = self.planner.memory()
        # The last step's snapshot is done with: its simulator copy is reused.
        state = self._state = self.handle.snapshot(self._state)
        offsets = np.zeros((o.candidates + 1, proposal.shape[0]), dtype=np.float32)
        offsets[1:, self.dims] = self.rng.normal(0.0, o.sigma, (o.candidates, self.dims.size))
        if o.arm_sigma > 0:
            arm = self.rng.normal(0.0, o.arm_sigma, (o.candidates, self.arm_dims.size))
            offsets[1:, self.arm_dims] = arm
        if o.keep_previous and self._previous is not None:
            offsets[1] = self._previous
        # A finger pushing a soft note or starting a strike has its command chosen by the
        # planner's own prediction of the steps ahead; a perturbation would undo it.
        offsets[:, self.planner.predicted_action_dims()] = 0.0
        costs: list[float] = []
        finger_costs: list[np.ndarray] = []
        for index, offset in enumerate(offsets):
            if index == 0:
                cost, per_finger = self._unperturbed(proposal, state, memory)
            elif self._batched is not None:
                more, more_fingers = self._open_loop_search(proposal, offsets[1:], state, memory)
                costs.extend(more)
                finger_costs.extend(more_fingers)
                break
            else:
                cost, per_finger = self._look_ahead(proposal, offset, state, memory)
            costs.append(cost)
            finger_costs.append(per_finger)
            if cost == 0.0:
                break  # nothing can do better; the same choice as trying them all
        if o.per_finger and len(costs) == len(offsets) > 1:
            combined = self._combine(offsets, np.stack(finger_costs))
            if not np.any(np.all(offsets == combined, axis=1)):
                offsets = np.vstack([offsets, combined])
                if self._batched is not None and not o.verify:
                    costs.append(self._open_loop(combined[None], state)[0][0])
                else:
                    costs.append(self._look_ahead(proposal, combined, state, memory)[0])
        # Back to the real episode, the planner as it was after proposing.
        self.look.back(self.planner, memory)
        best = int(np.argmin(costs))  # the first of equals: the proposal wins ties
        self._previous = offsets[best] if best > 0 else None
        if best > 0:
            self._trace = None  # the episode leaves the unperturbed look-ahead's path
        self._steps += 1
        self._refined += best > 0
        self._seconds += time.perf_counter() - start
        return np.clip(proposal + offsets[best], -1.0, 1.0)

    # What :class:`pianist.control.search.SegmentSearch` needs to run the refiner ahead.

    def memory(self) -> dict[str, Any]:
        """A copy of what the refiner remembers between steps (its planner's memory, the
        perturbation chosen last, its random generator and counters)."""
        return {
            "planner": self.planner.memory(),
            "previous": None if self._previous is None else self._previous.copy(),
            "rng": self.rng.bit_generator.state,
            "counts": (self._steps, self._refined),
        }

    def set_memory(self, memory: dict[str, Any]) -> None:
        """Go back to a :meth:`memory` copy."""
        self.planner.set_memory(memory["planner"])
        previous = memory["previous"]
        self._previous = None if previous is None else previous.copy()
        self.rng.bit_generator.state = memory["rng"]
        self._steps, self._refined = memory["counts"]

    def attach(self, handle: ControlHandle) -> None:
        """Act on another environment of the same song and scene from now on (a fork): its
        look-ahead fork is restored from that one's state each step, so it stays."""
        self.handle = self.look.home = handle
        self.planner.attach(handle)

    def _combine(self, offsets: np.ndarray, finger_costs: np.ndarray) -> np.ndarray:
        """(A,) each finger's part of the offset whose look-ahead cost that finger least (the
        first of equals, so the proposal's own where nothing did better), from ``offsets``
        (N, A) and ``finger_costs`` (N, 10)."""
        combined = offsets[0].copy()
        for finger, dims in self.finger_dims.items():
            combined[dims] = offsets[int(np.argmin(finger_costs[:, finger])), dims]
        return combined

    def _look_ahead(
        self,
        proposal: np.ndarray,
        offset: np.ndarray,
        state: EnvState,
        memory: list[FingerMemory],
    ) -> tuple[float, np.ndarray]:
        """Missed and wrong keys over the horizon when ``offset`` is added to the planner's
        actions, from ``state`` with the planner's ``memory``: the total, and (10,) the part
        of it each finger is answerable for (a due key: the finger the plan gives it; a wrong
        key: the fingertip nearest to it along the keyboard)."""
        self.look.start(self.planner, state, memory)
        trace = self._roll(proposal, offset, state.step, self.options.horizon_steps, False)
        return trace.total()

    def _open_loop(
        self, offsets: np.ndarray, state: EnvState
    ) -> tuple[list[float], list[np.ndarray]]:
        """:meth:`_look_ahead` of each of ``offsets`` (N, A) open-loop: the unperturbed
        look-ahead's actions (just made by :meth:`_unperturbed`) plus the offset, all N
        simulated at once. Returns each one's cost and (10,) per-finger part."""
        assert self._batched is not None and self._trace is not None
        nominal = np.stack(self._trace.actions)  # (H, A): the planner's own, closed-loop
        actions = np.clip(nominal[None] + offsets[:, None, :], -1.0, 1.0)
        keys, tips = self._batched.run(state.data, actions)
        active = keys >= self._threshold  # (N, H, 88)
        self.simulated_steps += actions.shape[0] * actions.shape[1]
        costs: list[float] = []
        per_fingers: list[np.ndarray] = []
        for n in range(actions.shape[0]):
            total, per_finger = 0.0, np.zeros(10)
            for j in range(actions.shape[1]):
                cost, part = self._step_cost(state.step + j, active[n, j], tips[n, j, :, 1])
                total += cost
                per_finger += part
            costs.append(total)
            per_fingers.append(per_finger)
        return costs, per_fingers

    def _open_loop_search(
        self,
        proposal: np.ndarray,
        offsets: np.ndarray,
        state: EnvState,
        memory: list[FingerMemory],
    ) -> tuple[list[float], list[np.ndarray]]:
        """The perturbed candidates ``offsets`` (N, A) looked ahead open-loop, in batches of
        ``open_loop_batch`` (0: one batch), the search ending after a batch whose cheapest
        candidate misses nothing (and, with ``verify``, still misses nothing looked ahead in
        closed loop), as the closed-loop search ends at such a candidate. Returns the costs
        of the candidates looked ahead (with ``verify`` only the cheapest open-loop one is
        finite: its closed-loop cost), and their (10,) per-finger parts."""
        o = self.options
        size = o.open_loop_batch or len(offsets)
        costs: list[float] = []
        per_fingers: list[np.ndarray] = []
        verified: dict[int, float] = {}
        for first in range(0, len(offsets), size):
            more, more_fingers = self._open_loop(offsets[first : first + size], state)
            costs.extend(more)
            per_fingers.extend(more_fingers)
            if first + size >= len(offsets) or min(more) > 0.0:
                continue
            best = first + int(np.argmin(more))
            if not o.verify:
                break
            verified[best] = self._look_ahead(proposal, offsets[best], state, memory)[0]
            if verified[best] == 0.0:
                break
        if o.verify:
            # Only the best of them competes, scored as it will be played.
            best = int(np.argmin(costs))
            if best not in verified:
                verified[best] = self._look_ahead(proposal, offsets[best], state, memory)[0]
            costs = [np.inf] * len(costs)
            costs[best] = verified[best]
        return costs, per_fingers

    def _unperturbed(
        self, proposal: np.ndarray, state: EnvState, memory: list[FingerMemory]
    ) -> tuple[float, np.ndarray]:
        """:meth:`_look_ahead` of the planner's own actions, continuing the last step's by
        one step where the episode followed it (``continue_look_ahead``), and kept."""
        o = self.options
        last = self._trace
        data = self.handle.data
        follows = (
            o.continue_look_ahead
            and last is not None
            and last.end is not None
            and len(last.actions) >= 2
            and last.step + 1 == state.step
            and np.array_equal(last.actions[1], proposal)
            and same_state(last.states[0], data)
        )
        if follows:
            assert last is not None and last.end is not None and last.memory is not None
            self.look.start(self.planner, last.end, last.memory)
            more = self._roll(None, None, last.step + len(last.actions), 1, True, last.end)
            trace = _Trace(
                step=state.step,
                costs=last.costs[1:] + more.costs,
                per_finger=last.per_finger[1:] + more.per_finger,
                actions=last.actions[1:] + more.actions,
                states=last.states[1:] + more.states,
                end=more.end,
                memory=more.memory,
            )
        else:
            self.look.start(self.planner, state, memory)
            spare = last.end if last is not None else None  # the last look-ahead is left
            trace = self._roll(proposal, None, state.step, o.horizon_steps, True, spare)
        self._trace = trace
        return trace.total()

    def _roll(
        self,
        first: np.ndarray | None,
        offset: np.ndarray | None,
        start: int,
        steps: int,
        keep: bool,
        spare: EnvState | None = None,
    ) -> _Trace:
        """Step the fork (where it is, the planner attached to it) ``steps`` steps from episode
        step ``start``: the action ``first`` at the first (None: the planner's), then the
        planner's, each plus ``offset`` (None: none). Returns each step's cost; with ``keep``
        also what :meth:`_unperturbed` continues from (``end`` is left None if the episode
        or the song ended within the steps; ``spare``: a snapshot done with, whose simulator
        copy ``end`` takes over)."""
        goal = self.handle.goal.keys
        trace = _Trace(step=start, costs=[], per_finger=[], actions=[], states=[])
        complete = True
        for j in range(steps):
            t = start + j
            if t >= goal.shape[0]:
                complete = False
                break
            action = first if j == 0 and first is not None else self.planner.act(None)
            played = np.clip(action if offset is None else action + offset, -1.0, 1.0)
            terminated, info = self.look.step(played)
            self.simulated_steps += 1
            cost, per_finger = self._step_cost(
                t, info["active_keys"], self.look.tip_y(self.tip_sites)
            )
            trace.costs.append(cost)
            trace.per_finger.append(per_finger)
            if keep:
                trace.actions.append(np.asarray(action).copy())
                trace.states.append(physics_state(self.look.handle.data))
            if terminated:
                complete = False
                break
        if keep and complete:
            trace.end = self.look.snapshot(spare)
            trace.memory = self.planner.memory()
        return trace

    def _step_cost(self, t: int, active: np.ndarray, tip_y: np.ndarray) -> tuple[float, np.ndarray]:
        """One look-ahead step's cost at episode step ``t`` from the (88,) keys sounding after
        it and the (10,) fingertips' y (m): planned keys missed, wrong keys sounded (times
        ``wrong_weight``), and ``crossing_cost`` if two fingers are crossed; and (10,) each
        finger's part of it."""
        o = self.options
        missed, _ = step_misses(self.planned[t], active)  # only the keys the plan plays
        _, wrong = step_misses(self.handle.goal.keys[t], active)
        cost = float(missed.size + o.wrong_weight * wrong.size)
        per_finger = np.zeros(10)
        key_y = self.planner.key_point[:, 1]
        by_plan, by_tip = blame(
            missed, wrong, self.planner.fingers[t], key_y, tip_y, self.tip_fingers
        )
        np.add.at(per_finger, by_plan, 1.0)
        np.add.at(per_finger, by_tip, o.wrong_weight)
        crossed = self._crossed(tip_y)
        if crossed.size:
            cost += o.crossing_cost
            np.add.at(per_finger, crossed, o.crossing_cost)
        return cost, per_finger

    def _crossed(self, tip_y: np.ndarray) -> np.ndarray:
        """The fingers (0-9) crossed with a neighbour (index to little finger, more than
        3 mm past it across the keys), from the fingertips' y (5 per hand, thumb first)."""
        y = tip_y.reshape(-1, 5)[:, 1:]  # (hands, 4): index to little finger
        up = (y[:, 1:] - y[:, :-1]) * self.hand_direction[:, None]  # (hands, 3) in order: > 0
        hand, pair = np.nonzero(up < -0.003)
        if not hand.size:
            return hand
        first = self.tip_fingers.reshape(-1, 5)[hand, pair + 1]
        return np.concatenate([first, first + 1])

    def stats(self) -> dict[str, float]:
        steps = max(self._steps, 1)
        return {
            **self.planner.stats(),
            "refined_share": self._refined / steps,
            "refine_seconds_per_step": self._seconds / steps,
            "lookahead_steps_per_step": self.simulated_steps / steps,
        }

    def plan_arrays(self) -> dict[str, np.ndarray]:
        return self.planner.plan_arrays()

    def options_dict(self) -> dict[str, Any]:
        return {"refine": asdict(self.options)}
