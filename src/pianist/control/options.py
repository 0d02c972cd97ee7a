"""The options of the controllers that need no training, as plain frozen dataclasses
(validated on construction): what :class:`pianist.control.refine.Refiner`,
:class:`pianist.control.search.SegmentSearch` and
:class:`pianist.control.mpc.PredictiveSampling` take, and what their specs in
:mod:`pianist.control.specs` are made of.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pianist.control.spline import INTERPOLATIONS, Interpolation


@dataclass(frozen=True)
class RefineOptions:
    """How much the refiner looks ahead (:mod:`pianist.control.refine`)."""

    candidates: int = 8
    """Perturbed actions tried per step, besides the planner's own."""
    horizon_steps: int = 4
    """Steps each candidate is looked ahead (0.2 s at 20 Hz)."""
    sigma: float = 0.15
    """Standard deviation of each finger joint's perturbation, in action units ([-1, 1] spans
    the joint's range)."""
    arm_sigma: float = 0.0
    """Standard deviation of the perturbation of each forearm's slide along the keyboard
    (action units; 0: the forearms are left to the planner). A hand held a little longer
    over a held key, or moved a little earlier, is a change the fingers alone cannot make."""
    keep_previous: bool = True
    """Try the perturbation chosen at the previous step again (in place of one random
    candidate): a finger that needed more push usually needs it for a few steps."""
    wrong_weight: float = 1.0
    """Cost of a key sounded that is not due, against 1 for a due key not sounded."""
    continue_look_ahead: bool = True
    """Where the last step played the planner's own action and the episode is where that
    step's look-ahead went, continue that look-ahead by one step instead of simulating the
    planner's again from the start: the same actions (the physics is deterministic; both
    the state and the planner's next action are checked), ``horizon_steps - 1`` fewer steps
    simulated per such step."""
    crossing_cost: float = 10.0
    """Cost of each look-ahead step that ends with two neighbouring fingers (index to little
    finger) crossed, one more than 3 mm past the other across the keys: perturbed towards
    each other, they catch, and the one behind then cannot get back to its keys for many
    steps, longer than the look-ahead sees."""
    per_finger: bool = True
    """Also combine the candidates finger by finger: each finger takes the perturbation
    whose look-ahead cost its own keys least (a due key counts for the finger the plan gives
    it, a wrong key for the nearest fingertip), and that combination is looked ahead too and
    played if it costs least. One random perturbation of every finger rarely helps two
    fingers at once; combined, each finger chooses from all of them."""

    open_loop: bool = False
    """Look the perturbed candidates ahead open-loop, all at once in MuJoCo's threads
    (:mod:`pianist.control.rollout_ahead`): each replays the unperturbed look-ahead's actions
    (the planner's own, in closed loop) plus its offset, instead of stepping a fork with the
    planner reacting at every step. The unperturbed candidate stays closed-loop. About 1.6
    times as fast on two cores, for ~0.01 less F1 (open-etude-12, fast: 0.858 against
    0.866)."""
    threads: int = 2
    """Threads of the open-loop look-ahead (0: the calling thread only)."""
    open_loop_batch: int = 2
    """With ``open_loop``: candidates simulated per batch (0: all of them in one). The search
    ends after a batch with a candidate that misses nothing, as the closed-loop one ends at
    such a candidate, so easy steps simulate fewer; a batch of ``threads`` keeps every
    thread busy. In pairs against one batch: the same F1 on open-etude-12 (0.8583 against
    0.8584, fast), 8-15 % faster
    (docs/notes/2026-12-07-planner-refine.md)."""
    verify: bool = True
    """With ``open_loop``: look the open-loop candidate that cost least ahead again in closed
    loop, and the per-finger combination too; only those compete with the unperturbed one.
    Open-loop, a candidate is scored without the planner's reactions that follow it when it
    is played (a push for a key that has not sounded, a finger lined up again)."""

    def __post_init__(self) -> None:
        if self.threads < 0 or self.open_loop_batch < 0:
            raise ValueError(
                "refine needs threads >= 0 and open_loop_batch >= 0, not "
                f"{self.threads} and {self.open_loop_batch}"
            )
        if (
            self.candidates < 0
            or self.horizon_steps < 1
            or not self.sigma >= 0
            or not self.arm_sigma >= 0
        ):
            raise ValueError(
                "refine needs candidates >= 0, horizon_steps >= 1, sigma >= 0 and arm_sigma "
                f">= 0, not {self.candidates}, {self.horizon_steps}, {self.sigma}, "
                f"{self.arm_sigma}"
            )


#: Named execution settings, as :class:`pianist.control.planner.PlannerConfig` overrides.
#: None changes the plan (hand positions, fingering): a variant can take over mid-piece.
VARIANTS: dict[str, dict[str, Any]] = {
    "plain": {},
    # Feedback on the wrist's flexion too (gain 1): under a chord the keys bend the wrist up
    # less, so the last finger down is not lifted off its key.
    "stiff-wrist": {"wrist_feedback": (2.0, 1.0)},
    # Every finger but the thumb commanded 0.2 rad further down while it presses.
    "finger-push": {"finger_push_rad": (0.2, 0.2, 0.2, 0.2)},
    # Harder down for a pressing finger by 1 rad per radian the keys bend the wrist up.
    "bent-wrist-push": {"bent_wrist_push": 1.0},
    # Fingers due soon hover 5 mm above their keys instead of 10: earlier strikes.
    "low-hover": {"hover_height_m": 0.005},
    # Half the wrist's flexion feedback of stiff-wrist.
    "half-stiff-wrist": {"wrist_feedback": (2.0, 0.5)},
    # The thumb commanded 0.5 rad further down while it presses (0.3 plain).
    "thumb-push": {"thumb_push_rad": 0.5},
    # A finger presses once within 12 mm (11 on a black key) of its key, not 9 (8).
    "loose-align": {"align_tolerance_m": 0.012, "black_align_tolerance_m": 0.011},
}


@dataclass(frozen=True)
class SearchOptions:
    """How the segment search looks ahead (:mod:`pianist.control.search`)."""

    segment_steps: int = 10
    """Control steps one variant plays before the next choice (0.5 s at 20 Hz)."""
    overlap_steps: int = 5
    """Steps each variant is also scored beyond its segment: a variant that gains at the end
    of a segment by leaving the hand badly placed for the next one is not chosen for it."""
    variants: tuple[str, ...] = (
        "plain",
        "stiff-wrist",
        "finger-push",
        "bent-wrist-push",
        "low-hover",
    )
    """Names from :data:`VARIANTS`; the first is the base's own setting and wins ties."""

    def __post_init__(self) -> None:
        if self.segment_steps < 1 or self.overlap_steps < 0:
            raise ValueError(
                "search needs segment_steps >= 1 and overlap_steps >= 0, not "
                f"{self.segment_steps}, {self.overlap_steps}"
            )
        unknown = [name for name in self.variants if name not in VARIANTS]
        if unknown or not self.variants:
            raise ValueError(
                f"unknown search variants {unknown or '(none given)'}; use {', '.join(VARIANTS)}"
            )


#: The MPC's named settings (``mpc:tenth``), as field values over the paper's defaults.
MPC_PRESETS: dict[str, dict[str, Any]] = {
    # Appendix "Baselines": N = 10, sigma 0.05, 2 knots, 0.2 s horizon, 0.01 s planning step.
    "paper": {},
    # What 1/10 real time (the paper's budget) buys on this project's 2-core machine: 2.5x the
    # paper's rollouts per control step (25 x 21 x 5 = 2625 rollout steps of 0.01 s, ~0.5 s at
    # the ~5.4k rollout steps/s measured with 2 threads on a quiet machine), spent on more
    # samples, and a wider search. benchmarks/bench_mpc.py --seconds 4 (first 4 s of
    # twinkle-twinkle, c-major-scale-right, c-major-chords, seed 0): mean F1 0.73 against 0.39
    # for the paper preset.
    "tenth": {"num_samples": 25, "sigma": 0.2},
}


@dataclass(frozen=True)
class MPCOptions:
    """Settings of :class:`pianist.control.mpc.PredictiveSampling`; the defaults are the
    paper's (preset ``paper``)."""

    num_samples: int = 10
    """Candidates per planning iteration, the kept nominal included (paper: N = 10)."""
    sigma: float = 0.05
    """Standard deviation of the knot noise, in normalised action units (half a range = 1)."""
    horizon_s: float = 0.2
    """Seconds of simulated time each rollout looks ahead (paper: 0.2 s)."""
    num_knots: int = 2
    """Spline knots over the horizon (the paper's "spline dimension")."""
    interpolation: Interpolation = "cubic"
    """How the knots are joined: zero (held), linear or cubic."""
    planning_timestep_s: float = 0.01
    """Timestep of the rollouts' physics (MJPC's agent_timestep); the env keeps its own."""
    iterations: int = 5
    """Planning iterations per control step."""
    key_weight: float = 1.0
    """Weight of the cost's key term (distance of the keys' state from the goal's)."""
    finger_weight: float = 1.0
    """Weight of the cost's finger term (m from each due key's finger to the key)."""
    threads: int = 2
    """Rollout threads (1 = the calling thread)."""
    seed: int | None = None
    """Seed of the sampling noise; None uses the seed given to ``reset``."""

    def __post_init__(self) -> None:
        if self.num_samples < 1:
            raise ValueError(f"num_samples must be >= 1, not {self.num_samples}")
        if not (self.sigma >= 0 and math.isfinite(self.sigma)):
            raise ValueError(f"sigma must be a finite number >= 0, not {self.sigma}")
        if self.num_knots < 1:
            raise ValueError(f"num_knots must be >= 1, not {self.num_knots}")
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(
                f"unknown interpolation {self.interpolation!r}; use one of {INTERPOLATIONS}"
            )
        if not (self.planning_timestep_s > 0 and math.isfinite(self.planning_timestep_s)):
            raise ValueError(f"planning_timestep_s must be > 0, not {self.planning_timestep_s}")
        steps = self.horizon_s / self.planning_timestep_s
        if (
            not (self.horizon_s > 0 and math.isfinite(steps))
            or abs(steps - round(steps)) > 1e-6
            or round(steps) < 1
        ):
            raise ValueError(
                f"horizon_s {self.horizon_s} must be a positive multiple of "
                f"planning_timestep_s {self.planning_timestep_s}"
            )
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, not {self.iterations}")
        if self.threads < 1:
            raise ValueError(f"threads must be >= 1, not {self.threads}")
        if self.key_weight < 0 or self.finger_weight < 0:
            raise ValueError("cost weights must be >= 0")

    @property
    def horizon_steps(self) -> int:
        """Rollout steps over the horizon."""
        return round(self.horizon_s / self.planning_timestep_s)
