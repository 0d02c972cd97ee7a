"""The ``pianist`` command: list songs, describe a song, play it and score the performance.

Heavy modules (MuJoCo, Gymnasium) are imported inside the subcommands so ``--help`` is instant.
Every expected failure ends with one readable line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import tyro


class CliError(Exception):
    """A failure the user can fix; printed as one line."""


@dataclass(frozen=True)
class Songs:
    """List songs with their size and difficulty: duration, notes, notes/s, span, polyphony."""

    suite: Literal[
        "all", "debug", "robopianist-debug", "open-etude-12", "etude-12", "repertoire-150"
    ] = "all"
    """Which suite: the debug songs, the original's debug songs note for note, the shipped open
    library, or imported PIG pieces."""

    def run(self) -> None:
        import warnings

        from pianist.music import SUITES, PigDatasetError, list_songs, load_song, song_stats

        suites = SUITES if self.suite == "all" else (self.suite,)
        _out(
            f"{'name':40s} {'suite':17s} {'s':>6s} {'notes':>5s} {'n/s':>5s} "
            f"{'span':>4s} {'poly':>4s}"
        )
        for suite in suites:
            try:
                names = list_songs(suite)
            except PigDatasetError:
                if self.suite == "all":
                    continue  # PIG suites appear once `pianist import-pig` has run
                raise
            for name in names:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # known-broken PIG pieces warn on load
                    stats = song_stats(load_song(name))
                span = "-" if stats.max_hand_span is None else str(stats.max_hand_span)
                _out(
                    f"{name:40s} {suite:17s} {stats.duration_s:6.1f} {stats.num_notes:5d} "
                    f"{stats.notes_per_second:5.1f} {span:>4s} {stats.max_polyphony:4d}"
                )


@dataclass(frozen=True)
class ImportPig:
    """Convert a copy of the PIG fingering dataset into songs (RoboPianist etude-12 and
    repertoire-150 names then resolve like built-in songs)."""

    src: tyro.conf.Positional[Path]
    """The dataset folder (e.g. PianoFingeringDataset_v1.2, with FingeringFiles/ and List.csv)."""
    dest: Path | None = None
    """Where to write the songs (default: $PIANIST_DATA, else the XDG data folder)."""
    strict: bool = True
    """Stop at the first unreadable file (else skip it and report it)."""

    def run(self) -> None:
        from pianist.music import import_pig

        _out(import_pig(self.src, self.dest, strict=self.strict).summary())


@dataclass(frozen=True)
class Info:
    """Describe a song: duration, notes, hands, fingering coverage, goal frames."""

    song: tyro.conf.Positional[str]
    """A built-in song name, a MIDI file (.mid) or a PIG fingering file (.txt)."""

    def run(self) -> None:
        from pianist.music import (
            check_playability,
            goal_frames,
            load_song,
            pitch_to_name,
            song_stats,
        )

        song = load_song(self.song)
        stats = song_stats(song)
        frames = goal_frames(song)
        pitches = [n.pitch for n in song.notes]
        hands = ", ".join(sorted(song.hands)) or "unknown (no fingering)"
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
            f"fingering:  {100 * song.fingering_coverage:.0f}% of notes",
            f"sustain:    {len(song.sustain)} pedal intervals",
            f"goal:       {frames.num_frames} frames at {1 / frames.dt:g} Hz, "
            f"max {int(frames.keys.sum(axis=1).max(initial=0))} keys at once",
            f"difficulty: {stats.notes_per_second:.1f} notes/s (peak {stats.peak_notes_per_second}"
            f" in 1 s), polyphony {stats.max_polyphony}, hand span "
            + ("-" if stats.max_hand_span is None else f"{stats.max_hand_span} semitones"),
        ]
        lines += [f"warning:    {problem}" for problem in check_playability(song)]
        _out("\n".join(lines))


@dataclass(frozen=True)
class Play:
    """Play a song and write its metrics, MIDI, actions, audio, piano roll and (optionally) video.

    Writes to OUT: metrics.json, performance.mid, actions.npy, performance.wav, score.wav,
    pianoroll.png and, with --video, performance.mp4 (every file written atomically).
    """

    song: tyro.conf.Positional[str]
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
    """Output directory (created if missing)."""
    physics: Literal["faithful", "fast"] = "faithful"
    """Physics preset."""
    seed: int = 0
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
    soundfont: Path | None = None
    """An .sf2/.sf3 SoundFont for the audio (default: the General MIDI one pretty_midi ships)."""
    audio: bool = True
    """Write performance.wav and score.wav."""

    def run(self) -> None:
        if self.video and sys.platform.startswith("linux"):
            # Offscreen rendering without a display; must be set before mujoco is imported.
            os.environ.setdefault("MUJOCO_GL", "egl")
        from pianist.control import make_controller
        from pianist.env import PianoEnv
        from pianist.eval import run_episode
        from pianist.files import save_npy_atomic, write_json_atomic
        from pianist.music import load_song, write_midi

        # Everything that can be checked before the (long) episode is checked first.
        song = load_song(self.song, fingering=self.fingering)
        if self.controller == "planner" and song.fingering_coverage < 1.0:
            missing = sum(n.finger is None for n in song.notes)
            raise CliError(
                f"{self.song}: {missing} of {song.num_notes} notes have no fingering; the "
                "planner needs a finger for every note (use --fingering auto)"
            )
        if not (math.isfinite(self.initial_buffer_s) and self.initial_buffer_s >= 0):
            raise CliError(f"--initial-buffer-s must be >= 0 seconds, not {self.initial_buffer_s}")
        policy = self.controller.startswith("policy:")
        if policy and self.initial_buffer_s:
            raise CliError(
                "--initial-buffer-s does not apply to a trained policy, which plays the task it "
                "was trained on"
            )
        if policy:
            from pianist.agents import PolicyController

            controller = PolicyController(self.controller.removeprefix("policy:"))
        else:
            controller = make_controller(self.controller)
        if self.audio:
            from pianist.media import check_soundfont

            check_soundfont(self.soundfont)
        _prepare_dir(self.out)
        if policy:  # the task the policy was trained on (its physics, hands, lookahead)
            env_options = controller.env_options(song)
            env = controller.make_env(song)
        else:
            env_options = _env_options_for(self.controller)
            if self.fingering == "none":
                env_options["fingering_reward"] = "optimal"
            if self.initial_buffer_s:
                env_options["initial_buffer_s"] = self.initial_buffer_s
            env = PianoEnv(song, physics=self.physics, **env_options)
        if self.video:
            from pianist.media import check_video_options

            check_video_options(env.model, self.camera, self.fps, self.size)

        start = time.perf_counter()
        episode = run_episode(env, controller, seed=self.seed, progress=sys.stderr.isatty())
        wall = time.perf_counter() - start
        metrics = episode.metrics()
        if hasattr(controller, "stats"):  # planning controllers report their own timing
            metrics.update(controller.stats())
            metrics["controller_options"] = controller.options_dict()
        if hasattr(controller, "close"):
            controller.close()
        metrics.update(
            song=self.song,
            controller=self.controller,
            fingering=self.fingering,
            physics=self.physics,
            seed=self.seed,
            env_options={k: list(v) if isinstance(v, tuple) else v for k, v in env_options.items()},
            wall_seconds=wall,
            realtime_factor=metrics["seconds"] / wall if wall > 0 else float("inf"),
        )
        save_npy_atomic(episode.actions, self.out / "actions.npy")
        write_midi(episode.performance(), self.out / "performance.mid")
        self._write_media(env, song, episode)
        write_json_atomic(metrics, self.out / "metrics.json")
        song_f1 = f"  song F1 {metrics['song_f1']:.3f}" if "song_f1" in metrics else ""
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}{song_f1}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({metrics['steps']} steps, {metrics['realtime_factor']:.1f}x real time) -> {self.out}"
        )

    def _write_media(self, env: Any, song: Any, episode: Any) -> None:
        from pianist.media import (
            plot_pianoroll,
            render_episode,
            synthesize_events,
            synthesize_song,
            write_wav,
        )
        from pianist.music.transforms import delay

        plot_pianoroll(
            episode,
            self.out / "pianoroll.png",
            title=f"{self.song} ({self.controller}, {self.physics} physics)",
            weights=env.config.rewards.as_dict(),
        )
        performance = None
        if self.audio:
            duration = episode.num_steps * episode.control_timestep_s
            performance = synthesize_events(episode.note_events, duration, soundfont=self.soundfont)
            write_wav(performance, self.out / "performance.wav")
            # The score starts where the performance's song does: after the lead-in.
            score = delay(song, env.config.lead_in_steps * env.config.control_timestep_s)
            write_wav(synthesize_song(score, soundfont=self.soundfont), self.out / "score.wav")
        if self.video:
            render_episode(
                env,
                episode,
                self.out / "performance.mp4",
                camera=self.camera,
                fps=self.fps,
                size=self.size,
                audio=performance,
                progress=sys.stderr.isatty(),
            )


@dataclass(frozen=True)
class Train:
    """Train an agent on a song (SAC/DroQ in JAX): log, checkpoints and config go to --out."""

    song: tyro.conf.Positional[str | None] = None
    """A built-in song name, a MIDI file or a PIG file (omit with --resume)."""
    preset: str = "droq-paper"
    """droq-paper, droq-paper-pipelined, sac, redq, fast, fast-small, fast-utd2, residual,
    residual-anchored."""
    steps: int | None = None
    """Total environment steps (default 1M; when resuming, the run's own total)."""
    out: Path = Path("runs/train")
    """Run directory (created if missing)."""
    resume: Path | None = None
    """Continue the run in this directory from its newest checkpoint."""
    progress: bool = True
    """Show a progress bar with steps/s and the latest F1."""

    def run(self) -> None:
        from pianist.agents import PRESETS, train
        from pianist.agents.rundir import read_run_config

        _require_jax()
        if self.resume is not None:
            steps = self.steps or int(read_run_config(self.resume)["steps"])
            result = train(
                None, None, steps, self.resume, resume=True, progress=self.progress, message=_out
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
                self.steps or 1_000_000,
                self.out,
                progress=self.progress,
                message=_out,
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
    """Score a trained policy on a song: metrics.json, performance.mid and actions.npy."""

    run_dir: tyro.conf.Positional[Path]
    """A training run directory (from `pianist train`)."""
    song: tyro.conf.Positional[str]
    """A built-in song name, a MIDI file or a PIG file."""
    out: Path | None = None
    """Output directory (default RUN_DIR/eval)."""
    seed: int = 0

    def run(self) -> None:
        from pianist.agents import PolicyController
        from pianist.eval import run_episode
        from pianist.files import save_npy_atomic, write_json_atomic
        from pianist.music import write_midi

        controller = PolicyController(self.run_dir)
        env = controller.make_env(self.song)
        out = self.out or self.run_dir / "eval"
        _prepare_dir(out)
        episode = run_episode(env, controller, seed=self.seed)
        metrics = episode.metrics()
        metrics.update(
            song=self.song,
            run=str(self.run_dir),
            checkpoint_step=controller.step,
            preset=controller.config.preset,
            seed=self.seed,
        )
        save_npy_atomic(episode.actions, out / "actions.npy")
        write_midi(episode.performance(), out / "performance.mid")
        write_json_atomic(metrics, out / "metrics.json")
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"(policy at step {controller.step}) -> {out}"
        )


def _require_jax() -> None:
    import importlib.util

    if importlib.util.find_spec("jax") is None:
        raise CliError("training needs JAX: pip install 'pianist[rl]' (jax, flax, optax)")


def _env_options_for(controller: str) -> dict[str, Any]:
    """Environment options a controller needs beyond the benchmark's defaults."""
    if controller == "planner":
        from pianist.control.planner import planner_env_options

        return planner_env_options()
    return {}


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
