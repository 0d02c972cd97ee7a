"""``pianist train`` and ``pianist eval``: learn a policy for a song, and score it."""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro

from pianist.agents.config import DEFAULT_PRESET, PRACTICE_PRESET
from pianist.cli.common import CliError, SongArg, check_seed
from pianist.cli.common import out as _out
from pianist.cli.common import prepare_dir as _prepare_dir
from pianist.cli.common import require_jax as _require_jax


@dataclass(frozen=True)
class Train:
    """Learn to play a song: practise it (the default), or train a SAC/DroQ agent (JAX) with
    --preset; the log, checkpoints or table and the config go to --out."""

    song: tyro.conf.Positional[
        Annotated[
            str | None,
            tyro.conf.arg(metavar="SONG", help_behavior_hint="(required unless --resume)"),
        ]
    ] = None
    """A built-in song name, a MIDI file, a PIG file or a score (MusicXML, Humdrum, ABC, MEI)."""
    preset: str = DEFAULT_PRESET
    """practice (a correction per step learned by replaying the piece with the refiner's
    look-ahead: no network, no JAX; the best measured per minute on real pieces),
    residual-anchored (a soft actor-critic correction learned on top of the planner),
    fast-small (from scratch: Twinkle in minutes), droq-paper (the paper's recipe: millions
    of steps), droq-paper-pipelined, sac, redq, fast, fast-utd2, residual, residual-windows."""
    steps: Annotated[
        int | None,
        tyro.conf.arg(
            metavar="INT", help_behavior_hint="(default: 1000000; when resuming, the run's own)"
        ),
    ] = None
    """Total environment steps."""
    minutes: Annotated[
        float | None, tyro.conf.arg(metavar="FLOAT", help_behavior_hint="(optional)")
    ] = None
    """Wall-clock budget of this call. Practice: a pass that runs into it plays the rest of
    the piece without looking ahead (what it learned is kept), and no pass starts that could
    not end in time. A soft actor-critic run stops at the end of the episode in which it runs
    out (after a checkpoint; the best evaluated policy is kept in OUT/best)."""
    out: Path = Path("runs/train")
    """Run directory (created if missing)."""
    resume: Annotated[
        Path | None, tyro.conf.arg(metavar="PATH", help_behavior_hint="(optional)")
    ] = None
    """Continue the run in this directory from its newest checkpoint."""
    passes: Annotated[
        int | None,
        tyro.conf.arg(metavar="INT", help_behavior_hint="(practice: default 20, or --minutes)"),
    ] = None
    """--preset practice: the most passes over the piece (--minutes may stop it sooner; with
    --minutes and no --passes, as many as the minutes allow)."""
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(metavar="faithful|fast", help_behavior_hint="(practice: default faithful)"),
    ] = None
    """--preset practice: the physics preset practised in (the piece is played in it later)."""
    eval_physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(metavar="faithful|fast", help_behavior_hint="(default: the preset's)"),
    ] = None
    """A soft actor-critic run's evaluations, which choose the policy kept in OUT/best, in
    this physics preset (the fast presets train on fast and evaluate on faithful)."""
    workers: Annotated[
        int | None, tyro.conf.arg(metavar="INT", help_behavior_hint="(practice: default 2)")
    ] = None
    """--preset practice: passes played at once, one per process (2 on two cores)."""
    progress: bool = True
    """Show a progress bar with steps/s and the latest F1 (on a terminal only: a redrawn bar
    would write thousands of lines into a pipe or log file)."""

    def run(self) -> None:
        started = time.perf_counter()  # --minutes counts the set-up (JAX, compiling) too
        from pianist.agents import PRESETS, get_preset, train
        from pianist.agents.rundir import read_run_config

        if self.steps is not None and self.steps < 1:
            raise CliError(f"--steps must be at least 1, not {self.steps}")
        if self.minutes is not None and not (math.isfinite(self.minutes) and self.minutes > 0):
            raise CliError(f"--minutes must be a positive number, not {self.minutes}")
        budget_s = None if self.minutes is None else 60.0 * self.minutes
        if self.resume is not None and self.song is not None:
            raise CliError(
                f"--resume continues the song {self.resume} was started with; leave out SONG"
            )
        if self.resume is None:
            _check_new_run_dir(self.out)
        if self._practice():
            if self.eval_physics is not None:
                raise CliError("--eval-physics applies to soft actor-critic presets, not practice")
            self._run_practice(budget_s)
            return
        if self.passes is not None or self.physics is not None or self.workers is not None:
            raise CliError("--passes, --physics and --workers apply to --preset practice only")
        _require_jax()
        show_bar = self.progress and sys.stderr.isatty()
        if self.resume is not None:
            if self.eval_physics is not None:
                raise CliError("--eval-physics is part of a run: a resumed run keeps its own")
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
                budget_from=started,
            )
        else:
            if self.song is None:
                raise CliError("give a SONG to train on, or --resume DIR")
            if self.preset not in PRESETS:
                choices = ", ".join((PRACTICE_PRESET, *PRESETS))
                raise CliError(f"unknown preset {self.preset!r}; choose from {choices}")
            _prepare_dir(self.out)
            preset: Any = self.preset
            if self.eval_physics is not None:
                preset = get_preset(self.preset, eval_physics=self.eval_physics)
            result = train(
                _song_spec(self.song),
                preset,
                self.steps if self.steps is not None else 1_000_000,
                self.out,
                progress=show_bar,
                message=_out,
                stop_after_s=budget_s,
                budget_from=started,
            )
        f1 = result.last_eval.get("f1", float("nan"))
        _out(f"trained to step {result.step}: F1 {f1:.3f} -> {result.run_dir}")
        if result.best_eval:
            best = result.best_eval
            _out(
                f"best evaluation: F1 {best['f1']:.3f} at step {best['step']} -> "
                f"{result.run_dir / 'best'}"
            )

    def _practice(self) -> bool:
        from pianist.agents.practice import is_practice_run

        if self.resume is not None:
            return is_practice_run(self.resume)
        return self.preset == PRACTICE_PRESET

    def _run_practice(self, budget_s: float | None) -> None:
        from dataclasses import replace

        from pianist.agents.practice import PracticeConfig, load_practice, practise_in
        from pianist.music import load_song

        if self.steps is not None:
            raise CliError("--steps does not apply to --preset practice; use --passes or --minutes")
        if self.passes is not None and self.passes < 1:
            raise CliError(f"--passes must be at least 1, not {self.passes}")
        if self.workers is not None and self.workers < 1:
            raise CliError(f"--workers must be at least 1, not {self.workers}")
        start = None
        if self.resume is not None:
            run_dir = self.resume
            song_spec, config, start = load_practice(run_dir)
            if self.physics is not None and self.physics != config.physics:
                raise CliError(
                    f"{run_dir} practises in {config.physics} physics, not {self.physics}"
                )
        else:
            if self.song is None:
                raise CliError("give a SONG to train on, or --resume DIR")
            run_dir, song_spec = self.out, _song_spec(self.song)
            config = PracticeConfig(physics=self.physics or "faithful", workers=2)
        if self.passes is not None:
            config = replace(config, passes=self.passes)
        elif budget_s is not None:  # the budget is the limit, not the default passes
            config = replace(config, passes=None)
        elif config.passes is None:  # resumed from a run that had a budget, without one
            config = replace(config, passes=PracticeConfig().passes)
        if self.workers is not None:
            config = replace(config, workers=self.workers)
        song = load_song(song_spec, fingering="auto")
        if song.fingering_coverage < 1.0:
            raise CliError(f"{song_spec}: practice needs a finger on every note")
        _prepare_dir(run_dir)

        def report(result: Any) -> None:
            row = result.history[-1]
            plans = row.get("plan_f1")
            tried = ""
            if plans and len(plans) > 1:
                each = ", ".join(f"{name} {f1:.3f}" for name, f1 in plans.items())
                tried = f"; the planner's hand plans: {each}; practising {row['hand_planning']}"
            _out(
                f"pass {row['pass']}: F1 {row['f1']:.3f} (best {result.f1:.3f}), "
                f"{row['seconds']:.0f} s{tried}"
            )

        result = practise_in(
            run_dir, song, song_spec, config, start=start, stop_after_s=budget_s, on_pass=report
        )
        _out(
            f"practised {result.history[-1]['pass']} passes: best F1 {result.f1:.3f} "
            f"(pass {result.pass_index}) -> {run_dir}"
        )


def _song_spec(song: str) -> str:
    """The song as a run records it: a file by its absolute path, so that ``--resume`` finds
    it from any working directory; a built-in song by its name."""
    path = Path(song).expanduser()
    return str(path.resolve()) if path.is_file() else song


def _check_new_run_dir(out: Path) -> None:
    """Refuse to start a run in a folder that holds files already (an earlier run's would be
    overwritten): an existing run is continued with ``--resume``."""
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out} is a file, not a directory")
    if out.is_dir() and any(out.iterdir()):
        raise CliError(
            f"{out} already holds files: continue a run there with --resume {out}, or give "
            "another --out"
        )


@dataclass(frozen=True)
class Eval:
    """Score a trained policy on a song: metrics.json, performance.mid, actions.npy and
    pianoroll.png."""

    run_dir: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="RUN_DIR")]]
    """A training run directory (from `pianist train`)."""
    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file, a PIG file or a score (MusicXML, Humdrum, ABC, MEI)."""
    out: Annotated[
        Path | None, tyro.conf.arg(metavar="PATH", help_behavior_hint="(default: RUN_DIR/eval)")
    ] = None
    """Output directory."""
    seed: int = 0
    """Seed of the episode (environment and policy)."""
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(
            metavar="faithful|fast", help_behavior_hint="(default: the one the run evaluated in)"
        ),
    ] = None
    """Evaluate in this physics preset (the rest of its task unchanged): how a policy
    trained on the fast preset plays on the faithful one. Unless told, the one the run's
    evaluations chose its best policy in (faithful for the fast presets), else the one it
    was trained in."""

    def run(self) -> None:
        from pianist.agents.specs import load_run
        from pianist.media.results import MediaOptions, play_to_folder

        check_seed(self.seed)
        if self.run_dir.exists() and not self.run_dir.is_dir():
            raise CliError(f"{self.run_dir} is a file, not a training run's directory")
        out = self.out or self.run_dir / "eval"
        controller, described = load_run(self.run_dir, physics=self.physics)
        extra: dict[str, Any] = {
            "song": self.song,
            "run": str(self.run_dir),
            "controller": f"policy:{self.run_dir}",  # as `play --controller` would name it
            **described,
        }
        step = (
            "practised"
            if described["preset"] == "practice"
            else f"policy at step {described['checkpoint_step']}"
        )
        result = play_to_folder(
            self.song,
            controller,
            out,
            MediaOptions(audio=False),
            extra_metrics=extra,
            seed=self.seed,
        )
        metrics = result.metrics
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({step}) -> {out}"
        )
