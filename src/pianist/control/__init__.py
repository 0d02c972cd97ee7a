"""Controllers that need no training, the controller contract and the registry of controller
kinds (:mod:`pianist.control.registry`).

The names below are imported on first use, so that reading a controller spec
(:mod:`pianist.control.registry`, :mod:`pianist.control.specs`) loads no simulator.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pianist.control.base import BaseController, Controller
    from pianist.control.basic import (
        NoisyController,
        RandomController,
        ReplayController,
        ZeroController,
        make_controller,
    )
    from pianist.control.registry import ControllerSpec, build_controller, parse_controller

_WHERE = {
    "BaseController": "base",
    "Controller": "base",
    "ControllerSpec": "registry",
    "NoisyController": "basic",
    "RandomController": "basic",
    "ReplayController": "basic",
    "ZeroController": "basic",
    "build_controller": "registry",
    "make_controller": "basic",
    "parse_controller": "registry",
}

__all__ = [
    "BaseController",
    "Controller",
    "ControllerSpec",
    "NoisyController",
    "RandomController",
    "ReplayController",
    "ZeroController",
    "build_controller",
    "make_controller",
    "parse_controller",
]


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"pianist.control.{_WHERE[name]}"), name)
