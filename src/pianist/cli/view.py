"""``pianist view``: watch a controller play a song in MuJoCo's interactive viewer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal

import tyro

from pianist.cli.common import CliError, SongArg, check_seed
from pianist.cli.common import out as _out
from pianist.control.registry import build_controller


@dataclass(frozen=True)
class View:
    """Watch a song being played, in real time, in MuJoCo's viewer window: keys green when
    played and due, red when played and not due, amber when due and silent. Closing the window
    stops the song. Needs a display (on a machine without one: xvfb-run -a pianist view ...)."""

    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file (.mid), a PIG fingering file (.txt) or a score
    (MusicXML .musicxml, .mxl, .xml; Humdrum .krn; ABC .abc; MEI .mei: hands from its
    staves, its finger numbers; needs music21)."""
    controller: str = "planner"
    """Any controller `pianist play` takes, as KIND[:OPTION=VALUE,...] (`pianist play --help`
    lists every kind with its options)."""
    fingering: Literal["auto", "file", "robot", "none"] = "auto"
    """How the song is fingered (as for `pianist play`)."""
    out_of_range: Literal["error", "drop"] = "error"
    """A file's notes outside the piano's 88 keys: refuse the file, or leave them out."""
    as_written: bool = False
    """Read a score as written (as for `pianist play`)."""
    physics: Annotated[
        Literal["faithful", "fast"] | None,
        tyro.conf.arg(
            metavar="faithful|fast",
            help_behavior_hint=(
                "(default: faithful; a trained policy: the one its run evaluated in)"
            ),
        ),
    ] = None
    """Physics preset: faithful (the paper's simulation) or fast (cheaper contacts)."""
    seed: int = 0
    """Seed of the episode (environment and controller)."""
    start: float = 0.0
    """Play an excerpt from this many seconds into the song, from a silent start."""
    seconds: Annotated[
        float | None,
        tyro.conf.arg(metavar="FLOAT", help_behavior_hint="(default: to the song's end)"),
    ] = None
    """Play only SECONDS of the song (from --start)."""
    realtime: bool = True
    """Pace the episode to the wall clock (--no-realtime: as fast as it plays)."""

    def run(self) -> None:
        from pianist.media.viewer import check_display

        check_display()  # before anything slow: the one thing a headless machine lacks
        check_seed(self.seed)
        if self.seconds is not None and not (math.isfinite(self.seconds) and self.seconds > 0):
            raise CliError(f"--seconds must be > 0, not {self.seconds}")
        if not (math.isfinite(self.start) and self.start >= 0):
            raise CliError(f"--start must be >= 0 seconds, not {self.start}")
        from pianist.media.viewer import view
        from pianist.music import load_song

        song = load_song(
            self.song,
            out_of_range=self.out_of_range,
            fingering=self.fingering,
            as_written=self.as_written,
        )
        controller = build_controller(self.controller)
        result, stats = view(
            song,
            controller,
            realtime=self.realtime,
            physics=self.physics,
            fingering=self.fingering,
            seed=self.seed,
            start_s=self.start,
            seconds=self.seconds,
        )
        metrics = result.metrics
        stopped = "  window closed: scored up to there" if stats.closed else ""
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({metrics['steps']} steps, {stats.frames} viewer frames, {metrics['seconds']:.2f} s "
            f"of music in {stats.wall_s:.2f} s){stopped}"
        )
