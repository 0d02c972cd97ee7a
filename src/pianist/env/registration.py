"""Gymnasium ids: ``pianist/<song>-v0`` for every built-in song (debug, robopianist-debug and
open-etude-12), ``pianist/<song>-dynamics-v0`` for the same with the score's loudness in the
observation (``velocity_goal``), and the original's own ids for its debug songs
(``RoboPianist-debug-<name>-v0``, where no other package has registered them).

Registering only adds entries to Gymnasium's registry (no model is built until ``gym.make``).
"""

from __future__ import annotations

import gymnasium as gym

from pianist.music import OPEN_SUITE, list_songs
from pianist.music.library import DYNAMICS_SUITE, OCTAVE_SUITE, ORIGINAL_DEBUG_SUITE

NAMESPACE = "pianist"
VERSION = 0


def env_id(song: str) -> str:
    """Gymnasium id of a built-in song, e.g. ``pianist/twinkle-twinkle-v0``."""
    return f"{NAMESPACE}/{song}-v{VERSION}"


def dynamics_env_id(song: str) -> str:
    """Gymnasium id of a built-in song with its loudness observed (``velocity_goal``), e.g.
    ``pianist/twinkle-twinkle-dynamics-v0``."""
    return f"{NAMESPACE}/{song}-dynamics-v{VERSION}"


def original_env_id(song: str) -> str:
    """The original RoboPianist's id of one of its debug songs, e.g.
    ``RoboPianist-debug-TwinkleTwinkleLittleStar-v0``."""
    return f"RoboPianist-debug-{song}-v{VERSION}"


def register_envs() -> list[str]:
    """Register every built-in song (idempotent) and return the ids."""
    ids = []
    songs = [
        *list_songs("debug"),
        *list_songs(ORIGINAL_DEBUG_SUITE),
        *list_songs(OCTAVE_SUITE),
        *list_songs(DYNAMICS_SUITE),
        *list_songs(OPEN_SUITE),
    ]
    plain: dict[str, object] = {}
    dynamics: dict[str, object] = {"velocity_goal": True}
    named = [(env_id(song), song, plain) for song in songs]
    named += [(dynamics_env_id(song), song, dynamics) for song in songs]
    named += [(original_env_id(song), song, plain) for song in list_songs(ORIGINAL_DEBUG_SUITE)]
    for name, song, options in named:
        if name not in gym.registry:
            gym.register(
                id=name,
                entry_point="pianist.env.piano_env:PianoEnv",
                kwargs={"song": song, **options},
                disable_env_checker=False,
            )
        ids.append(name)
    return ids
