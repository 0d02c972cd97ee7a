"""``pianist sweep``: one task over a grid of songs x variants x physics x seeds, on Ray."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro

from pianist.agents.config import DEFAULT_PRESET
from pianist.cli.common import CliError, check_seed
from pianist.cli.common import out as _out


def _hint(text: str, metavar: str | None = None) -> Any:
    """The default shown in --help as ``text``; ``metavar``: the value's name (an optional
    field's would show as ``{None}|TYPE``)."""
    return tyro.conf.arg(help_behavior_hint=text, metavar=metavar)


_OPTIONAL = _hint("(optional)")


@dataclass(frozen=True)
class Sweep:
    """Run play, train, eval or dataset over a grid of songs x controllers/presets/runs x physics x
    seeds, each cell a Ray task (a local Ray by default, a cluster with --address).

    Writes OUT/cells/<cell id>/ per cell (whole, or not at all), OUT/results.csv and
    results.json (one row per cell), summary.json and summary.png (mean F1 per suite and
    variant, per-song bars). A rerun skips finished cells (failed ones run again).
    """

    task: Literal["play", "train", "eval", "dataset"] = "play"
    """What each cell runs: dataset records one demonstration episode per cell (then
    `pianist dataset assemble OUT` writes them as one Minari dataset)."""
    suite: Annotated[tuple[str, ...], _OPTIONAL] = ()
    """Suites whose songs the grid holds: debug, robopianist-debug, open-etude-12, etude-12,
    repertoire-150."""
    songs: Annotated[tuple[str, ...], _OPTIONAL] = ()
    """Songs by name or file (MIDI, PIG .txt, or a score: MusicXML, Humdrum, ABC, MEI)."""
    folder: Annotated[tuple[Path, ...], _OPTIONAL] = ()
    """Folders whose song files (MIDI, PIG .txt, MusicXML, Humdrum, ABC, MEI) the grid
    holds."""
    controllers: Annotated[tuple[str, ...], _hint("(default: planner)")] = ()
    """play, dataset: controller specs, as play --controller takes them."""
    presets: Annotated[tuple[str, ...], _hint(f"(default: {DEFAULT_PRESET})")] = ()
    """train: training presets."""
    runs: Annotated[tuple[Path, ...], _hint("(required for eval)")] = ()
    """eval: training run folders to evaluate."""
    physics: Annotated[
        tuple[Literal["faithful", "fast"], ...],
        _hint("(default: the controller's own, else faithful)"),
    ] = ()
    """play, dataset: physics presets."""
    seeds: tuple[int, ...] = (0,)
    """Seeds of the episodes (play, eval) or training runs (train)."""
    out: Path = Path("runs/sweep")
    """The sweep's folder (created; a rerun into it skips finished cells)."""
    workers: Annotated[int | None, _hint("(default: this machine's cores)", "INT")] = None
    """CPUs of the local Ray: cells run at once (with --cpus-per-cell 1)."""
    address: Annotated[str | None, _hint("(optional)", "HOST:PORT")] = None
    """A Ray cluster's address (HOST:PORT of `ray start --head`) instead of a local Ray."""
    cpus_per_cell: float = 1.0
    """CPUs each cell asks Ray for."""
    max_retries: int = 3
    """How often a cell whose worker died (killed, out of memory) is run again."""
    fingering: Literal["auto", "file", "robot", "none"] = "auto"
    """play/eval: how songs are fingered (as play --fingering)."""
    initial_buffer_s: float = 0.0
    """play: seconds of silence before each song."""
    audio: bool = False
    """play: also write performance.wav and score.wav in each cell."""
    steps: int = 1_000_000
    """train: total environment steps of each run."""
    minutes: Annotated[float | None, _hint("(optional)", "FLOAT")] = None
    """train: wall-clock budget of each run."""
    noise: float = 0.02
    """dataset: std of the action noise of every seed but the first (0: none)."""
    list_only: Annotated[bool, tyro.conf.arg(name="list")] = False
    """Print the grid's cells (id and whether finished) and stop, without Ray."""

    def run(self) -> None:
        from pianist.sweep import SweepOptions, expand, run_sweep, songs_of
        from pianist.sweep.runner import check_grid
        from pianist.sweep.tasks import TASKS, read_record

        variants = self._variants()
        if not (math.isfinite(self.initial_buffer_s) and self.initial_buffer_s >= 0):
            raise CliError(f"--initial-buffer-s must be >= 0 seconds, not {self.initial_buffer_s}")
        if self.steps < 1:
            raise CliError(f"--steps must be at least 1, not {self.steps}")
        if self.minutes is not None and not (math.isfinite(self.minutes) and self.minutes > 0):
            raise CliError(f"--minutes must be a positive number, not {self.minutes}")
        if self.physics and not TASKS[self.task].takes_physics:
            raise CliError(
                f"--physics applies to --task play or dataset (a {self.task} cell's is its own)"
            )
        if not (math.isfinite(self.noise) and self.noise >= 0):
            raise CliError(f"--noise must be a std >= 0, not {self.noise}")
        for seed in self.seeds:
            check_seed(seed, "--seeds")
        songs = songs_of(self.suite, self.songs, self.folder)
        if len(self.seeds) > 1 and self.task == "play":
            _note_seedless(variants, self.seeds)
        physics: tuple[str | None, ...] = self.physics or (None,)
        cells = expand(self.task, songs, variants, physics, self.seeds)
        if self.list_only:
            check_grid(cells)
            for cell in cells:
                record = read_record(self.out, cell)
                _out(f"{cell.id}  {record['status'] if record else 'to run'}")
            _out(f"{len(cells)} cells -> {self.out}")
            return
        _require_ray()
        options = SweepOptions(
            fingering=self.fingering,
            initial_buffer_s=self.initial_buffer_s,
            audio=self.audio,
            steps=self.steps,
            minutes=self.minutes,
            noise=self.noise,
            clean_seed=min(self.seeds),
        )
        report = run_sweep(
            cells,
            self.out,
            options=options,
            workers=self.workers,
            address=self.address,
            cpus_per_cell=self.cpus_per_cell,
            max_retries=self.max_retries,
            message=_out,
        )
        ok = len(report.rows) - report.failed
        timing = f" in {report.wall_s:.1f} s" if report.ran else ""
        _out(
            f"{len(report.rows)} cells: {ok} ok, {report.failed} failed ({report.ran} run"
            f"{timing}, {report.skipped} skipped) -> {self.out / 'results.csv'}"
        )
        if report.failed:  # the exit status tells a script what the table tells a person
            raise CliError(
                f"{report.failed} of {len(report.rows)} cells failed: their errors are in "
                f"{self.out / 'results.csv'} (a rerun runs them again)"
            )

    def _variants(self) -> list[str]:
        given: dict[str, list[str]] = {
            "play": list(self.controllers),
            "dataset": list(self.controllers),
            "train": list(self.presets),
            "eval": [str(run) for run in self.runs],
        }
        flags = {"play": "--controllers", "train": "--presets", "eval": "--runs"}
        uses = {"dataset": "play"}.get(self.task, self.task)  # dataset takes --controllers
        for task, variants in given.items():
            if task != "dataset" and variants and task != uses:
                raise CliError(f"{flags[task]} applies to --task {task}, not {self.task}")
        if given[self.task]:
            return given[self.task]
        if self.task == "eval":
            raise CliError("--task eval needs --runs RUN_DIR ... (training run folders)")
        from pianist.sweep.tasks import TASKS

        return [TASKS[self.task].default_variant]


def _note_seedless(variants: list[str], seeds: tuple[int, ...]) -> None:
    """Say which controllers play the same whatever the seed: their rows for the seeds will
    be the same (a deterministic controller in a start the seed does not change)."""
    from pianist.control.registry import parse_controller

    same = [v for v in variants if not parse_controller(v).uses_seed()]
    if same:
        _out(
            f"note: the seed does not change what {', '.join(same)} "
            f"{'plays' if len(same) == 1 else 'play'}: the {len(seeds)} seeds give the same "
            "rows there"
        )


def _require_ray() -> None:
    import importlib.util

    if importlib.util.find_spec("ray") is None:
        raise CliError("sweep runs on Ray: pip install 'pianist[scale]'")
