"""Controllers that need no training."""

from pianist.control.base import BaseController, Controller
from pianist.control.basic import (
    NoisyController,
    RandomController,
    ReplayController,
    ZeroController,
    make_controller,
)

__all__ = [
    "BaseController",
    "Controller",
    "NoisyController",
    "RandomController",
    "ReplayController",
    "ZeroController",
    "make_controller",
]
