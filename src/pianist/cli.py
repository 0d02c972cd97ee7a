"""The ``pianist`` command: list songs, describe a song, play it and score the performance.

Heavy modules (MuJoCo, Gymnasium) are imported inside the subcommands so ``--help`` is instant.
Every expected failure ends with one readable line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro


class CliError(Exception):
    """A failure the user can fix; printed as one line."""


# The song positional as --help shows it (tyro would show its type, STR).
SongArg = Annotated[str, tyro.conf.arg(metavar="SONG")]


@dataclass(frozen=True)
class Songs:
    """List songs with their size and difficulty: duration, notes, notes/s, span, polyphony."""

    suite: Literal[
        "all", "debug", "robopianist-debug", "open-etude-12", "etude-12", "repertoire-150"
    ] = "all"
    """Which suite: the debug songs, the original's debug songs note for note, the shipped open
    library, or imported PIG pieces."""

    def run(self) -> None:
        from pianist.music import SUITES, PigDatasetError, list_songs, load_song, song_stats

        suites = SUITES if self.suite == "all" else (self.suite,)
        _out(
            f"{'name':40s} {'suite':17s} {'s':>6s} {'notes':>5s} {'n/s':>5s} "
            f"{'span':>4s} {'poly':>4s}"
        )
        flagged = False
        for suite in suites:
            try:
                names = list_songs(suite)
            except PigDatasetError:
                if self.suite == "all":
                    continue  # PIG suites appear once `pianist import-pig` has run
                raise
            for name in names:
                # Known-broken PIG pieces warn on load: a mark in the table, not a warning each.
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    stats = song_stats(load_song(name))
                flagged |= bool(caught)
                span = "-" if stats.max_hand_span is None else str(stats.max_hand_span)
                _out(
                    f"{name:40s} {suite:17s} {stats.duration_s:6.1f} {stats.num_notes:5d} "
                    f"{stats.notes_per_second:5.1f} {span:>4s} {stats.max_polyphony:4d}"
                    + (" !" if caught else "")
                )
        _out(
            "s: duration in seconds; n/s: notes per second; span: widest hand span in "
            "semitones (keys held together in one hand; - without hands); poly: most notes "
            "sounding at once"
            + ("; !: known problems (`pianist info NAME` lists them)" if flagged else "")
        )


@dataclass(frozen=True)
class ImportPig:
    """Convert a copy of the PIG fingering dataset into songs (RoboPianist etude-12 and
    repertoire-150 names then resolve like built-in songs).

    Every command looks the songs up in one folder, where they are written by default:
    PIANIST_PIG if set, else pig/ in PIANIST_DATA, else ~/.local/share/pianist/pig (the XDG
    data folder). After an import with --dest elsewhere, set PIANIST_PIG to that folder (the
    import prints the exact line): a variable, not a hidden record, keeps each lookup explicit.
    """

    src: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="DIR")]]
    """The dataset folder (e.g. PianoFingeringDataset_v1.2, with FingeringFiles/ and List.csv)."""
    dest: Annotated[
        Path | None,
        tyro.conf.arg(help_behavior_hint="(default: where songs are looked up, see above)"),
    ] = None
    """Where to write the songs."""
    strict: bool = True
    """Stop at the first unreadable file (else skip it and report it)."""

    def run(self) -> None:
        from pianist.music import import_pig

        _out(import_pig(self.src, self.dest, strict=self.strict).summary())


@dataclass(frozen=True)
class Info:
    """Describe a song: duration, notes, hands, fingering coverage, goal frames.

    Hands and fingers the file lacks are given as `play` (with its default --fingering auto)
    estimates them, saying where the hands come from: the file's fingering, a MIDI file's
    tracks (named "Right Hand", "LH", "Treble", ... or told apart by register), or estimated.
    """

    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file (.mid) or a PIG fingering file (.txt)."""

    def run(self) -> None:
        from pianist.music import (
            check_playability,
            describe_midi_hands,
            goal_frames,
            load_song,
            pitch_to_name,
            song_stats,
        )

        # Warnings on load (a known-broken PIG piece) are part of the description.
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            song = load_song(self.song)
            # What `play` plays by default: the missing hands and fingers estimated.
            played = song if song.has_full_fingering else load_song(self.song, fingering="auto")
        problems = list(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))
        problems += [p for p in check_playability(played) if not any(p in q for q in problems)]
        stats = song_stats(played)
        frames = goal_frames(song)
        pitches = [n.pitch for n in song.notes]
        hands = ", ".join(sorted(played.hands)) or "-"
        if any(n.hand is None for n in song.notes):
            is_midi = Path(self.song).suffix.lower() in (".mid", ".midi")
            parts = describe_midi_hands(self.song) if is_midi else None
            if parts is not None:
                hands += f" (from the MIDI file, {parts})"
            elif song.hands:
                hands += " (partly estimated: the file names a hand for some notes)"
            else:
                hands += " (estimated: the file names none)"
        fingering = f"{100 * song.fingering_coverage:.0f}% of notes"
        if not song.has_full_fingering and song.notes:
            fingering += " in the file (play estimates the rest: --fingering auto)"
        lines = [
            f"song:       {song.name or self.song}",
            f"duration:   {song.duration_s:.2f} s",
            f"notes:      {song.num_notes}",
        ]
        if pitches:
            lines.append(
                f"range:      {pitch_to_name(min(pitches))} - {pitch_to_name(max(pitches))}"
            )
        lines += [
            f"hands:      {hands}",
            f"fingering:  {fingering}",
            f"sustain:    {len(song.sustain)} pedal intervals",
            f"goal:       {frames.num_frames} frames at {1 / frames.dt:g} Hz, "
            f"max {int(frames.keys.sum(axis=1).max(initial=0))} keys at once",
            f"difficulty: {stats.notes_per_second:.1f} notes/s (peak {stats.peak_notes_per_second}"
            f" in 1 s), polyphony {stats.max_polyphony}, hand span "
            + ("-" if stats.max_hand_span is None else f"{stats.max_hand_span} semitones"),
        ]
        lines += [f"warning:    {problem}" for problem in problems]
        _out("\n".join(lines))


@dataclass(frozen=True)
class Play:
    """Play a song and write its metrics, MIDI, actions, audio, piano roll and (optionally) video.

    Writes to OUT: metrics.json, performance.mid, actions.npy, performance.wav, score.wav,
    pianoroll.png and, with --video, performance.mp4 (the folder appears whole, or not at all).
    """

    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file (.mid) or a PIG fingering file (.txt)."""
    controller: str = "planner"
    """planner; mpc (the paper's predictive sampling; mpc:tenth, or e.g.
    mpc:paper,num_samples=20,sigma=0.1,horizon_s=0.3,num_knots=3,iterations=8); policy:RUN_DIR
    (a trained agent); random; zero; or replay:ACTIONS.npy."""
    fingering: Literal["auto", "file", "robot", "none"] = "auto"
    """auto: keep the song's fingering and estimate what is missing (hands from a MIDI's
    tracks when they say so); file: require the file's own; robot: re-finger every note for
    this robot hand, keeping the song's hands (a human fingering puts the thumb on black keys,
    which the Shadow thumb cannot press); none: no labels (the fingering reward then matches
    fingertips to keys; the planner needs fingers)."""
    out: Path = Path("out")
    """Output directory: created with the results once they are complete, or replaced whole
    if it holds an earlier run's results (a folder holding other files is refused)."""
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(help_behavior_hint="(default: faithful; a trained policy: its own)"),
    ] = None
    """Physics preset: faithful (the paper's simulation) or fast (cheaper contacts)."""
    seed: int = 0
    """Seed of the episode (environment and controller)."""
    initial_buffer_s: float = 0.0
    """Seconds of silence before the song, for the hands to reach the first notes (the
    original's initial_buffer_time; 0, the benchmark's default, scores the cold start).
    metrics.json then also has song_precision/recall/f1, over the song's own steps."""
    video: bool = False
    """Also render performance.mp4 (with the performance's audio)."""
    camera: str = "closeup"
    """Video camera: closeup, left, right, back, egocentric or topdown."""
    fps: float = 30.0
    """Video frames per second."""
    size: tuple[int, int] = (480, 640)
    """Video frame height and width in pixels (even numbers)."""
    soundfont: Annotated[
        Path | None,
        tyro.conf.arg(help_behavior_hint="(default: the General MIDI one pretty_midi ships)"),
    ] = None
    """An .sf2/.sf3 SoundFont for the audio."""
    audio: bool = True
    """Write performance.wav and score.wav."""

    def run(self) -> None:
        if self.video and sys.platform.startswith("linux"):
            # Offscreen rendering without a display; must be set before mujoco is imported.
            os.environ.setdefault("MUJOCO_GL", "egl")
        from pianist.eval.session import make_env, play
        from pianist.media.results import (
            MediaOptions,
            check_media_options,
            check_output_folder,
            write_result,
        )
        from pianist.music import load_song

        # Everything that can be checked before the (long) episode is checked first.
        if not (math.isfinite(self.initial_buffer_s) and self.initial_buffer_s >= 0):
            raise CliError(f"--initial-buffer-s must be >= 0 seconds, not {self.initial_buffer_s}")
        if self.controller.startswith("policy:") and self.initial_buffer_s:
            raise CliError(
                "--initial-buffer-s does not apply to a trained policy, which plays the task it "
                "was trained on"
            )
        song = load_song(self.song, fingering=self.fingering)
        if self.controller == "planner" and song.fingering_coverage < 1.0:
            missing = sum(n.finger is None for n in song.notes)
            raise CliError(
                f"{self.song}: {missing} of {song.num_notes} notes have no fingering; the "
                "planner needs a finger for every note (use --fingering auto)"
            )
        controller = _make_controller(self.controller)
        check_output_folder(self.out)
        media = MediaOptions(
            audio=self.audio,
            video=self.video,
            camera=self.camera,
            fps=self.fps,
            size=self.size,
            soundfont=self.soundfont,
            progress=sys.stderr.isatty(),
        )
        if self.video:  # the cameras are the scene's: build it once to check
            check_media_options(make_env(song, controller, physics=self.physics), media)
        else:
            check_media_options(None, media)
        result = play(
            song,
            controller,
            physics=self.physics,
            fingering=self.fingering,
            initial_buffer_s=self.initial_buffer_s,
            seed=self.seed,
            progress=sys.stderr.isatty(),
        )
        metrics = result.metrics
        title = f"{self.song} ({self.controller}, {metrics['physics']} physics)"
        write_result(
            result,
            self.out,
            media,
            title=title,
            extra_metrics={"song": self.song, "controller": self.controller},
        )
        song_f1 = f"  song F1 {metrics['song_f1']:.3f}" if "song_f1" in metrics else ""
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}{song_f1}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({metrics['steps']} steps, {metrics['realtime_factor']:.1f}x real time) -> {self.out}"
        )


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
    preset: str = "droq-paper"
    """droq-paper, droq-paper-pipelined, sac, redq, fast, fast-small, fast-utd2, residual,
    residual-anchored."""
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

    def run(self) -> None:
        from pianist.agents import PolicyController
        from pianist.eval.session import play
        from pianist.media.results import MediaOptions, check_output_folder, write_result

        controller = PolicyController(self.run_dir)
        out = self.out or self.run_dir / "eval"
        check_output_folder(out)
        result = play(self.song, controller, seed=self.seed)
        metrics = result.metrics
        extra = {
            "song": self.song,
            "run": str(self.run_dir),
            "checkpoint_step": controller.step,
            "preset": controller.config.preset,
        }
        write_result(result, out, MediaOptions(audio=False), extra_metrics=extra)
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"(policy at step {controller.step}) -> {out}"
        )


def _require_jax() -> None:
    import importlib.util

    if importlib.util.find_spec("jax") is None:
        raise CliError("training needs JAX: pip install 'pianist[rl]' (jax, flax, optax)")


def _make_controller(spec: str) -> Any:
    """A controller from the --controller spec: policy:RUN_DIR, or what make_controller takes."""
    if spec.startswith("policy:"):
        from pianist.agents import PolicyController

        return PolicyController(spec.removeprefix("policy:"))
    from pianist.control import make_controller

    return make_controller(spec)


def _prepare_dir(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"cannot create output directory {path}: {exc.strerror}") from None
    probe = path / ".pianist-write-test"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise CliError(f"output directory {path} is not writable: {exc.strerror}") from None


def _out(text: str) -> None:
    sys.stdout.write(text + "\n")


Command = (
    Annotated[Songs, tyro.conf.subcommand("songs")]
    | Annotated[Info, tyro.conf.subcommand("info")]
    | Annotated[Play, tyro.conf.subcommand("play")]
    | Annotated[ImportPig, tyro.conf.subcommand("import-pig")]
    | Annotated[Train, tyro.conf.subcommand("train")]
    | Annotated[Eval, tyro.conf.subcommand("eval")]
)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pianist`` console script; returns the exit status."""
    command = tyro.cli(Command, args=argv, prog="pianist", description=__doc__.splitlines()[0])
    try:
        with warnings.catch_warnings():  # restores the library's warning display afterwards
            warnings.showwarning = _show_warning
            command.run()
    except KeyboardInterrupt:
        sys.stderr.write("pianist: interrupted\n")
        return 130
    except Exception as exc:  # noqa: BLE001 - turned into one line below, or re-raised
        message = _expected_error(exc)
        if message is None:
            raise
        sys.stderr.write(f"pianist: error: {message}\n")
        return 1
    return 0


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: Any = None,
    line: str | None = None,
) -> None:
    """Show a warning raised during a command as one line (no file path or source line): the
    warnings are about the user's input (e.g. a known-broken PIG piece), not about code."""
    sys.stderr.write(f"pianist: warning: {' '.join(str(message).split())}\n")


def _expected_error(exc: Exception) -> str | None:
    """One line for failures caused by input or environment, None for bugs."""
    from pianist.env import SimulationUnstableError
    from pianist.media import MediaError
    from pianist.music import MusicError

    expected = CliError | MusicError | MediaError | SimulationUnstableError | FileNotFoundError
    if isinstance(exc, expected):
        return " ".join(str(exc).split())
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc)
    if isinstance(exc, ValueError):
        return " ".join(str(exc).split())
    return None


if __name__ == "__main__":
    raise SystemExit(main())
