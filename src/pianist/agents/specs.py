"""The specs of the learned controller kinds (``policy:RUN_DIR``, ``bc:DIR``, ``generalist``),
registered in :data:`pianist.control.registry.KINDS`, and :func:`load_run`, the one place
that tells a trained agent's run folder from a practised piece's.

Nothing here imports JAX or the simulator: ``build`` imports the controller's module.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pianist.control.registry import ControllerSpec

if TYPE_CHECKING:
    from pianist.control.base import Controller


@dataclass(frozen=True)
class PolicySpec(ControllerSpec):
    """A trained agent, or a practised piece (a ``pianist train`` run folder)."""

    kind: ClassVar[str] = "policy"
    path_field: ClassVar[str | None] = "run_dir"

    run_dir: str = ""
    """The run folder."""

    def uses_seed(self) -> bool:
        return False  # a trained policy acts with its mean action; a practised piece replays

    def build(self) -> Controller:
        return load_run(self.run_dir)[0]


@dataclass(frozen=True)
class BCSpec(ControllerSpec):
    """A behaviour-cloning policy (a ``pianist bc train`` folder)."""

    kind: ClassVar[str] = "bc"
    path_field: ClassVar[str | None] = "dir"

    dir: str = ""
    """The policy's folder."""

    def uses_seed(self) -> bool:
        return False

    def build(self) -> Controller:
        from pianist.agents.bc import BCController

        return BCController(self.dir)


@dataclass(frozen=True)
class GeneralistSpec(ControllerSpec):
    """The fingertip policy shipped with the package, for any song: the plan made at reset
    fingers it and places the hands, the policy decides every finger."""

    kind: ClassVar[str] = "generalist"

    forearm: Literal["plan", "policy"] | None = None
    """Where its forearms go: plan (along the plan's path), policy (its own slide targets);
    none: the policy's own choice (plan for the shipped one)."""

    def uses_seed(self) -> bool:
        return False

    def build(self) -> Controller:
        from pianist.agents.generalist import generalist_controller

        return generalist_controller(self.forearm)


def load_run(run_dir: str | Path, physics: str | None = None) -> tuple[Controller, dict[str, Any]]:
    """The controller a ``pianist train`` run folder holds, and what to record of it.

    Args:
        run_dir: a practice run (its table of corrections) or a trained agent's run (its
            last checkpoint).
        physics: for a trained agent, the preset to play in (None: the one its run evaluated
            in); a practised piece plays in the physics it was practised in, so any value is
            refused for one.
    Returns:
        The controller, and ``preset``, ``trained_physics`` and, for an agent,
        ``checkpoint_step`` (for metrics.json).
    Raises:
        FileNotFoundError: no run there; ValueError: ``physics`` for a practised piece, or an
            unreadable run.
    """
    from pianist.agents.practice import CorrectedPlanner, is_practice_run

    if is_practice_run(run_dir):
        if physics is not None:
            raise ValueError("a practised piece plays in the physics it was practised in")
        practised = CorrectedPlanner.load(run_dir)
        return practised, {"preset": "practice", "trained_physics": practised.physics}
    from pianist.agents.policy import PolicyController

    policy = PolicyController(run_dir, physics=physics)
    return policy, {
        "preset": policy.config.preset,
        "trained_physics": policy.config.task.physics,
        "checkpoint_step": policy.step,
    }
