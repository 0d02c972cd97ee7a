"""pianist: two simulated Shadow hands playing an 88-key MuJoCo piano (RoboPianist, faster).

``pianist.make_env(song, **options)`` builds the Gymnasium environment; heavier subpackages
load only when used, so importing :mod:`pianist` stays cheap.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pianist.env import PianoEnv
    from pianist.music import GoalFrames, Song

__version__ = "0.1.0"


def make_env(song: Song | GoalFrames | str | Path, **options: Any) -> PianoEnv:
    """A :class:`pianist.env.PianoEnv` for ``song``: a built-in name, a MIDI/PIG path, a Song.

    ``options`` are those of :func:`pianist.env.make_config` (``lookahead``, ``hands``,
    ``physics``, ``reduced_action_space``, ...), plus ``render_mode``.
    """
    from pianist.env import PianoEnv

    return PianoEnv(song, **options)


def make_vector_env(song: Song | GoalFrames | str | Path, num_envs: int, **options: Any) -> Any:
    """N environments stepped together on all cores (:class:`pianist.env.vector.PianoVectorEnv`)."""
    from pianist.env.vector import PianoVectorEnv

    return PianoVectorEnv(song, num_envs, **options)


__all__ = ["__version__", "make_env", "make_vector_env"]
