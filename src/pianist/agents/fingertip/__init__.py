"""A policy in fingertip space: per hand, where the forearm goes and what each finger does.

- :mod:`~pianist.agents.fingertip.features`: what the policy reads and writes, per hand;
- :mod:`~pianist.agents.fingertip.controller`: :class:`FingertipController` (the policy's
  decisions played through the planner's execution stages), :class:`ExpertRecorder` (the
  planner's decisions as labels), saving and loading.
"""

from pianist.agents.fingertip.controller import (
    ExpertRecorder,
    FingertipController,
    FingertipPolicy,
    Forearm,
    load_policy,
    read_fingering,
    save_policy,
)
from pianist.agents.fingertip.features import Mode

__all__ = [
    "ExpertRecorder",
    "FingertipController",
    "FingertipPolicy",
    "Forearm",
    "Mode",
    "load_policy",
    "read_fingering",
    "save_policy",
]
