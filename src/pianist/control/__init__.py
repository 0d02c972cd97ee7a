"""Controllers that need no training."""

from pianist.control.basic import (
    Controller,
    RandomController,
    ReplayController,
    ZeroController,
    make_controller,
)

__all__ = [
    "Controller",
    "RandomController",
    "ReplayController",
    "ZeroController",
    "make_controller",
]
