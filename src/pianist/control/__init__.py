"""Controllers that need no training."""

from pianist.control.basic import (
    Controller,
    NoisyController,
    RandomController,
    ReplayController,
    ZeroController,
    make_controller,
)

__all__ = [
    "Controller",
    "NoisyController",
    "RandomController",
    "ReplayController",
    "ZeroController",
    "make_controller",
]
