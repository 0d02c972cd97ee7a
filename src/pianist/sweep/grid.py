"""A sweep's grid: which cells it holds, in which order, and each cell's id.

A grid is songs x variants x physics presets x seeds for one task. Songs come from suites
(:func:`pianist.music.list_songs`), an explicit list (names or files) and folders of MIDI
files, in that order, each song once; the variant is what the task varies besides the song:
a controller spec (``play``), a training preset (``train``) or a trained run's folder
(``eval``). :func:`expand` lists the cells song by song, then variant, physics and seed, so
the cells of one song are neighbours in the table.

A cell's id names its folder: stable (the same spelling of the same cell gives the same id on
every machine and every run) and safe as a file name on any filesystem (ASCII letters, digits,
``.``, ``_`` and ``-``, at most ~120 characters). Where the readable part had to drop
characters (a file path, a spec with ``:`` or ``=``) a short hash of the exact spelling keeps
two different cells apart.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

#: The suite name of songs given one by one (``--songs``).
LIST_SUITE = "songs"

_SAFE = re.compile(r"[A-Za-z0-9._-]+")
_UNSAFE_RUN = re.compile(r"[^A-Za-z0-9._-]+")
_PART_CHARS = 40


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a task on one song with one variant, physics preset and seed.

    Attributes:
        task: the task's name (``play``, ``train``, ``eval``; :data:`pianist.sweep.tasks.TASKS`).
        song: a built-in song name or a file path, as given.
        suite: where the song came from: a suite's name, ``songs`` (given one by one) or the
            folder's name; the summary groups by it.
        variant: a controller spec, a training preset or a trained run's folder.
        physics: "faithful", "fast", or None (the task's default).
        seed: the episode's or the training run's seed.
    """

    task: str
    song: str
    suite: str
    variant: str
    physics: str | None
    seed: int

    @property
    def id(self) -> str:
        """The cell's folder name (see the module docstring)."""
        return cell_id(self)

    def as_dict(self) -> dict[str, Any]:
        return {"id": self.id, **asdict(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Cell:
        return cls(
            task=str(data["task"]),
            song=str(data["song"]),
            suite=str(data["suite"]),
            variant=str(data["variant"]),
            physics=None if data.get("physics") is None else str(data["physics"]),
            seed=int(data["seed"]),
        )


def _part(text: str) -> tuple[str, bool]:
    """A readable, safe rendering of ``text`` and whether it is exact."""
    if _SAFE.fullmatch(text) and len(text) <= _PART_CHARS and not text.startswith("."):
        return text, True
    if "/" in text or "\\" in text:  # a path: its last folder and file name say the most
        path = Path(text.replace("\\", "/"))
        text = "-".join([*path.parent.parts[-1:], path.stem]) or text
    readable = _UNSAFE_RUN.sub("-", text).strip("-.")[:_PART_CHARS].strip("-.")
    return readable or "x", False


def cell_id(cell: Cell) -> str:
    """``<song>.<variant>.<physics>.s<seed>``, plus ``-<hash>`` when a part is not exact.

    The task is not part of the id: a sweep's folder holds one task's cells. Examples:
    ``twinkle-twinkle.planner.fast.s0``; ``midi-nocturne.policy-runs-a.default.s1-3f9c2a1b``
    for the song ``midi/nocturne.mid`` and the variant ``policy:runs/a``.
    """
    song, song_exact = _part(cell.song)
    variant, variant_exact = _part(cell.variant)
    physics = cell.physics or "default"
    name = f"{song}.{variant}.{physics}.s{cell.seed}"
    if song_exact and variant_exact:
        return name
    key = "\0".join((cell.song, cell.variant, physics, str(cell.seed)))
    return f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:8]}"


def songs_of(
    suites: Sequence[str] = (), songs: Sequence[str] = (), folders: Sequence[str | Path] = ()
) -> list[tuple[str, str]]:
    """The (song, suite) pairs of a grid: each suite's songs, then ``songs``, then each folder's
    song files (MIDI or PIG, sorted by name), each song once (its first place wins).

    Raises:
        ValueError: an unknown suite, a folder that does not exist, or no song at all.
        PigDatasetError: a PIG suite before ``pianist import-pig`` has run.
    """
    from pianist.music import list_songs
    from pianist.music.fileio import SONG_FILE_SUFFIXES, song_files

    found: list[tuple[str, str]] = []
    for suite in suites:
        found.extend((song, suite) for song in list_songs(suite))
    found.extend((song, LIST_SUITE) for song in songs)
    for folder in folders:
        path = Path(folder)
        if not path.is_dir():
            raise ValueError(f"song folder {path} does not exist or is not a folder")
        files = song_files(path)
        if not files:
            kinds = ", ".join(SONG_FILE_SUFFIXES)
            raise ValueError(f"song folder {path} holds no song file ({kinds})")
        suite = path.resolve().name or str(path)
        found.extend((str(p), suite) for p in files)
    seen: set[str] = set()
    unique = []
    for song, suite in found:
        if song not in seen:
            seen.add(song)
            unique.append((song, suite))
    if not unique:
        raise ValueError("the grid has no song: give --suite, --songs or --folder")
    return unique


def expand(
    task: str,
    songs: Sequence[tuple[str, str]],
    variants: Sequence[str],
    physics: Sequence[str | None] = (None,),
    seeds: Sequence[int] = (0,),
) -> list[Cell]:
    """Every cell of the grid, song by song, then variant, physics and seed.

    Args:
        task: the task every cell runs.
        songs: (song, suite) pairs, e.g. from :func:`songs_of`.
        variants: controller specs, training presets or run folders (at least one).
        physics: physics presets (None: the task's default).
        seeds: seeds (at least one).
    Returns:
        len(songs) * len(variants) * len(physics) * len(seeds) cells, duplicates removed.
    Raises:
        ValueError: an empty dimension, or two cells that would share an id.
    """
    for name, values in (("variant", variants), ("physics", physics), ("seed", seeds)):
        if not values:
            raise ValueError(f"the grid needs at least one {name}")
    cells = [
        Cell(task, song, suite, variant, preset, int(seed))
        for song, suite in songs
        for variant in dict.fromkeys(variants)
        for preset in dict.fromkeys(physics)
        for seed in dict.fromkeys(seeds)
    ]
    by_id: dict[str, Cell] = {}
    for cell in cells:
        other = by_id.setdefault(cell.id, cell)
        if other != cell:
            raise ValueError(f"two cells share the id {cell.id}: {other} and {cell}")
    return cells
