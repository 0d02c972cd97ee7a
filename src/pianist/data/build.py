"""A dataset build: songs x episodes recorded (resumable, in parallel), then one Minari dataset.

Each episode is recorded by :func:`pianist.data.record.record_episode` into its own folder of
a work folder, ``ROOT/.pianist-work/<id>/episodes/``, which appears whole or not at all; a
rerun records only the episodes whose folder is missing. Once every episode exists the
dataset is written whole (:func:`pianist.data.minari_io.write_dataset`) and the work folder
removed. Episodes run in local processes (``workers`` > 1, spawned: MuJoCo and JAX state are
not forked); a sweep can run :func:`record_episode` itself with the arguments of
:func:`plan_episodes`' tasks and then call :func:`assemble`.

Variety: episode ``i`` of a song is played with seed ``seed + i``, and from the second episode
on (``i`` >= 1) with Gaussian action noise of std ``noise``: the planner is deterministic, so
without noise every episode of a song would be the same.
"""

from __future__ import annotations

import json
import math
import multiprocessing
import shutil
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pianist.data.minari_io import check_dataset_id, dataset_dir, default_root, write_dataset
from pianist.data.record import EpisodeRecord, read_episode, record_episode, slug
from pianist.files import write_json_atomic

WORK_FOLDER = ".pianist-work"
SETTINGS_FILE = "settings.json"
DEFAULT_NOISE = 0.02

Log = Callable[[str], None]


@dataclass(frozen=True)
class BuildSettings:
    """What every episode of one dataset is played with (a resumed build must match)."""

    controller: str = "planner"
    physics: str | None = None
    noise: float = DEFAULT_NOISE
    seed: int = 0
    fingering: str = "auto"


@dataclass(frozen=True)
class EpisodeTask:
    """One episode to record: :func:`record_episode`'s arguments and where it goes."""

    song: str
    index: int
    seed: int
    noise: float
    out_dir: Path


@dataclass
class BuildReport:
    """What a build did: the dataset's id and folder, episodes recorded now and found done."""

    dataset_id: str
    path: Path
    episodes: int
    recorded: int
    skipped: int
    steps: int
    mean_f1: float
    f1_by_song: dict[str, float] = field(default_factory=dict)


def resolve_songs(entries: tuple[str, ...] | list[str]) -> list[str]:
    """The songs of ``entries``, each a suite name, a folder of song files (MIDI or
    PIG) or one song.

    Raises:
        ValueError: nothing given, an empty folder, or an entry that is none of these.
        MusicError: a song cannot be loaded.
    """
    from pianist.music import SUITES, MusicError, list_songs, load_song
    from pianist.music.fileio import SONG_FILE_SUFFIXES, song_files

    if not entries:
        raise ValueError("no songs: give --songs a suite, a folder of MIDI files or a song")
    refs: list[str] = []
    for entry in entries:
        path = Path(entry)
        if entry in SUITES:
            refs.extend(list_songs(entry))
        elif path.is_dir():
            files = song_files(path)
            if not files:
                kinds = ", ".join(SONG_FILE_SUFFIXES)
                raise ValueError(f"folder {path} holds no song files ({kinds})")
            refs.extend(str(p) for p in files)
        else:
            try:
                load_song(entry)
            except MusicError:
                raise ValueError(
                    f"--songs {entry!r} is not a suite ({', '.join(SUITES)}), a folder of MIDI "
                    "files or a song name or file"
                ) from None
            refs.append(entry)
    duplicates = {_song_key(r) for r in refs if sum(_song_key(o) == _song_key(r) for o in refs) > 1}
    if duplicates:
        raise ValueError(f"songs named twice: {', '.join(sorted(duplicates))}")
    return refs


def _song_key(ref: str) -> str:
    """The name a song's episodes are filed under (a file's stem)."""
    path = Path(ref)
    return slug(path.stem if path.suffix.lower() in (".mid", ".midi", ".txt") else ref)


def default_dataset_id(entries: tuple[str, ...] | list[str], controller: str) -> str:
    """``pianist/<songs>-<controller>-v0``, e.g. ``pianist/open-etude-12-planner-v0``."""
    label = slug(Path(entries[0]).name) if entries else "songs"
    return f"pianist/{label}-{slug(controller)}-v0"


def work_dir(dataset_id: str, root: Path) -> Path:
    """Where a build of ``dataset_id`` keeps its episodes until the dataset is written."""
    return root / WORK_FOLDER / dataset_id.replace("/", "__")


def plan_episodes(
    songs: list[str], episodes: int, settings: BuildSettings, work: Path
) -> list[EpisodeTask]:
    """The build's episodes, song by song: episode ``i`` has seed ``settings.seed + i`` and
    noise 0 for ``i`` = 0, ``settings.noise`` after."""
    return [
        EpisodeTask(
            song=song,
            index=i,
            seed=settings.seed + i,
            noise=0.0 if i == 0 else settings.noise,
            out_dir=work / "episodes" / f"{_song_key(song)}--{i:04d}",
        )
        for song in songs
        for i in range(episodes)
    ]


def build_dataset(
    songs: tuple[str, ...] | list[str],
    *,
    episodes: int,
    settings: BuildSettings = BuildSettings(),
    dataset_id: str | None = None,
    root: Path | None = None,
    workers: int = 1,
    log: Log | None = None,
) -> BuildReport:
    """Record ``episodes`` episodes of every song and write them as one Minari dataset.

    Args:
        songs: suites, folders of MIDI files or songs (:func:`resolve_songs`).
        episodes: episodes per song (>= 1).
        settings: controller, physics, action noise (from the second episode), first seed.
        dataset_id: the Minari id; default :func:`default_dataset_id`.
        root: the datasets folder; default Minari's (:func:`default_root`).
        workers: episodes recorded at once, each in its own process (1: in this process).
        log: called with one line per recorded episode and step of the build.
    Returns:
        The :class:`BuildReport`.
    Raises:
        ValueError: bad arguments, an existing dataset, a work folder of other settings, or
            episodes that failed (those recorded stay for the rerun).
        MusicError: a song cannot be loaded.
        FileWriteError: the root is not writable.
    """
    say = log or (lambda _line: None)
    if episodes < 1:
        raise ValueError(f"--episodes must be >= 1, not {episodes}")
    if workers < 1:
        raise ValueError(f"--workers must be >= 1, not {workers}")
    if not (math.isfinite(settings.noise) and settings.noise >= 0):
        raise ValueError(f"--noise must be a std >= 0, not {settings.noise}")
    if settings.physics not in (None, "faithful", "fast"):
        raise ValueError(f"--physics must be faithful or fast, not {settings.physics!r}")
    dataset_id = dataset_id or default_dataset_id(songs, settings.controller)
    check_dataset_id(dataset_id)
    root = Path(root) if root is not None else default_root()
    if dataset_dir(dataset_id, root).exists():
        raise ValueError(
            f"dataset {dataset_id} already exists in {root}: choose another --out (a new "
            "version, -v1) or delete it first"
        )
    refs = resolve_songs(songs)
    from pianist.data.record import episode_controller

    episode_controller(settings.controller, 0.0)  # an unknown controller fails here, once
    work = work_dir(dataset_id, root)
    _claim_work_dir(work, settings)
    tasks = plan_episodes(refs, episodes, settings, work)
    todo = [task for task in tasks if not task.out_dir.is_dir()]
    say(
        f"{dataset_id}: {len(tasks)} episodes ({len(refs)} songs x {episodes}), "
        f"{len(tasks) - len(todo)} already recorded, {len(todo)} to record"
    )
    failures = _run(todo, settings, workers, say)
    if failures:
        first = failures[0]
        raise ValueError(
            f"{len(failures)} of {len(todo)} episodes failed (the {len(todo) - len(failures)} "
            f"others are kept; rerun to retry): {first[0].song} episode {first[0].index}: "
            f"{first[1]}"
        )
    report = assemble(dataset_id, tasks, settings, root, recorded=len(todo))
    shutil.rmtree(work, ignore_errors=True)
    if not any((root / WORK_FOLDER).iterdir()):
        (root / WORK_FOLDER).rmdir()
    say(
        f"wrote {report.path}: {report.episodes} episodes, {report.steps} steps, "
        f"mean F1 {report.mean_f1:.3f}"
    )
    return report


def _shown(setting: Any) -> str:
    """A setting as a message names it (None: the controller's own, the default)."""
    return "the default" if setting is None else repr(setting)


def _claim_work_dir(work: Path, settings: BuildSettings) -> None:
    """Create the work folder, or check that the one there holds these settings' episodes."""
    path = work / SETTINGS_FILE
    wanted = asdict(settings)
    if path.is_file():
        found = json.loads(path.read_text(encoding="utf-8"))
        if found != wanted:
            changed = ", ".join(
                f"{key} {_shown(found.get(key))} -> {_shown(value)}"
                for key, value in wanted.items()
                if found.get(key) != value
            )
            raise ValueError(
                f"{work} holds episodes recorded with other settings ({changed}): rerun with "
                "those settings to resume, or delete the folder"
            )
        return
    (work / "episodes").mkdir(parents=True, exist_ok=True)
    write_json_atomic(wanted, path)


def _record(task: EpisodeTask, settings: BuildSettings) -> Path:
    return record_episode(
        task.song,
        settings.controller,
        task.seed,
        settings.physics,
        task.out_dir,
        noise=task.noise,
        fingering=settings.fingering,
    )


def _run(
    todo: list[EpisodeTask], settings: BuildSettings, workers: int, say: Log
) -> list[tuple[EpisodeTask, str]]:
    """Record ``todo``; return the failed tasks with their one-line errors."""
    failures: list[tuple[EpisodeTask, str]] = []
    done = 0

    def finished(task: EpisodeTask, error: BaseException | None) -> None:
        nonlocal done
        done += 1
        where = f"[{done}/{len(todo)}] {_song_key(task.song)} episode {task.index}"
        if error is not None:
            failures.append((task, " ".join(str(error).split())))
            say(f"{where}: failed: {failures[-1][1]}")
            return
        f1 = json.loads((task.out_dir / "episode.json").read_text(encoding="utf-8"))["f1"]
        say(f"{where}: F1 {f1:.3f}")

    if workers == 1 or len(todo) <= 1:
        for task in todo:
            try:
                _record(task, settings)
            except Exception as exc:  # noqa: BLE001 - kept as this episode's failure, as in a worker
                finished(task, exc)
            else:
                finished(task, None)
        return failures
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=context) as pool:
        futures: dict[Future[Path], EpisodeTask] = {
            pool.submit(_record, task, settings): task for task in todo
        }
        for future in as_completed(futures):
            finished(futures[future], future.exception())
    return failures


def assemble(
    dataset_id: str,
    tasks: list[EpisodeTask],
    settings: BuildSettings,
    root: Path,
    *,
    recorded: int = 0,
) -> BuildReport:
    """Write the recorded episodes of ``tasks`` (all must exist) as Minari dataset
    ``dataset_id`` under ``root``."""
    steps = 0
    f1: dict[str, list[float]] = {}
    songs: dict[str, Any] = {}

    def records() -> Iterator[EpisodeRecord]:
        nonlocal steps
        for task in tasks:
            try:
                record = read_episode(task.out_dir)
            except ValueError as exc:
                raise ValueError(
                    f"{exc}; delete {task.out_dir} and build again to record that episode anew"
                ) from None
            steps += record.num_steps
            f1.setdefault(record.metadata["song"], []).append(float(record.metadata["f1"]))
            songs[record.metadata["song"]] = record.metadata["provenance"]
            yield record

    metadata = {
        "settings": asdict(settings),
        "songs": songs,  # filled while the records are read
        "episodes": [
            {"song": _song_key(t.song), "index": t.index, "seed": t.seed, "noise": t.noise}
            for t in tasks
        ],
        "infos": "per step, aligned with actions: active_keys (T, 88) bool, sustain (T,), "
        "goal_keys (T, 88) bool, goal_sustain (T,), reward_terms/NAME (T,)",
    }
    description = (
        f"Demonstrations of the {settings.controller} controller playing "
        f"{len({t.song for t in tasks})} songs on pianist's two Shadow hands and 88-key piano; "
        f"episode 0 of each song is noiseless, later ones add action noise of std "
        f"{settings.noise}."
    )
    path = write_dataset(
        dataset_id,
        records(),  # fills metadata['songs'], which write_dataset stores after the episodes
        root,
        algorithm_name=settings.controller,
        description=description,
        metadata=metadata,
    )
    all_f1 = [value for values in f1.values() for value in values]
    return BuildReport(
        dataset_id=dataset_id,
        path=path,
        episodes=len(tasks),
        recorded=recorded,
        skipped=len(tasks) - recorded,
        steps=steps,
        mean_f1=float(np.mean(all_f1)),
        f1_by_song={song: float(np.mean(values)) for song, values in f1.items()},
    )
