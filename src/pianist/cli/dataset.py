"""``pianist dataset``: record demonstration datasets in the Farama Minari format, describe one."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro

from pianist.cli.common import CliError, check_seed, prepare_dir
from pianist.cli.common import out as _out


def _hint(text: str, metavar: str | None = None) -> Any:
    """The default shown in --help as ``text``; ``metavar``: the value's name (an optional
    field's would show as ``{None}|TYPE``)."""
    return tyro.conf.arg(help_behavior_hint=text, metavar=metavar)


_ROOT_HINT = _hint("(default: $MINARI_DATASETS_PATH, else ~/.minari/datasets)", "PATH")


@dataclass(frozen=True)
class Build:
    """Play every song K times with a controller and store each step (observation, action,
    reward terms, goal and key states) with each episode's F1 and the song's provenance as a
    Minari dataset (docs/datasets.md).

    Episode i of a song has seed --seed + i; from the second episode on, actions get Gaussian
    noise of std --noise (the planner is deterministic). Episodes are kept in ROOT/.pianist-work
    until all exist: a rerun of the same command records only the missing ones.
    """

    songs: tuple[str, ...]
    """Suites (debug, robopianist-debug, open-etude-12, etude-12, repertoire-150), folders of
    song files (MIDI, fingered automatically, PIG, or scores: MusicXML, Humdrum, ABC, MEI),
    or songs by name or file."""
    controller: str = "planner"
    """The demonstrator: any controller `pianist play` takes (`pianist play --help` lists
    every kind with its options), e.g. planner, refine or policy:RUN_DIR."""
    episodes: int = 1
    """Episodes per song (K)."""
    out: Annotated[str | None, _hint("(default: pianist/<songs>-<controller>-v0)", "STR")] = None
    """The dataset id, (NAMESPACE/)NAME-vN, e.g. pianist/open-etude-12-planner-v0."""
    root: Annotated[Path | None, _ROOT_HINT] = None
    """Where datasets are stored (Minari's datasets folder)."""
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        _hint("(default: the controller's own, else faithful)", "faithful|fast"),
    ] = None
    """Physics preset."""
    noise: float = 0.02
    """Std of the action noise of episodes 2..K (action units; 0: none)."""
    seed: int = 0
    """Seed of each song's first episode."""
    workers: int = 1
    """Episodes recorded at once, each in its own process."""

    def run(self) -> None:
        from pianist.data.build import BuildSettings, build_dataset
        from pianist.data.minari_io import default_root

        _require_minari()
        if self.episodes < 1:
            raise CliError(f"--episodes must be >= 1, not {self.episodes}")
        if self.workers < 1:
            raise CliError(f"--workers must be >= 1, not {self.workers}")
        check_seed(self.seed)
        root = self.root if self.root is not None else default_root()
        prepare_dir(root)
        settings = BuildSettings(
            controller=self.controller, physics=self.physics, noise=self.noise, seed=self.seed
        )
        build_dataset(
            self.songs,
            episodes=self.episodes,
            settings=settings,
            dataset_id=self.out,
            root=root,
            workers=self.workers,
            log=_out,
        )


@dataclass(frozen=True)
class DatasetInfo:
    """Describe a dataset: episodes, steps, mean F1 per song, the songs' provenance."""

    name: tyro.conf.Positional[Annotated[str, tyro.conf.arg(metavar="NAME")]]
    """The dataset id, e.g. pianist/open-etude-12-planner-v0."""
    root: Annotated[Path | None, _ROOT_HINT] = None
    """Where datasets are stored."""

    def run(self) -> None:
        from pianist.data.minari_io import dataset_summary, load_dataset

        _require_minari()
        summary = dataset_summary(load_dataset(self.name, self.root))
        settings = summary["pianist"].get("settings", {})
        _out(
            f"{summary['dataset_id']}: {summary['episodes']} episodes, {summary['steps']} "
            f"steps, mean F1 {summary['mean_f1']:.3f}"
            + (f"; controller {settings['controller']}" if "controller" in settings else "")
        )
        provenance = summary["pianist"].get("songs", {})
        _out(f"{'song':40s} {'episodes':>8s} {'F1':>6s}  source")
        for song, row in summary["songs"].items():
            source = provenance.get(song, {}).get("source", "?")
            _out(f"{song:40s} {row['episodes']:8d} {row['mean_f1']:6.3f}  {source}")


@dataclass(frozen=True)
class Assemble:
    """Write the episodes a `pianist sweep --task dataset` recorded (on Ray, on one machine or
    a cluster) as one Minari dataset."""

    sweep: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="SWEEP_DIR")]]
    """The sweep's folder (its --out)."""
    out: str
    """The dataset id, (NAMESPACE/)NAME-vN."""
    root: Annotated[Path | None, _ROOT_HINT] = None
    """Where datasets are stored (Minari's datasets folder)."""

    def run(self) -> None:
        from pianist.data.minari_io import default_root
        from pianist.sweep.datasets import assemble_sweep

        _require_minari()
        root = self.root if self.root is not None else default_root()
        prepare_dir(root)
        report = assemble_sweep(self.sweep, self.out, root)
        _out(
            f"wrote {report.path}: {report.episodes} episodes, {report.steps} steps, "
            f"mean F1 {report.mean_f1:.3f}"
        )


@dataclass(frozen=True)
class Dataset:
    """Demonstration datasets in the Farama Minari format: build one, assemble one from a
    sweep, describe one."""

    # OmitArgPrefixes: the subcommand's description is shown once, not again over its options.
    command: tyro.conf.OmitArgPrefixes[
        tyro.conf.OmitSubcommandPrefixes[
            Annotated[Build, tyro.conf.subcommand("build")]
            | Annotated[Assemble, tyro.conf.subcommand("assemble")]
            | Annotated[DatasetInfo, tyro.conf.subcommand("info")]
        ]
    ]

    def run(self) -> None:
        self.command.run()


def _require_minari() -> None:
    import importlib.util

    if importlib.util.find_spec("minari") is None or importlib.util.find_spec("h5py") is None:
        raise CliError("datasets need Minari: pip install 'pianist[data]' (minari[hdf5])")
