"""Writing a played episode's files: the one writer the CLI and scripts share.

:func:`write_result` writes a :class:`pianist.eval.session.PlayResult` into a folder: the
metrics, the performance as MIDI (velocities from the keys' strike speeds, see
:mod:`pianist.media.dynamics`), the actions, the piano roll and, on request, the audio of the
performance, of the score and of both side by side (comparison.wav) and a video. The files
are written into a temporary folder that replaces ``out`` whole once every file is complete, so
an interrupted or failed write never leaves a mix of two runs (or half a run) in ``out``.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pianist.eval.session import PlayResult, play
from pianist.files import (
    atomic_dir,
    check_replaceable_dir,
    save_npy_atomic,
    write_json_atomic,
)
from pianist.media.errors import MediaError
from pianist.media.report import KEY_RECORD, REPORT, VELOCITIES
from pianist.music import write_midi
from pianist.music.transforms import delay

if TYPE_CHECKING:
    from pianist.eval.session import Controller
    from pianist.music import Note, Song
    from pianist.sim.scene import Scene

METRICS = "metrics.json"
PERFORMANCE_MIDI = "performance.mid"
ACTIONS = "actions.npy"
PIANOROLL = "pianoroll.png"
PERFORMANCE_WAV = "performance.wav"
SCORE_WAV = "score.wav"
COMPARISON_WAV = "comparison.wav"
VIDEO = "performance.mp4"
#: Every file a result folder may hold: a folder holding anything else is not replaced.
RESULT_FILES = frozenset(
    {
        METRICS,
        PERFORMANCE_MIDI,
        ACTIONS,
        PIANOROLL,
        PERFORMANCE_WAV,
        SCORE_WAV,
        COMPARISON_WAV,
        VIDEO,
        KEY_RECORD,
        REPORT,
        VELOCITIES,
    }
)


@dataclass(frozen=True)
class MediaOptions:
    """What to write beside the metrics, MIDI, actions and piano roll."""

    audio: bool = True
    """performance.wav, score.wav and comparison.wav (score left, performance right), each
    normalised to the same loudness (:func:`pianist.media.audio.normalise_loudness`)."""
    video: bool = False
    """performance.mp4 (with the performance's audio when ``audio``)."""
    camera: str = "auto"
    """``auto`` (both hands and the keys played, framed on the episode) or a scene camera."""
    falling_notes: bool = False
    """Draw the falling-notes strip under the video's picture."""
    antialias: bool = True
    """Smooth the video's edges (off: its picture renders ~2.5x as fast, edges jagged)."""
    fps: float = 30.0
    size: tuple[int, int] = (480, 640)
    """Video frame (height, width) in pixels."""
    soundfont: Path | None = None
    """An .sf2/.sf3 SoundFont (default: the General MIDI one pretty_midi ships)."""
    progress: bool = False
    """Show the video's progress bar on stderr."""
    report: bool = False
    """report.html, the page of :mod:`pianist.media.report` (the key record keys.npz it reads
    is written always)."""


def check_output_folder(out: str | os.PathLike[str]) -> None:
    """Refuse a result folder that cannot be written, before a long episode.

    ``out`` may be missing (it is created at the end, with its parents), a result folder of an
    earlier run (replaced whole) or empty; a folder holding other files is refused, so that
    replacing it cannot delete them.

    Raises:
        MediaError: one line naming the problem.
    """
    out = Path(out)
    check_replaceable_dir(out, RESULT_FILES, error=lambda m: MediaError(f"output directory {m}"))
    ancestor = out if out.is_dir() else out.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise MediaError(f"output directory {out} cannot be created: {ancestor} is a file")
    parent = out.parent if out.is_dir() else ancestor
    if not os.access(parent, os.W_OK | os.X_OK):
        raise MediaError(f"output directory {out} is not writable ({parent} is read-only)")
    # Permissions do not tell everything (root may write anywhere, but not into /proc or a
    # read-only mount): the results are written to a temporary folder there, so make one.
    try:
        tempfile.TemporaryDirectory(dir=parent, prefix=".pianist-check-").cleanup()
    except OSError as exc:
        raise MediaError(
            f"output directory {out} cannot be written in {parent} ({exc.strerror or exc})"
        ) from None


def check_media_options(scene: Scene | None, media: MediaOptions) -> None:
    """Refuse bad media options before a long episode (one-line :class:`MediaError`).

    ``scene``: the scene the episode will be played in (for its cameras; None: the video's
    options are not checked).
    """
    if media.audio or media.video:
        from pianist.media.audio import check_soundfont

        check_soundfont(media.soundfont)
    if media.video and scene is not None:
        from pianist.media.video import check_video_options

        check_video_options(scene.model, media.camera, media.fps, media.size, media.falling_notes)


def play_to_folder(
    song: Song | str | Path,
    controller: Controller,
    out: str | os.PathLike[str],
    media: MediaOptions | None = None,
    *,
    title: str | None = None,
    extra_metrics: dict[str, Any] | None = None,
    **play_options: Any,
) -> PlayResult:
    """Play ``song`` with ``controller`` and write the result's files into ``out``: the
    folder and the media options are checked before the episode (the video's against the
    scene, which is built once), and nothing is written unless the episode completes.

    Args:
        song, controller: as :func:`pianist.eval.session.play` takes them.
        out, media, extra_metrics: as :func:`write_result` takes them.
        title: the piano roll's title; ``{physics}`` in it is replaced by the physics preset
            played in (the controller's own when none is given).
        play_options: the other keywords of :func:`pianist.eval.session.play` (physics,
            fingering, initial_buffer_s, seed, env_options, progress).
    Raises:
        MediaError: the folder or a medium cannot be written; and what ``play`` raises.
    """
    media = media or MediaOptions()
    check_output_folder(Path(out))
    check_media_options(None, media)
    result = play(
        song,
        controller,
        check_scene=lambda scene: check_media_options(scene, media),
        **play_options,
    )
    if title is not None:
        title = title.replace("{physics}", str(result.metrics["physics"]))
    write_result(result, out, media, title=title, extra_metrics=extra_metrics)
    return result


def write_result(
    result: PlayResult,
    out: str | os.PathLike[str],
    media: MediaOptions | None = None,
    *,
    title: str | None = None,
    extra_metrics: dict[str, Any] | None = None,
) -> list[Path]:
    """Write ``result``'s files into the folder ``out`` (replaced whole, see module docstring).

    Args:
        result: what :func:`pianist.eval.session.play` returned.
        out: the folder; created with its parents if missing.
        media: which media to write (default: audio, no video).
        title: the piano roll's title.
        extra_metrics: more entries for metrics.json (e.g. the command's own arguments).
    Returns:
        The paths written, in ``out``.
    Raises:
        MediaError: the folder cannot be written, or a medium fails.
    """
    from pianist.media.plots import plot_velocities
    from pianist.media.report import key_record, write_key_record, write_report

    media = media or MediaOptions()
    out = Path(out)
    check_output_folder(out)
    episode = result.episode
    metrics = dict(result.metrics)
    performance, velocities, matched, loudness = played_dynamics(result)
    metrics.update(loudness)
    metrics.update(extra_metrics or {})
    with atomic_dir(out, error=MediaError) as tmp:
        save_npy_atomic(episode.actions, tmp / ACTIONS)
        write_midi(performance, tmp / PERFORMANCE_MIDI)
        _write_media(result, tmp, media, title, velocities)
        if matched:
            plot_velocities(
                [p.velocity for p, _ in matched],
                [s.velocity for _, s in matched],
                tmp / VELOCITIES,
                title or "",
            )
        write_json_atomic(metrics, tmp / METRICS)
        write_key_record(key_record(result), tmp / KEY_RECORD)
        if media.report:  # last: the page lists the folder's files
            write_report([tmp], tmp / REPORT, title=out.name, shown_as=[out])
        names = sorted(p.name for p in tmp.iterdir())
    return [out / name for name in names]


def played_dynamics(
    result: PlayResult,
) -> tuple[Song, Any, list[tuple[Note, Note]], dict[str, Any]]:
    """The performance with the velocities its strikes sounded, and how far they are from the
    score's.

    Returns:
        The performance (a Song of the notes played, each with its strike's MIDI velocity),
        the MIDI velocity of each note event ((n,) ints aligned with
        ``episode.note_events``, 0 for key-off and pedal rows; None when the episode kept no
        key angles), the (performed, score) pairs of matched notes,
        and the loudness metrics (:func:`pianist.media.dynamics.velocity_metrics`; empty
        without key angles).
    """
    from pianist.media.dynamics import (
        episode_velocities,
        match_notes,
        velocity_metrics,
        with_velocities,
    )

    episode = result.episode
    performance = episode.performance()
    if episode.qpos is None:  # velocities come from the keys' recorded angles
        return performance, None, [], {}
    velocities = episode_velocities(episode, result.scene)
    performance = with_velocities(performance, episode.note_events, velocities)
    score = _score(result)
    return (
        performance,
        velocities,
        match_notes(performance, score),
        velocity_metrics(performance, score),
    )


def _score(result: PlayResult) -> Any:
    """The song as the episode asked for it: it starts after the lead-in, as the performance's
    song does."""
    episode = result.episode
    return delay(result.song, episode.lead_in_steps * episode.control_timestep_s)


def _write_media(
    result: PlayResult, folder: Path, media: MediaOptions, title: str | None, velocities: Any
) -> None:
    from pianist.media.audio import (
        normalise_loudness,
        stereo_comparison,
        synthesize_events,
        synthesize_song,
        write_wav,
    )
    from pianist.media.plots import plot_pianoroll

    episode = result.episode
    plot_pianoroll(episode, folder / PIANOROLL, title=title or "", weights=result.reward_weights)
    performance = None
    if media.audio:
        duration = episode.num_steps * episode.control_timestep_s
        performance, _ = normalise_loudness(
            synthesize_events(
                episode.note_events, duration, soundfont=media.soundfont, velocities=velocities
            )
        )
        write_wav(performance, folder / PERFORMANCE_WAV)
        score, _ = normalise_loudness(synthesize_song(_score(result), soundfont=media.soundfont))
        write_wav(score, folder / SCORE_WAV)
        write_wav(stereo_comparison(score, performance), folder / COMPARISON_WAV)
    if media.video:
        from pianist.media.video import render_episode

        render_episode(
            result.scene,
            episode,
            folder / VIDEO,
            camera=media.camera,
            fps=media.fps,
            size=media.size,
            audio=performance,
            progress=media.progress,
            falling_notes=media.falling_notes,
            antialias=media.antialias,
        )
