"""Practise the hard parts: training episodes that start mid-piece and last a few seconds.

The paper's agent replays the whole piece from the start in every episode, however well it
already plays most of it. With ``TrainConfig.windows`` a share of the training episodes are
*windows* instead: each starts from a full-physics state that a guide, the inverse-kinematics
planner, reaches at that point of the piece, runs ``window_s`` seconds and is truncated
there (the critic bootstraps past the cut, as at any truncation). Windows where the current
policy loses F1 are drawn more often. Evaluation stays the whole piece from the start.

- :func:`record_windows` plays the piece once with the guide and keeps a snapshot every
  ``window_stride_s`` (:meth:`AgentEnv.snapshot`, plus the memory of a residual policy's
  planner, which must go on from the same point). The play is deterministic (a fixed seed;
  the planner draws no random numbers), so the snapshots stay in memory and a resumed run
  records the same ones again rather than storing them in its checkpoint.
- :class:`Windows` keeps each window's *error*, 1 - the mean per-step F1 of the policy over
  the window's steps: set for every window from each whole-piece evaluation (the
  deterministic policy), blended with the result of each window episode (the exploring
  policy). :meth:`Windows.draw` draws window i with probability
  ``(1 - u) * w_i / sum(w) + u / N``, ``w_i = (error_i + 0.01) ** power``, ``u`` the uniform
  share. The errors and draw counts go into checkpoints (:meth:`Windows.state`).
- :func:`start_window` starts an episode at a window, through ``env.reset`` options (the
  environment package does the restoring).

With the planner as the actor, an episode started at a window repeats the recording's
observations and rewards exactly (tests/test_agents_windows.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.agents.envs import AgentEnv, AgentEnvState, Featurizer
from pianist.eval.metrics import per_step_precision_recall_f1

if TYPE_CHECKING:
    from pianist.control.planner.hand import FingerMemory

#: Added to every error before the power: a window played perfectly is still drawn.
ERROR_FLOOR = 0.01
#: Weight of a window episode's result in its window's error (the rest: the old estimate).
EPISODE_RATE = 0.5


@dataclass(frozen=True)
class WindowStart:
    """Where a window starts: step ``step`` of the piece, the environment's state there and
    what the residual policy's planner remembered there (None without a planner)."""

    step: int
    state: AgentEnvState
    planner_memory: list[FingerMemory] | None


def window_starts(num_steps: int, window_steps: int, stride_steps: int) -> list[int]:
    """Start steps of the windows of a piece of ``num_steps`` steps: every ``stride_steps``
    while a whole window fits, then one that ends with the piece; [0] for a short piece."""
    if window_steps < 1 or stride_steps < 1:
        raise ValueError(f"window and stride must be >= 1 step, not {window_steps}, {stride_steps}")
    if num_steps <= window_steps:
        return [0]
    starts = list(range(0, num_steps - window_steps + 1, stride_steps))
    if starts[-1] + window_steps < num_steps:
        starts.append(num_steps - window_steps)
    return starts


class Windows:
    """The windows of one piece, each window's error estimate, and the draws.

    Attributes:
        starts: N :class:`WindowStart` s, in the order of the piece.
        ends: (N,) int, the step index at which each window is truncated.
        errors: (N,) float64 in [0, 1], 1 - the policy's mean per-step F1 on each window.
        draws: (N,) int64, how often each window was drawn.
    """

    def __init__(self, starts: list[WindowStart], ends: np.ndarray, errors: np.ndarray) -> None:
        if not starts or len(starts) != len(ends) or len(ends) != len(errors):
            raise ValueError("windows need one end and one error per start, and a start")
        self.starts = starts
        self.ends = np.asarray(ends, np.int64)
        self.errors = np.asarray(errors, np.float64).copy()
        self.draws = np.zeros(len(starts), np.int64)

    def __len__(self) -> int:
        return len(self.starts)

    def probabilities(self, power: float, uniform: float) -> np.ndarray:
        """(N,) the probability of drawing each window (module docstring)."""
        weights = (self.errors + ERROR_FLOOR) ** power
        return (1.0 - uniform) * weights / weights.sum() + uniform / len(self)

    def draw(self, rng: np.random.Generator, power: float, uniform: float) -> int:
        """Draw a window's index with :meth:`probabilities` and count the draw."""
        i = int(rng.choice(len(self), p=self.probabilities(power, uniform)))
        self.draws[i] += 1
        return i

    def record_evaluation(self, step_f1: np.ndarray) -> None:
        """Set every window's error from the per-step F1 (T',) of an episode played from step
        0 (an episode that ended early counts the steps it did not play as F1 0)."""
        for i, start in enumerate(self.starts):
            self.errors[i] = _error(step_f1, start.step, int(self.ends[i]))

    def record_episode(self, i: int, step_f1: np.ndarray) -> None:
        """Blend the per-step F1 (n,) of an episode of window ``i`` into its error."""
        steps = int(self.ends[i]) - self.starts[i].step
        error = 1.0 - float(np.sum(step_f1[:steps])) / steps  # unplayed steps count 0
        self.errors[i] += EPISODE_RATE * (error - self.errors[i])

    def state(self) -> dict[str, Any]:
        """What a checkpoint keeps (JSON): the errors and the draw counts."""
        return {"errors": self.errors.tolist(), "draws": self.draws.tolist()}

    def load_state(self, state: dict[str, Any]) -> None:
        """Go back to a :meth:`state` of the same windows."""
        errors, draws = np.asarray(state["errors"], np.float64), np.asarray(state["draws"])
        if errors.shape != self.errors.shape or draws.shape != self.draws.shape:
            raise ValueError(
                f"the checkpoint has {errors.size} windows, the piece {len(self)}: "
                "another song or window settings"
            )
        self.errors, self.draws = errors, draws.astype(np.int64)


def _error(step_f1: np.ndarray, begin: int, end: int) -> float:
    played = step_f1[begin:end]
    return 1.0 - float(played.sum()) / (end - begin)


def step_f1(active_keys: np.ndarray, goal_keys: np.ndarray) -> np.ndarray:
    """(T,) per-step key F1 of (T, 88) sounding and due keys (the evaluation's metric)."""
    return per_step_precision_recall_f1(active_keys, goal_keys)[2]


def record_windows(
    env: AgentEnv,
    features: Featurizer,
    window_steps: int,
    stride_steps: int,
    seed: int,
) -> tuple[Windows, np.ndarray]:
    """Play the piece once with the planner from ``env.reset(seed=seed)`` and keep the start
    of every window (:func:`window_starts`).

    For a residual task the guide is the residual policy with a zero correction, which is the
    planner (its planner is ``features``' own, whose memory each start keeps); otherwise a
    planner of its own plays. Leaves ``env`` and ``features`` mid-episode: reset them.

    Returns:
        The windows, with errors from the guide's play for a residual task (it is what the
        first residual policy plays) and 1 (unknown) otherwise; and the play's (T',) per-step
        F1 (T' < T when ``wrong_press_termination`` ended it early).

    Raises:
        ValueError: a note of the song has no finger (the planner needs them).
    """
    from pianist.control.planner import IKPlanner

    T = env.num_steps
    starts = window_starts(T, window_steps, stride_steps)
    obs, _ = env.reset(seed=seed)
    features.reset(env, seed)
    guide = None
    if not features.task.residual:
        guide = IKPlanner()
        guide.reset(env, seed)
    zero = np.zeros(features.action_dim, np.float32)
    wanted = set(starts)
    kept: list[WindowStart] = []
    active, due = [], []
    for t in range(T):
        if t in wanted:
            kept.append(WindowStart(t, env.snapshot(), features.memory()))
        features(obs)  # a residual's planner acts on every state, as in training
        action = features.env_action(zero) if guide is None else guide.act(obs)
        obs, _, terminated, _, info = env.step(action)
        active.append(info["active_keys"])
        due.append(info["goal_keys"])
        if terminated:
            break
    f1 = step_f1(np.stack(active), np.stack(due))
    ends = np.array([min(s.step + window_steps, T) for s in kept])
    windows = Windows(kept, ends, np.ones(len(kept)))
    if features.task.residual:
        windows.record_evaluation(f1)
    return windows, f1


def start_window(env: AgentEnv, features: Featurizer, start: WindowStart, seed: int) -> Any:
    """Start an episode at ``start`` (the policy's planner too); returns the observation."""
    obs, _ = env.reset(seed=seed, options={"start": start.state})
    features.reset(env, seed)
    features.set_memory(start.planner_memory)
    return obs
