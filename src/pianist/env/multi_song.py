"""One Gymnasium environment over many songs: a song sampled per episode.

:class:`MultiSongEnv` holds one :class:`PianoEnv` per song (built the first time the song is
drawn, then kept) and plays the drawn one until the next reset. Every song's environment is
built with the same options (both hands, the same forearm slides, physics and lookahead), so
the observation and action spaces are those of the first song for all of them; a song whose
environment would have other spaces is refused. It is a :class:`gymnasium.Wrapper` of the
current song's environment, so :func:`pianist.env.handle.control_handle` and controllers that
read the simulator see the song being played (after :meth:`MultiSongEnv.reset`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from pianist.env.piano_env import PianoEnv
from pianist.music import Song

SongRef = Song | str | Path


def song_name(song: SongRef) -> str:
    """A song's name: a Song's own, else the name or path as given."""
    return song.name if isinstance(song, Song) else str(song)


class MultiSongEnv(gym.Wrapper):
    """A piano environment whose song is drawn uniformly from ``songs`` at every reset.

    Args:
        songs: built-in song names, MIDI/PIG files or Songs (at least one, no repeats).
        options: :class:`PianoEnv` keyword options, the same for every song; ``hands``
            defaults to ``"both"`` so one action and observation layout fits every song.

    ``reset(seed=s)`` reseeds the song draw (and the drawn song's environment);
    ``reset(options={"song": name_or_index})`` plays that song instead of drawing one. The
    reset's ``info`` holds ``song`` (its name) and ``song_index``.

    Raises:
        ValueError: no songs, a song named twice, or (at a reset) a song whose environment has
            other spaces than the first song's.
    """

    def __init__(self, songs: Sequence[SongRef], **options: Any) -> None:
        if not songs:
            raise ValueError("a multi-song environment needs at least one song")
        names = [song_name(s) for s in songs]
        if len(set(names)) != len(names):
            raise ValueError(f"songs named twice: {', '.join(sorted(names))}")
        self.songs = list(songs)
        self.names = names
        self.options = {"hands": "both", **options}
        first = PianoEnv(self.songs[0], **self.options)
        super().__init__(first)
        self._envs: dict[int, PianoEnv] = {0: first}
        self.observation_space = first.observation_space
        self.action_space = first.action_space
        self.song_index = 0
        self._draw = np.random.default_rng()

    def _env_for(self, index: int) -> PianoEnv:
        env = self._envs.get(index)
        if env is None:
            env = PianoEnv(self.songs[index], **self.options)
            if (
                env.observation_space != self.observation_space
                or env.action_space != self.action_space
            ):
                raise ValueError(
                    f"song {self.names[index]} gives other observation or action spaces than "
                    f"{self.names[0]} with the same options"
                )
            self._envs[index] = env
        return env

    def _index(self, song: Any) -> int:
        if isinstance(song, int | np.integer):
            if not 0 <= int(song) < len(self.songs):
                raise ValueError(f"song index {song} out of range 0..{len(self.songs) - 1}")
            return int(song)
        if song not in self.names:
            raise ValueError(f"song {song!r} is not one of {', '.join(self.names)}")
        return self.names.index(song)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        options = dict(options or {})
        if seed is not None:
            self._draw = np.random.default_rng(seed)
        chosen = options.pop("song", None)
        index = (
            self._index(chosen) if chosen is not None else int(self._draw.integers(len(self.songs)))
        )
        self.env = self._env_for(index)
        self.song_index = index
        obs, info = self.env.reset(seed=seed, options=options or None)
        info = {**info, "song": self.names[index], "song_index": index}
        return obs, info

    @property
    def song(self) -> str:
        """The name of the song being played (the one drawn at the last reset)."""
        return self.names[self.song_index]

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
