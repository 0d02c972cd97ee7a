"""Learning to play: SAC with DroQ/REDQ presets in JAX, training with checkpoints, trained
policies as controllers.

Importing this package does not import JAX; :func:`train` and the agent modules do.
``pianist.agents.config`` holds the presets, ``PolicyController`` acts in NumPy.
``pianist.agents.bc``: behaviour cloning and DAgger, one policy for many songs (docs/bc.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pianist.agents.config import PRESETS, SACConfig, TaskConfig, TrainConfig, get_preset

if TYPE_CHECKING:
    from pianist.agents.policy import PolicyController
    from pianist.agents.training import TrainResult, train

__all__ = [
    "PRESETS",
    "PolicyController",
    "SACConfig",
    "TaskConfig",
    "TrainConfig",
    "TrainResult",
    "get_preset",
    "train",
]


def __getattr__(name: str) -> Any:
    if name == "PolicyController":
        from pianist.agents.policy import PolicyController

        return PolicyController
    if name in ("train", "TrainResult"):
        from pianist.agents import training as module

        return getattr(module, name)
    raise AttributeError(f"module 'pianist.agents' has no attribute {name!r}")
