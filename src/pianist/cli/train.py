"""``pianist train`` and ``pianist eval``: learn a policy for a song, and score it."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import tyro

from pianist.agents.config import DEFAULT_PRESET
from pianist.cli.common import CliError, SongArg
from pianist.cli.common import out as _out
from pianist.cli.common import prepare_dir as _prepare_dir
from pianist.cli.common import require_jax as _require_jax


@dataclass(frozen=True)
class Train:
    """Train an agent on a song (SAC/DroQ in JAX): log, checkpoints and config go to --out."""

    song: tyro.conf.Positional[
        Annotated[
            str | None,
            tyro.conf.arg(metavar="SONG", help_behavior_hint="(required unless --resume)"),
        ]
    ] = None
    """A built-in song name, a MIDI file or a PIG file."""
    preset: str = DEFAULT_PRESET
    """residual-anchored (a correction learned on top of the planner: the best measured per
    minute on real pieces), fast-small (from scratch: Twinkle in minutes), droq-paper (the
    paper's recipe: millions of steps), droq-paper-pipelined, sac, redq, fast, fast-utd2,
    residual, residual-windows."""
    steps: Annotated[
        int | None,
        tyro.conf.arg(help_behavior_hint="(default: 1000000; when resuming, the run's own)"),
    ] = None
    """Total environment steps."""
    minutes: Annotated[float | None, tyro.conf.arg(help_behavior_hint="(optional)")] = None
    """Wall-clock budget of this call: training stops at the end of the episode in which it
    runs out (after a checkpoint; the best evaluated policy is kept in OUT/best)."""
    out: Path = Path("runs/train")
    """Run directory (created if missing)."""
    resume: Annotated[Path | None, tyro.conf.arg(help_behavior_hint="(optional)")] = None
    """Continue the run in this directory from its newest checkpoint."""
    progress: bool = True
    """Show a progress bar with steps/s and the latest F1 (on a terminal only: a redrawn bar
    would write thousands of lines into a pipe or log file)."""

    def run(self) -> None:
        from pianist.agents import PRESETS, train
        from pianist.agents.rundir import read_run_config

        if self.steps is not None and self.steps < 1:
            raise CliError(f"--steps must be at least 1, not {self.steps}")
        if self.minutes is not None and not (math.isfinite(self.minutes) and self.minutes > 0):
            raise CliError(f"--minutes must be a positive number, not {self.minutes}")
        budget_s = None if self.minutes is None else 60.0 * self.minutes
        _require_jax()
        show_bar = self.progress and sys.stderr.isatty()
        if self.resume is not None:
            steps = (
                self.steps if self.steps is not None else int(read_run_config(self.resume)["steps"])
            )
            result = train(
                None,
                None,
                steps,
                self.resume,
                resume=True,
                progress=show_bar,
                message=_out,
                stop_after_s=budget_s,
            )
        else:
            if self.song is None:
                raise CliError("give a SONG to train on, or --resume DIR")
            if self.preset not in PRESETS:
                raise CliError(f"unknown preset {self.preset!r}; choose from {', '.join(PRESETS)}")
            _prepare_dir(self.out)
            result = train(
                self.song,
                self.preset,
                self.steps if self.steps is not None else 1_000_000,
                self.out,
                progress=show_bar,
                message=_out,
                stop_after_s=budget_s,
            )
        f1 = result.last_eval.get("f1", float("nan"))
        _out(f"trained to step {result.step}: F1 {f1:.3f} -> {result.run_dir}")
        if result.best_eval:
            best = result.best_eval
            _out(
                f"best evaluation: F1 {best['f1']:.3f} at step {best['step']} -> "
                f"{result.run_dir / 'best'}"
            )


@dataclass(frozen=True)
class Eval:
    """Score a trained policy on a song: metrics.json, performance.mid, actions.npy and
    pianoroll.png."""

    run_dir: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="RUN_DIR")]]
    """A training run directory (from `pianist train`)."""
    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file or a PIG file."""
    out: Annotated[Path | None, tyro.conf.arg(help_behavior_hint="(default: RUN_DIR/eval)")] = None
    """Output directory."""
    seed: int = 0
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(help_behavior_hint="(default: the one it was trained in)"),
    ] = None
    """Evaluate in this physics preset instead of the one the policy was trained in (the
    rest of its task unchanged): how a policy trained on the fast preset plays on the
    faithful one."""

    def run(self) -> None:
        from pianist.agents import PolicyController
        from pianist.eval.session import play
        from pianist.media.results import MediaOptions, check_output_folder, write_result

        controller = PolicyController(self.run_dir, physics=self.physics)
        out = self.out or self.run_dir / "eval"
        check_output_folder(out)
        result = play(self.song, controller, seed=self.seed)
        metrics = result.metrics
        extra = {
            "song": self.song,
            "run": str(self.run_dir),
            "checkpoint_step": controller.step,
            "preset": controller.config.preset,
            "trained_physics": controller.config.task.physics,
        }
        write_result(result, out, MediaOptions(audio=False), extra_metrics=extra)
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"(policy at step {controller.step}) -> {out}"
        )
