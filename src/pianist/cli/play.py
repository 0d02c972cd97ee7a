"""``pianist play``: play a song with a controller and write its results."""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import tyro

from pianist.cli.common import CliError, SongArg, check_seed
from pianist.cli.common import out as _out
from pianist.control.registry import ControllerSpec, controller_help, parse_controller
from pianist.control.specs import PUSH_BELOW_VELOCITY

#: The help of --controller: every kind with its options, from the registry.
CONTROLLER_HELP = (
    "The controller, as KIND or KIND:OPTION=VALUE,... (a bare first item: a preset or, for "
    "search, the controller searched over; KIND:PATH for a folder or file):\n" + controller_help()
)


@dataclass(frozen=True)
class Play:
    """Play a song and write its metrics, MIDI, actions, audio, piano roll and (optionally) video.

    Writes to OUT: metrics.json, performance.mid, actions.npy, performance.wav, score.wav,
    comparison.wav, pianoroll.png and, with --video, performance.mp4 (the folder appears whole,
    or not at all).
    """

    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file (.mid), a PIG fingering file (.txt) or a score
    (MusicXML .musicxml, .mxl, .xml; Humdrum .krn; ABC .abc; MEI .mei: hands from its
    staves, its finger numbers; needs music21)."""
    controller: Annotated[
        str, tyro.conf.arg(help=CONTROLLER_HELP, metavar="KIND[:OPTION=VALUE,...]")
    ] = "planner"
    refine: bool = False
    """Refine the planner's actions by looking ahead with the physics (the same as
    --controller refine; with --controller search, the search runs over the refiner)."""
    fingering: Literal["auto", "file", "robot", "none"] = "auto"
    """auto: keep the song's fingering and estimate what is missing (hands from a MIDI's
    tracks when they say so); file: require the file's own; robot: re-finger every note for
    this robot hand, keeping the song's hands (a human fingering puts the thumb on black keys,
    which the Shadow thumb cannot press); none: nothing estimated and the labels left out of
    the reward, which then matches fingertips to keys (the planner still plays a song's own
    fingers, and refuses a song without them)."""
    out_of_range: Literal["error", "drop"] = "error"
    """A file's notes outside the piano's 88 keys: refuse the file (error) or leave them out
    (drop)."""
    as_written: bool = False
    """Read a score (MusicXML, Humdrum, ABC, MEI) as written: once through, with no ornaments,
    fermatas or articulations played (other song files are read as always)."""
    out: Path = Path("out")
    """Output directory: created with the results once they are complete, or replaced whole
    if it holds an earlier run's results (a folder holding other files is refused)."""
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
    """Play an excerpt from this many seconds into the song, from a silent start (the hands
    at rest; notes already sounding there are struck again)."""
    seconds: Annotated[
        float | None,
        tyro.conf.arg(metavar="FLOAT", help_behavior_hint="(default: to the song's end)"),
    ] = None
    """Play an excerpt this many seconds long (from --start)."""
    initial_buffer_s: float = 0.0
    """Seconds of silence before the song, for the hands to reach the first notes (the
    original's initial_buffer_time; 0, the benchmark's default, scores the cold start).
    metrics.json then also has song_precision/recall/f1, over the song's own steps."""
    video: bool = False
    """Also render performance.mp4 (with the performance's audio)."""
    camera: str = "auto"
    """Video camera: auto (both hands and the keys played, from above the player's seat,
    framed on the piece), front (the whole keyboard), closeup, left, right, back, egocentric or
    topdown."""
    falling_notes: bool = False
    """Draw a falling-notes strip (the goal notes approaching a hit line) under the video."""
    antialias: bool = True
    """Smooth the video's edges (--no-antialias: the video renders ~2.5x as fast on a CPU,
    with jagged edges)."""
    fps: float = 30.0
    """Video frames per second."""
    size: tuple[int, int] = (480, 640)
    """Video frame height and width in pixels (even numbers)."""
    soundfont: Annotated[
        Path | None,
        tyro.conf.arg(
            metavar="PATH", help_behavior_hint="(default: the General MIDI one pretty_midi ships)"
        ),
    ] = None
    """An .sf2/.sf3 SoundFont for the audio."""
    audio: bool = True
    """Write performance.wav and score.wav."""
    report: bool = False
    """Also write report.html: a page with the metrics, piano roll, audio and video players,
    the missed and wrong notes and the song's provenance (see `pianist report`)."""

    def run(self) -> None:
        if self.video and sys.platform.startswith("linux"):
            # Offscreen rendering without a display; must be set before mujoco is imported.
            os.environ.setdefault("MUJOCO_GL", "egl")
        from pianist.control.specs import refined
        from pianist.eval.rollout import realtime_text
        from pianist.media.results import MediaOptions, play_to_folder, played_dynamics
        from pianist.music import load_song

        # Everything that can be checked before the (long) episode is checked first.
        check_seed(self.seed)
        if not (math.isfinite(self.initial_buffer_s) and self.initial_buffer_s >= 0):
            raise CliError(f"--initial-buffer-s must be >= 0 seconds, not {self.initial_buffer_s}")
        spec = parse_controller(self.controller)
        if spec.kind == "policy" and self.initial_buffer_s:
            raise CliError(
                "--initial-buffer-s does not apply to a trained policy, which plays the task it "
                "was trained on"
            )
        if self.refine:
            spec = refined(spec)
        song = load_song(
            self.song,
            out_of_range=self.out_of_range,
            fingering=self.fingering,
            as_written=self.as_written,
        )
        if spec.needs_fingering and song.fingering_coverage < 1.0:
            missing = sum(n.finger is None for n in song.notes)
            raise CliError(
                f"{self.song}: {missing} of {song.num_notes} notes have no fingering; the "
                f"{spec.kind} controller needs a finger for every note (use --fingering auto)"
            )
        media = MediaOptions(
            audio=self.audio,
            video=self.video,
            camera=self.camera,
            falling_notes=self.falling_notes,
            antialias=self.antialias,
            fps=self.fps,
            size=self.size,
            soundfont=self.soundfont,
            progress=sys.stderr.isatty(),
            report=self.report,
        )
        result = play_to_folder(
            song,
            spec.build(),
            self.out,
            media,
            title=f"{self.song} ({spec}, " + "{physics} physics)",
            extra_metrics={
                "song": self.song,
                "controller": str(spec),
                "as_written": self.as_written,
            },
            physics=self.physics,
            fingering=self.fingering,
            initial_buffer_s=self.initial_buffer_s,
            seed=self.seed,
            progress=sys.stderr.isatty(),
            start_s=self.start,
            seconds=self.seconds,
        )
        metrics = result.metrics
        song_f1 = f"  song F1 {metrics['song_f1']:.3f}" if "song_f1" in metrics else ""
        ceiling, planned = metrics.get("reach_ceiling_f1"), metrics.get("plan_f1")
        ceiling_f1 = f" (at most {ceiling:.3f} with these hands)" if ceiling is not None else ""
        if ceiling is not None and planned is not None:
            ceiling_f1 = f" (plan {planned:.3f}, at most {ceiling:.3f} with these hands)"
        _out(
            f"{self.song}: precision {metrics['precision']:.3f}  recall {metrics['recall']:.3f}  "
            f"F1 {metrics['f1']:.3f}{ceiling_f1}{song_f1}  sustain F1 {metrics['sustain_f1']:.3f}  "
            f"({metrics['steps']} steps, {realtime_text(metrics['realtime_factor'])} real time) "
            f"-> {self.out}"
        )
        _out(_errors_line(metrics))
        _out(_f1_lost_line(metrics))
        dynamics = _dynamics_line(played_dynamics(result)[3], spec)
        if dynamics:
            _out(dynamics)


def _dynamics_line(metrics: dict, spec: ControllerSpec) -> str:
    """One line of how far the loudness is from the score's (``metrics``: the loudness
    metrics, :func:`pianist.media.results.played_dynamics`), for a score whose notes'
    velocities differ (none for one velocity throughout), with the option that plays them
    where the planner, the refiner or the search was run without it."""
    rho = metrics.get("velocity_rank_correlation")
    if rho is None or not math.isfinite(rho):
        return ""
    line = (
        f"  dynamics: velocity error {metrics['velocity_mae']:.1f} (MIDI units), rank "
        f"correlation {rho:.2f} over {metrics['velocity_matched_notes']} notes"
    )
    if getattr(spec, "push_below_velocity", None) == 0:
        line += (
            f" (push_below_velocity=0 strikes every note at full speed; the default, "
            f"{PUSH_BELOW_VELOCITY}, plays the soft notes softly)"
        )
    return line


def _errors_line(metrics: dict) -> str:
    """One line of the errors by kind (:func:`pianist.eval.note_errors`), in % of the due
    key-frames: what the missed ones missed, and what the false ones were."""

    def pct(name: str) -> str:
        return f"{100 * metrics[name]:.1f} %"

    return (
        f"  of the due key-frames, missed: {pct('lost_never_share')} in notes never sounding, "
        f"{pct('lost_late_share')} before a late note sounded, "
        f"{pct('lost_dropout_share')} after a note sounded; false: "
        f"{pct('false_held_share')} held on, {pct('false_early_share')} early, "
        f"{pct('false_other_share')} other keys "
        f"({100 * metrics['notes_late_share']:.0f} % of the {metrics['notes']:.0f} notes late)"
    )


def _f1_lost_line(metrics: dict) -> str:
    """One line of the F1 each class of error costs, were it alone put right
    (:func:`pianist.eval.f1_lost`); the plan's classes, where the controller has a plan,
    overlap the others (a key left out is a note never sounding)."""
    kinds = (
        ("never", "notes never sounding"),
        ("late", "late notes"),
        ("dropout", "drop-outs"),
        ("false", "false keys"),
    )
    plan = (("plan_left_out", "keys it left out"), ("plan_in_shift", "keys let go for shifts"))

    def part(name: str, label: str) -> str:
        return f"{label} {metrics[f'f1_lost_{name}']:.3f}"

    line = "  F1 lost to " + ", ".join(
        part(n, label) for n, label in kinds if f"f1_lost_{n}" in metrics
    )
    of_plan = [part(n, label) for n, label in plan if f"f1_lost_{n}" in metrics]
    return line + (f"; of the plan's: {', '.join(of_plan)}" if of_plan else "")
