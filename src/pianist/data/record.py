"""One demonstration episode: play it, keep every step's arrays, write it to a folder.

:func:`record_episode` is the unit of work of a dataset build: a pure function of its
arguments (song, controller spec, seed, physics, noise) that writes one folder and returns its
path, so the local workers of :mod:`pianist.data.build` or a sweep's task can run it anywhere.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pianist.control import NoisyController
from pianist.files import atomic_dir

#: The files of one recorded episode's folder.
ARRAYS_FILE = "arrays.npz"
META_FILE = "episode.json"

# Key names inside ARRAYS_FILE: "obs/NAME", "info/NAME", "info/reward_terms/NAME", and the
# plain arrays below.
_PLAIN = ("actions", "rewards", "terminations", "truncations")
_INFO_KEYS = ("active_keys", "sustain", "goal_keys", "goal_sustain")


@dataclass
class EpisodeRecord:
    """One episode as a demonstration dataset keeps it (Minari's episode layout).

    Attributes:
        observations: name -> (T + 1, ...) float32, the environment's own observation after
            reset and after each step.
        actions: (T, A) float32 normalised actions in [-1, 1].
        rewards: (T,) float64 total reward of each step.
        terminations: (T,) bool; truncations: (T,) bool (the last step is truncated when the
            song ends).
        infos: per step, aligned with ``actions``: ``active_keys`` (T, 88) bool (keys sounding
            after the step), ``sustain`` (T,) bool, ``goal_keys`` (T, 88) bool (keys due),
            ``goal_sustain`` (T,) bool, and ``reward_terms``: name -> (T,) float64.
        metadata: JSON-ready facts of the episode: song, provenance, controller, seed, noise,
            physics, precision/recall/f1, steps, seconds, return.
    """

    observations: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict[str, Any]
    metadata: dict[str, Any]

    @property
    def num_steps(self) -> int:
        return len(self.actions)


def song_provenance(ref: str, song: Any | None = None) -> dict[str, Any]:
    """What is known of where song ``ref`` (a built-in name or a file) comes from.

    Returns a JSON-ready dict with at least ``name``, ``suite`` (or None for a file),
    ``source``, ``licence`` and ``fingering`` (where the fingers come from). Open-library
    pieces carry their whole ``provenance.json`` entry (composer, source, segment, ...); a file
    carries its path and SHA-256; a song that is neither says so.
    """
    from pianist.music import OPEN_SUITE, list_songs, load_song
    from pianist.music.library import ORIGINAL_DEBUG_SUITE
    from pianist.music.open_library import open_song_info

    path = Path(ref)
    if ref in list_songs(OPEN_SUITE):
        info = open_song_info(ref)
        info.pop("file", None)
        return {"suite": OPEN_SUITE, **info}
    if ref in list_songs("debug"):
        return {
            "name": ref,
            "suite": "debug",
            "source": "pianist's built-in debug songs (src/pianist/music/library.py)",
            "licence": "part of pianist, Apache-2.0",
            "fingering": "written with the notes, every note",
        }
    if ref in list_songs(ORIGINAL_DEBUG_SUITE):
        return {
            "name": ref,
            "suite": ORIGINAL_DEBUG_SUITE,
            "source": "RoboPianist's debug songs, note for note (src/pianist/music/library.py)",
            "licence": "part of pianist, Apache-2.0",
            "fingering": "written with the notes, every note",
        }
    if path.is_file():
        # What the file itself says about fingers decides the fingering's origin.
        raw = load_song(path, fingering="none")
        fingered = sum(note.finger is not None for note in raw.notes)
        if fingered == raw.num_notes and raw.num_notes:
            origin = "from the file, every note"
        elif fingered:
            origin = f"from the file for {fingered} of {raw.num_notes} notes, the rest automatic"
        else:
            origin = "automatic (pianist.music.assign_fingering), every note"
        return {
            "name": song.name if song is not None else path.stem,
            "suite": None,
            "source": f"file {path.resolve()}",
            "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "licence": "unknown (the user's file)",
            "fingering": origin,
        }
    return {
        "name": ref,
        "suite": None,
        "source": "imported PIG piece (Nakamura et al.; not redistributable)",
        "licence": "PIG dataset terms (research use)",
        "fingering": "from the PIG file",
    }


def episode_controller(spec: str, noise: float) -> Any:
    """The controller of spec ``spec`` (:func:`pianist.control.registry.build_controller`),
    with Gaussian action noise of std ``noise`` when > 0."""
    from pianist.control.registry import build_controller

    controller = build_controller(spec)
    return NoisyController(controller, noise) if noise > 0 else controller


def record_episode(
    song: str,
    controller_spec: str,
    seed: int,
    physics: str | None,
    out_dir: str | Path,
    *,
    noise: float = 0.0,
    fingering: str = "auto",
) -> Path:
    """Play ``song`` once and write the episode's arrays and facts to the folder ``out_dir``.

    The folder appears whole or not at all (:func:`pianist.files.atomic_dir`): a folder that
    exists is a finished episode, which is what a resumed build relies on.

    Args:
        song: a built-in song name or a MIDI/PIG file path.
        controller_spec: ``planner``, ``refine``, ``mpc``, ``random``, ``policy:RUN_DIR``, ...
        seed: the episode's seed (environment, controller and action noise).
        physics: "faithful", "fast", or None for the controller's own.
        out_dir: the episode's folder (its parent must be writable).
        noise: std of Gaussian noise added to each action (action units, clipped to [-1, 1]);
            0 plays the controller as it is.
        fingering: how the song is fingered (:func:`pianist.music.load_song`).
    Returns:
        ``out_dir`` as a Path.
    Raises:
        ValueError: a negative or non-finite noise, or an unknown controller.
        MusicError: the song cannot be loaded.
    """
    from pianist.eval.session import play
    from pianist.music import load_song

    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"action noise must be a std >= 0, not {noise}")
    loaded = load_song(song, fingering=fingering)  # type: ignore[arg-type]
    controller = episode_controller(controller_spec, noise)
    result = play(
        loaded,
        controller,
        physics=physics,
        seed=seed,
        record_observations=True,
    )
    record = episode_record(result, song_ref=song, controller_spec=controller_spec, noise=noise)
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        _write_record(record, tmp)
    return out


def episode_record(
    result: Any, *, song_ref: str, controller_spec: str, noise: float
) -> EpisodeRecord:
    """The :class:`EpisodeRecord` of a :class:`pianist.eval.session.PlayResult` played with
    ``record_observations=True``."""
    from minari.serialization import serialize_space

    episode, metrics = result.episode, result.metrics
    if "observations" not in episode.extra:
        raise ValueError("the episode was played without record_observations=True")
    infos: dict[str, Any] = {
        "active_keys": episode.active_keys.astype(bool),
        "sustain": episode.sustain.astype(bool),
        "goal_keys": episode.goal_keys.astype(bool),
        "goal_sustain": episode.goal_sustain.astype(bool),
        "reward_terms": {k: np.asarray(v, np.float64) for k, v in episode.reward_terms.items()},
    }
    keep = ("precision", "recall", "f1", "sustain_f1", "steps", "seconds", "return")
    metadata = {
        "song": result.song.name,
        "song_ref": song_ref,
        "provenance": song_provenance(song_ref, result.song),
        "controller": controller_spec,
        "noise": noise,
        "seed": metrics["seed"],
        "physics": metrics["physics"],
        "control_timestep_s": episode.control_timestep_s,
        "env_options": metrics["env_options"],
        **{k: metrics[k] for k in keep if k in metrics},
        # The spaces of the environment itself, inside any wrapper of the controller's.
        "observation_space": serialize_space(result.observation_space),
        "action_space": serialize_space(result.action_space),
    }
    return EpisodeRecord(
        observations=dict(episode.extra["observations"]),
        actions=np.asarray(episode.actions, np.float32),
        rewards=np.asarray(episode.rewards, np.float64),
        terminations=np.asarray(episode.extra["terminations"], bool),
        truncations=np.asarray(episode.extra["truncations"], bool),
        infos=infos,
        metadata=metadata,
    )


def _write_record(record: EpisodeRecord, folder: Path) -> None:
    arrays: dict[str, np.ndarray] = {name: getattr(record, name) for name in _PLAIN}
    arrays.update({f"obs/{k}": v for k, v in record.observations.items()})
    arrays.update({f"info/{k}": record.infos[k] for k in _INFO_KEYS})
    arrays.update({f"info/reward_terms/{k}": v for k, v in record.infos["reward_terms"].items()})
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)  # type: ignore[arg-type]
    (folder / ARRAYS_FILE).write_bytes(buffer.getvalue())
    text = json.dumps(record.metadata, indent=2, default=_json_default)
    (folder / META_FILE).write_text(text + "\n", encoding="utf-8")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def read_episode(folder: str | Path) -> EpisodeRecord:
    """Read an episode folder written by :func:`record_episode`.

    Raises:
        ValueError: the folder is not a complete episode.
    """
    folder = Path(folder)
    try:
        metadata = json.loads((folder / META_FILE).read_text(encoding="utf-8"))
        with np.load(folder / ARRAYS_FILE, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{folder} is not a recorded episode: {exc}") from None
    observations = {k.removeprefix("obs/"): v for k, v in arrays.items() if k.startswith("obs/")}
    terms_prefix = "info/reward_terms/"
    infos: dict[str, Any] = {k: arrays[f"info/{k}"] for k in _INFO_KEYS}
    infos["reward_terms"] = {
        k.removeprefix(terms_prefix): v for k, v in arrays.items() if k.startswith(terms_prefix)
    }
    return EpisodeRecord(
        observations=observations,
        infos=infos,
        metadata=metadata,
        **{name: arrays[name] for name in _PLAIN},
    )


def slug(text: str) -> str:
    """``text`` as a file and dataset-id friendly name: letters, digits, ``-`` and ``_``."""
    return re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-") or "x"
