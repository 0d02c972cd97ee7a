"""The ``pianist`` command: list songs, describe a song, play it and score the performance.

Heavy modules (MuJoCo, Gymnasium) are imported inside the subcommands so ``--help`` is instant.
Every expected failure ends with one readable line on stderr and a non-zero exit status.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import tyro


class CliError(Exception):
    """A failure the user can fix; printed as one line."""


@dataclass(frozen=True)
class Songs:
    """List the built-in songs."""

    def run(self) -> None:
        from pianist.music import get_song, list_songs, song_description

        for name in list_songs():
            song = get_song(name)
            _out(
                f"{name:22s} {song.duration_s:5.1f} s {song.num_notes:4d} notes  "
                f"{song_description(name)}"
            )


@dataclass(frozen=True)
class Info:
    """Describe a song: duration, notes, hands, fingering coverage, goal frames."""

    song: tyro.conf.Positional[str]
    """A built-in song name, a MIDI file (.mid) or a PIG fingering file (.txt)."""

    def run(self) -> None:
        from pianist.music import goal_frames, load_song, pitch_to_name

        song = load_song(self.song)
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
        ]
        _out("\n".join(lines))


@dataclass(frozen=True)
class Play:
    """Play a song with a controller and write metrics.json, performance.mid and actions.npy."""

    song: tyro.conf.Positional[str]
    """A built-in song name, a MIDI file (.mid) or a PIG fingering file (.txt)."""
    controller: str = "random"
    """random, zero, or replay:ACTIONS.npy."""
    out: Path = Path("out")
    """Output directory (created if missing)."""
    physics: Literal["faithful", "fast"] = "faithful"
    """Physics preset."""
    seed: int = 0

    def run(self) -> None:
        from pianist.control import make_controller
        from pianist.env import PianoEnv
        from pianist.eval import run_episode
        from pianist.eval.episode import save_npy_atomic, write_json_atomic
        from pianist.music import write_midi

        controller = make_controller(self.controller)
        _prepare_dir(self.out)
        env = PianoEnv(self.song, physics=self.physics)
        start = time.perf_counter()
        episode = run_episode(env, controller, seed=self.seed)
        wall = time.perf_counter() - start
        metrics = episode.metrics()
        metrics.update(
            song=self.song,
            controller=self.controller,
            physics=self.physics,
            seed=self.seed,
            wall_seconds=wall,
            realtime_factor=metrics["seconds"] / wall if wall > 0 else float("inf"),
        )
        save_npy_atomic(episode.actions, self.out / "actions.npy")
        write_midi(episode.performance(), self.out / "performance.mid")
        write_json_atomic(metrics, self.out / "metrics.json")
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({metrics['steps']} steps, {metrics['realtime_factor']:.1f}x real time) -> {self.out}"
        )


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
    from pianist.music import MusicError

    if isinstance(exc, CliError | MusicError | SimulationUnstableError | FileNotFoundError):
        return " ".join(str(exc).split())
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc)
    if isinstance(exc, ValueError):
        return " ".join(str(exc).split())
    return None


if __name__ == "__main__":
    raise SystemExit(main())
