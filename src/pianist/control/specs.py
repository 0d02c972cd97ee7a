"""The specs of the controller kinds that need no training: each kind's options as a frozen
dataclass with the controller it builds (:mod:`pianist.control.registry` reads and writes
their string form).

This module imports no simulator: the controllers' own modules are imported by ``build``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pianist.control.options import MPC_PRESETS, MPCOptions, RefineOptions, SearchOptions
from pianist.control.registry import ControllerSpec

if TYPE_CHECKING:
    from pianist.control.base import Controller
    from pianist.control.planner import IKPlanner


#: The planner's default ``push_below_velocity`` (``StrikeConfig``'s).
PUSH_BELOW_VELOCITY = 80


@dataclass(frozen=True)
class PlannerSpec(ControllerSpec):
    """The inverse-kinematics planner (:mod:`pianist.control.planner`)."""

    kind: ClassVar[str] = "planner"
    needs_fingering: ClassVar[bool] = True

    push_below_velocity: int = PUSH_BELOW_VELOCITY
    """Play the score's dynamics: notes softer than this MIDI velocity are pushed down at the
    speed their velocity maps to (``StrikeConfig.push_below_velocity``; a song of one
    velocity throughout plays the same either way; 0: every note struck at full speed)."""
    predict_strikes: Literal["dynamics", "always", "never"] = "dynamics"
    """Where each note not pushed is struck with the force whose strike, simulated two steps
    ahead, sounds in the note's step nearest its velocity (``StrikeConfig.predict_strikes``):
    in songs whose velocities differ, in every song (more F1, ~2.3x slower), or never."""

    def __post_init__(self) -> None:
        _check_push(self.kind, self.push_below_velocity)

    def uses_seed(self) -> bool:
        return False  # the plan and its execution are deterministic

    def build(self) -> Controller:
        return _planner(self.push_below_velocity, self.predict_strikes)


def _check_push(kind: str, velocity: int) -> None:
    """Refuse a ``push_below_velocity`` that is not a MIDI velocity (one line)."""
    if not 0 <= velocity <= 128:
        raise ValueError(
            f"{kind} option push_below_velocity needs a MIDI velocity from 0 to 128, not {velocity}"
        )


def _planner(push_below_velocity: int, predict_strikes: str) -> IKPlanner:
    """The planner, pushing notes softer than ``push_below_velocity``, and predicting its
    strikes or not."""
    from pianist.control.planner import IKPlanner, PlannerConfig

    return IKPlanner(
        PlannerConfig().with_fields(
            push_below_velocity=push_below_velocity, predict_strikes=predict_strikes
        )
    )


@dataclass(frozen=True)
class RefineSpec(RefineOptions, ControllerSpec):
    """The planner, each action refined by looking ahead with the physics
    (:mod:`pianist.control.refine`)."""

    kind: ClassVar[str] = "refine"
    needs_fingering: ClassVar[bool] = True

    push_below_velocity: int = PUSH_BELOW_VELOCITY
    """The planner's: notes softer than this MIDI velocity pushed (see ``planner``)."""
    predict_strikes: Literal["dynamics", "always", "never"] = "dynamics"
    """The planner's: where strikes have a predicted force (see ``planner``)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_push(self.kind, self.push_below_velocity)

    def build(self) -> Controller:
        from pianist.control.refine import Refiner

        return Refiner(_planner(self.push_below_velocity, self.predict_strikes), options=self)


@dataclass(frozen=True)
class SearchSpec(SearchOptions, ControllerSpec):
    """The planner (or, with base refine, the refiner), its execution settings chosen per
    segment of music by playing each variant ahead with the physics
    (:mod:`pianist.control.search`)."""

    kind: ClassVar[str] = "search"
    positional: ClassVar[str | None] = "base"
    needs_fingering: ClassVar[bool] = True

    base: Literal["planner", "refine"] = "planner"
    """The controller searched over: the planner, or the refiner with its defaults."""
    push_below_velocity: int = PUSH_BELOW_VELOCITY
    """The planner's: notes softer than this MIDI velocity pushed (see ``planner``)."""
    predict_strikes: Literal["dynamics", "always", "never"] = "dynamics"
    """The planner's: where strikes have a predicted force (see ``planner``)."""

    def __post_init__(self) -> None:
        if self.base not in ("planner", "refine"):
            raise ValueError(f"search runs over planner or refine, not {self.base!r}")
        super().__post_init__()
        _check_push(self.kind, self.push_below_velocity)

    def uses_seed(self) -> bool:
        return self.base == "refine"  # the refiner's perturbations are drawn from the seed

    def build(self) -> Controller:
        from pianist.control.refine import Refiner
        from pianist.control.search import SegmentSearch

        options = SearchOptions(self.segment_steps, self.overlap_steps, self.variants)
        planner = _planner(self.push_below_velocity, self.predict_strikes)
        return SegmentSearch(Refiner(planner) if self.base == "refine" else planner, options)


@dataclass(frozen=True)
class MPCSpec(MPCOptions, ControllerSpec):
    """The paper's predictive-sampling MPC (:class:`pianist.control.mpc.PredictiveSampling`);
    the defaults are the paper's (preset ``paper``)."""

    kind: ClassVar[str] = "mpc"
    presets: ClassVar[Mapping[str, Mapping[str, Any]]] = MPC_PRESETS

    def uses_seed(self) -> bool:
        return self.seed is None  # a fixed seed of its own overrides the episode's

    def build(self) -> Controller:
        from pianist.control.mpc import PredictiveSampling

        return PredictiveSampling(self)


def refined(spec: ControllerSpec) -> ControllerSpec:
    """``spec`` with the refiner in the planner's place (``pianist play --refine``): the
    planner becomes ``refine``, a search runs over the refiner, refine stays as it is.

    Raises:
        ValueError: a kind that has no planner to refine.
    """
    if isinstance(spec, PlannerSpec):
        return RefineSpec(
            push_below_velocity=spec.push_below_velocity, predict_strikes=spec.predict_strikes
        )
    if isinstance(spec, SearchSpec):
        return dataclasses.replace(spec, base="refine")
    if isinstance(spec, RefineSpec):
        return spec
    raise ValueError(f"--refine refines the planner, not --controller {spec}")


@dataclass(frozen=True)
class RandomSpec(ControllerSpec):
    """Uniform random actions in [-1, 1] from the episode's seed."""

    kind: ClassVar[str] = "random"

    def build(self) -> Controller:
        from pianist.control.basic import RandomController

        return RandomController()


@dataclass(frozen=True)
class ZeroSpec(ControllerSpec):
    """Every actuator at the middle of its range, the pedal up."""

    kind: ClassVar[str] = "zero"

    def uses_seed(self) -> bool:
        return False

    def build(self) -> Controller:
        from pianist.control.basic import ZeroController

        return ZeroController()


@dataclass(frozen=True)
class ReplaySpec(ControllerSpec):
    """Recorded actions played back (an ``actions.npy`` that ``pianist play`` wrote)."""

    kind: ClassVar[str] = "replay"
    path_field: ClassVar[str | None] = "actions"

    actions: str = ""
    """The .npy file of (T, A) actions."""

    def uses_seed(self) -> bool:
        return False

    def build(self) -> Controller:
        from pianist.control.basic import ReplayController

        return ReplayController(self.actions)
