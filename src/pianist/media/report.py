"""A result folder as one page a person reads: ``report.html``.

The page shows a run's metrics and options, its piano roll, players for its audio and video,
the notes it missed and the notes it played that were not asked for, and where the song comes
from. Several result folders give one page that compares them. The page is a single HTML file
with no scripts and nothing fetched from the network: the media are the folder's own files,
referenced by relative path, so the page works offline and moves with its folder.

The missed and wrong notes come from the run's key record, ``keys.npz``, which
:func:`pianist.media.results.write_result` writes beside the metrics (:func:`key_record` makes
it). A folder written before the record existed still gets a page, without the note tables.

Definitions (times in seconds from the start of the recording, lead-in included, as in the
audio and the video; step t covers [t dt, (t + 1) dt) and is scored on the keys sounding at its
end):

- a **missed note** is a note of the score whose key sounded in fewer than half of the steps it
  was due (:data:`MISSED_BELOW`); the table gives the fraction it sounded;
- a **wrong note** is a run of steps in which a key sounded while not due. It is ``early`` when
  the key's next due step follows it directly, ``held`` when it continues a due run of the same
  key (released late), ``extra`` otherwise. Its finger is the fingertip nearest the key when it
  went down.
"""

from __future__ import annotations

import html
import io
import json
import math
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import quote

import numpy as np

from pianist.eval.rollout import realtime_text
from pianist.files import write_bytes_atomic, write_text_atomic
from pianist.media.errors import MediaError
from pianist.media.metric_text import in_words, metric_text

if TYPE_CHECKING:
    from pianist.eval.session import PlayResult

REPORT = "report.html"
KEY_RECORD = "keys.npz"
METRICS = "metrics.json"
PIANOROLL = "pianoroll.png"
#: Performed against score velocities of the matched notes (when the episode has them).
VELOCITIES = "velocities.png"
LOWEST_PITCH = 21  # MIDI pitch of key 0 (A0)
NUM_KEYS = 88
#: A score note is missed when its key sounded in less than this fraction of its due steps.
MISSED_BELOW = 0.5
#: Rows shown per note table; a run of a wrong policy can play thousands of wrong notes.
MAX_ROWS = 300

_FINGER_NAMES = ("thumb", "index", "middle", "ring", "little")
_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
_AUDIO_LABELS = {
    "score.wav": "the score: what was asked",
    "performance.wav": "the performance: what the hands played",
    "comparison.wav": "both at once: score on the left, performance on the right",
}
_VIDEO_SUFFIXES = (".mp4", ".webm")
# The headline metrics, in the order a reader wants them; every other entry follows.
_METRIC_LABELS = {
    "precision": "precision",
    "recall": "recall",
    "f1": "F1",
    "song_precision": "song-only precision",
    "song_recall": "song-only recall",
    "song_f1": "song-only F1",
    "sustain_precision": "sustain precision",
    "sustain_recall": "sustain recall",
    "sustain_f1": "sustain F1",
    "steps": "steps",
    "excerpt_start_s": "excerpt from (s)",
    "excerpt_seconds": "excerpt length (s)",
    "seconds": "simulated seconds",
    "realtime_factor": "real-time factor",
    "wall_seconds": "wall seconds",
    "return": "return",
    "song": "song",
    "controller": "controller",
    "physics": "physics",
    "fingering": "fingering",
    "seed": "seed",
}
# Compared across runs on a comparison page (the higher the better for the first nine).
_COMPARED = (
    "f1",
    "precision",
    "recall",
    "song_f1",
    "sustain_f1",
    "realtime_factor",
)
_COMPARED_INFO = (
    "song",
    "excerpt_start_s",
    "excerpt_seconds",
    "controller",
    "physics",
    "fingering",
    "seed",
    "steps",
)


@dataclass(frozen=True)
class NoteRow:
    """One row of a note table.

    Attributes:
        time_s: when the note starts (s, from the start of the recording).
        duration_s: how long it was due (missed) or sounded (wrong), s.
        pitch: MIDI pitch.
        finger: 0-4 right thumb..little, 5-9 left thumb..little, or None (unknown).
        hand: "right", "left" or None.
        sounded: a missed note's fraction of due steps its key sounded (0..1); None for wrong.
        kind: a wrong note's kind (``extra``, ``early``, ``held``); "" for missed.
    """

    time_s: float
    duration_s: float
    pitch: int
    finger: int | None
    hand: str | None
    sounded: float | None = None
    kind: str = ""


@dataclass(frozen=True)
class RunReport:
    """What one result folder shows.

    Attributes:
        folder: the result folder.
        metrics: its metrics.json.
        media: names of the folder's audio and video files, and of its piano roll.
        missed: the missed notes, or None without a key record.
        wrong: the wrong notes, or None without a key record.
        provenance: where the song comes from (label -> text), in reading order.
        shown_as: the folder as the page names it, when it differs from ``folder`` (a page
            written inside the temporary folder that becomes the result folder).
    """

    folder: Path
    metrics: dict[str, Any]
    media: tuple[str, ...]
    missed: tuple[NoteRow, ...] | None
    wrong: tuple[NoteRow, ...] | None
    provenance: tuple[tuple[str, str], ...]
    shown_as: Path | None = None

    @property
    def name(self) -> Path:
        """The folder as the page names it."""
        return self.shown_as or self.folder


# ----------------------------------------------------------------------- the key record


def key_record(result: PlayResult) -> dict[str, np.ndarray]:
    """The arrays the note tables are made of, for ``keys.npz``.

    Returns:
        ``goal_keys`` and ``active_keys`` (T, 88) bool (due / sounding at the end of each step);
        ``finger_at_key`` (T, 88) int8, the fingertip (0-9) nearest each sounding key, -1 where
        none sounds or the episode has no joint positions; ``control_timestep_s`` () float;
        ``lead_in_steps`` () int; and the score as the episode asked for it (delayed by the
        lead-in): ``score_pitch`` (n,) int, ``score_onset_s`` and ``score_offset_s`` (n,) s,
        ``score_finger`` (n,) int (-1 unlabelled), ``score_hand`` (n,) str ("" unknown).
    """
    episode = result.episode
    dt = episode.control_timestep_s
    lead_in_s = episode.lead_in_steps * dt
    notes = sorted(result.song.notes, key=lambda n: (n.onset_s, n.pitch))
    active = np.asarray(episode.active_keys, dtype=bool)
    return {
        "goal_keys": np.asarray(episode.goal_keys, dtype=bool),
        "active_keys": active,
        "finger_at_key": _nearest_fingers(result, active),
        "control_timestep_s": np.array(dt, dtype=np.float64),
        "lead_in_steps": np.array(episode.lead_in_steps, dtype=np.int64),
        "score_pitch": np.array([n.pitch for n in notes], dtype=np.int64),
        "score_onset_s": np.array([n.onset_s + lead_in_s for n in notes], dtype=np.float64),
        "score_offset_s": np.array([n.offset_s + lead_in_s for n in notes], dtype=np.float64),
        "score_finger": np.array([-1 if n.finger is None else n.finger for n in notes], np.int64),
        "score_hand": np.array([n.hand or "" for n in notes], dtype="<U5"),
    }


def _nearest_fingers(result: PlayResult, active: np.ndarray) -> np.ndarray:
    """(T, 88) int8: the fingertip nearest each sounding key, replaying the recorded joint
    positions (row t + 1 of ``qpos`` is the state at the end of step t)."""
    import mujoco

    out = np.full(active.shape, -1, dtype=np.int8)
    qpos = result.episode.qpos
    if qpos is None or not active.any():
        return out
    scene = result.scene
    model = scene.model
    tips: list[int] = []
    numbers: list[int] = []
    for hand in scene.hands:
        first = 0 if hand.side == "right" else 5
        tips.extend(int(s) for s in hand.fingertip_sites)
        numbers.extend(first + i for i in range(len(hand.fingertip_sites)))
    data = mujoco.MjData(model)  # never the environment's own state
    key_sites = np.asarray(scene.key_sites)
    finger_numbers = np.array(numbers, dtype=np.int8)
    for t in np.flatnonzero(active.any(axis=1)):
        data.qpos[:] = qpos[t + 1]
        mujoco.mj_kinematics(model, data)
        keys = np.flatnonzero(active[t])
        # Across the keyboard (y) and height (z) only: a finger may press anywhere along a key.
        tip = data.site_xpos[tips][:, 1:]
        key = data.site_xpos[key_sites[keys]][:, 1:]
        distance = np.square(tip[None, :, :] - key[:, None, :]).sum(axis=-1)
        out[t, keys] = finger_numbers[np.argmin(distance, axis=1)]
    return out


def write_key_record(record: Mapping[str, np.ndarray], path: str | os.PathLike[str]) -> None:
    """Write :func:`key_record`'s arrays as a compressed ``.npz`` (no pickles), atomically."""
    buffer = io.BytesIO()
    arrays: dict[str, Any] = {name: np.asarray(a) for name, a in record.items()}
    np.savez_compressed(buffer, **arrays)
    write_bytes_atomic(buffer.getvalue(), path)


def read_key_record(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read a ``keys.npz`` written by :func:`write_key_record`.

    Raises:
        MediaError: unreadable, or an array missing or of the wrong shape.
    """
    try:
        with np.load(path, allow_pickle=False) as archive:
            record = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise MediaError(f"{path}: not a readable key record ({exc})") from None
    needed = ("goal_keys", "active_keys", "control_timestep_s", "score_pitch", "score_onset_s")
    missing = [name for name in needed if name not in record]
    if missing:
        raise MediaError(f"{path}: key record lacks {', '.join(missing)}")
    goal, active = record["goal_keys"], record["active_keys"]
    if goal.shape != active.shape or goal.ndim != 2 or goal.shape[1] != NUM_KEYS:
        raise MediaError(
            f"{path}: goal_keys {goal.shape} and active_keys {active.shape} must be (T, 88)"
        )
    return record


# ------------------------------------------------------------------------- note tables


def missed_notes(record: Mapping[str, np.ndarray]) -> list[NoteRow]:
    """The score's notes whose key sounded in fewer than :data:`MISSED_BELOW` of their due
    steps, by time. A note is due from step floor(onset / dt) to ceil(offset / dt), as the
    goal frames have it (:mod:`pianist.music.frames`)."""
    goal = np.asarray(record["goal_keys"], dtype=bool)
    active = np.asarray(record["active_keys"], dtype=bool)
    dt = float(record["control_timestep_s"])
    steps = len(goal)
    fingers = record.get("score_finger")
    hands = record.get("score_hand")
    rows = []
    for i, (pitch, onset, offset) in enumerate(
        zip(record["score_pitch"], record["score_onset_s"], record["score_offset_s"], strict=True)
    ):
        key = int(pitch) - LOWEST_PITCH
        first = math.floor(round(float(onset) / dt, 9))
        last = min(math.ceil(round(float(offset) / dt, 9)), steps - 1)
        if first >= steps:  # cut off by the episode's end
            continue
        sounded = float(active[first : last + 1, key].mean())
        if sounded < MISSED_BELOW:
            finger = None if fingers is None or int(fingers[i]) < 0 else int(fingers[i])
            hand = str(hands[i]) if hands is not None and str(hands[i]) else None
            duration = float(offset) - float(onset)
            rows.append(NoteRow(float(onset), duration, int(pitch), finger, hand, sounded))
    return rows


def wrong_notes(record: Mapping[str, np.ndarray]) -> list[NoteRow]:
    """Runs of steps in which a key sounded while not due, by time (kinds in the module
    docstring); the finger is ``finger_at_key`` at the run's first step."""
    goal = np.asarray(record["goal_keys"], dtype=bool)
    active = np.asarray(record["active_keys"], dtype=bool)
    dt = float(record["control_timestep_s"])
    at_key = record.get("finger_at_key")
    wrong = active & ~goal
    rows = []
    for key in np.flatnonzero(wrong.any(axis=0)):
        column = wrong[:, key]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], column.astype(np.int8), [0]])))
        for start, stop in zip(edges[::2], edges[1::2], strict=True):
            kind = "extra"
            if start > 0 and goal[start - 1, key] and active[start - 1, key]:
                kind = "held"
            elif stop < len(goal) and goal[stop, key]:
                kind = "early"
            finger = None if at_key is None else int(at_key[start, key])
            finger = None if finger is None or finger < 0 else finger
            hand = None if finger is None else ("right" if finger < 5 else "left")
            pitch = int(key) + LOWEST_PITCH
            rows.append(
                NoteRow(
                    float(start * dt), float((stop - start) * dt), pitch, finger, hand, None, kind
                )
            )
    rows.sort(key=lambda r: (r.time_s, r.pitch))
    return rows


# ----------------------------------------------------------------------- reading folders


def load_run(folder: str | os.PathLike[str]) -> RunReport:
    """Read what the page shows of one result folder.

    Raises:
        MediaError: the folder is missing or is not a result folder (no readable metrics.json),
            or its key record is unreadable.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MediaError(f"{folder}: no such result folder")
    metrics_path = folder / METRICS
    if not metrics_path.is_file():
        raise MediaError(
            f"{folder} is not a result folder (no {METRICS}; `pianist play SONG --out DIR` "
            "writes one)"
        )
    try:
        metrics = json.loads(metrics_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise MediaError(f"{metrics_path}: not readable JSON ({exc})") from None
    if not isinstance(metrics, dict):
        raise MediaError(f"{metrics_path}: not a metrics object")
    names = sorted(p.name for p in folder.iterdir() if p.is_file())
    media = tuple(
        n
        for n in names
        if n.endswith(".wav") or n.endswith(_VIDEO_SUFFIXES) or n in (PIANOROLL, VELOCITIES)
    )
    missed = wrong = None
    if (folder / KEY_RECORD).is_file():
        record = read_key_record(folder / KEY_RECORD)
        missed, wrong = tuple(missed_notes(record)), tuple(wrong_notes(record))
    return RunReport(folder, metrics, media, missed, wrong, song_provenance(metrics))


def song_provenance(metrics: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """Where the played song comes from, as (label, text) pairs: the open library's record
    for its pieces, the description of other built-in songs, the file for a song file."""
    from pianist.music import MusicError, open_song_info, song_description

    song = str(metrics.get("song", ""))
    if not song:
        return ()
    rows: list[tuple[str, str]] = [("song", song)]
    try:
        info = open_song_info(song)
    except MusicError:
        info = None
    if info is not None:
        segment = info.get("segment", {})
        for label, value in (
            ("title", info.get("title")),
            ("composer", _join(info.get("composer"), info.get("composer_dates"))),
            ("segment", segment.get("description") if isinstance(segment, dict) else None),
            ("source", info.get("source")),
            ("source licence", info.get("source_licence")),
            ("composition", info.get("composition")),
            ("licence", info.get("licence")),
            ("fingering", info.get("fingering")),
            ("notes", info.get("note")),
        ):
            if value:
                rows.append((label, str(value)))
        return tuple(rows)
    try:
        rows.append(("description", song_description(song)))
    except MusicError:
        path = Path(song)
        kind = {".mid": "MIDI file", ".midi": "MIDI file", ".txt": "PIG fingering file"}
        rows.append(("file", kind.get(path.suffix.lower(), "song file")))
        if not path.is_absolute():
            rows.append(("note", "path as given on the command line"))
    return tuple(rows)


def _join(*parts: Any) -> str:
    return " ".join(f"({p})" if i else str(p) for i, p in enumerate(parts) if p)


# ------------------------------------------------------------------------------- the page


def render_report(runs: Sequence[RunReport], page_folder: Path, title: str = "") -> str:
    """The HTML page for ``runs`` (one: its report; several: a comparison, then each run).

    Args:
        runs: what :func:`load_run` read, one or more.
        page_folder: the folder the page will be written to; media are referenced relative
            to it.
        title: the page's heading (default: the run folder's name, or "comparison").
    Returns:
        The page, every text escaped.
    """
    if not runs:
        raise MediaError("a report needs at least one result folder")
    heading = title or (runs[0].name.name if len(runs) == 1 else f"{len(runs)} runs compared")
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>pianist: {_e(heading)}</title>",
        f"<style>{_STYLE}</style>",
        "</head>",
        "<body>",
        f"<h1>{_e(heading)}</h1>",
    ]
    if len(runs) > 1:
        parts.append(_comparison(runs))
    for index, run in enumerate(runs, start=1):
        parts.append(_run_section(run, page_folder, index, len(runs) > 1))
    parts.append(
        "<footer>Written by <code>pianist report</code>. Times are seconds from the start of "
        "the recording (the lead-in included), as in the audio and the video. Missed: a score "
        f"note whose key sounded in fewer than {MISSED_BELOW:.0%} of the steps it was due. "
        "Wrong: a key sounding while not due (early: just before it was due; held: released "
        "late; extra: otherwise); its finger is the fingertip nearest the key.</footer>"
    )
    parts += ["</body>", "</html>", ""]
    return "\n".join(parts)


def write_report(
    folders: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str] | None = None,
    *,
    title: str = "",
    shown_as: Sequence[str | os.PathLike[str]] | None = None,
) -> Path:
    """Write the page for one or more result folders.

    Args:
        folders: result folders of ``pianist play`` (or :func:`write_result`).
        out: the HTML file; default ``report.html`` in the folder when there is one folder.
        title: the page's heading.
        shown_as: the folders as the page names them (default: ``folders``).
    Returns:
        The page's path.
    Raises:
        MediaError: a folder is not a result folder, several folders without ``out``, or the
            page cannot be written.
    """
    if not folders:
        raise MediaError("give at least one result folder")
    if out is None:
        if len(folders) > 1:
            raise MediaError("a report of several result folders needs --out FILE")
        out = Path(folders[0]) / REPORT
    out = Path(out)
    if out.is_dir():
        raise MediaError(f"{out} is a folder; give the report's file name (e.g. {out / REPORT})")
    if out.exists() and not _is_report(out):
        raise MediaError(f"{out} exists and is not a report page: give another file name")
    seen = [Path(folder).resolve() for folder in folders]
    twice = next((f for i, f in enumerate(folders) if seen[i] in seen[:i]), None)
    if twice is not None:
        raise MediaError(f"{twice} is given twice: compare different result folders")
    runs = [load_run(folder) for folder in folders]
    if shown_as is not None:
        runs = [replace(run, shown_as=Path(name)) for run, name in zip(runs, shown_as, strict=True)]
    page = render_report(runs, out.parent if str(out.parent) else Path("."), title)
    write_text_atomic(page, out)
    return out


def _is_report(path: Path) -> bool:
    """Whether the file at ``path`` is a page this module wrote (which a new one may replace):
    an HTML page whose title starts "pianist: "."""
    try:
        with open(path, encoding="utf-8", errors="replace") as handle:
            head = handle.read(4096)
    except OSError:
        return False
    return head.startswith("<!DOCTYPE html>") and "<title>pianist: " in head


def _run_section(run: RunReport, page_folder: Path, index: int, several: bool) -> str:
    """One run: the summary first, then the piano roll, the players and the video, the
    song's provenance, every metric (folded) and the missed and wrong notes."""
    anchor = f"run-{index}"
    parts = [f'<section class="run" id="{anchor}">']
    if several:
        parts.append(f"<h2>{index}. {_e(run.name.name)}</h2>")
    parts.append(_summary_table(run))
    parts.append(f'<p class="folder">Folder: <code>{_e(str(run.name))}</code></p>')
    if PIANOROLL in run.media:
        src = _src(run.folder / PIANOROLL, page_folder)
        parts.append(
            f'<h3>Piano roll</h3><img class="pianoroll" src="{src}" alt="piano roll of '
            f'{_e(run.name.name)}: goal boxes, played green, wrong red, missed orange">'
        )
    sounds = [n for n in run.media if n.endswith(".wav")]
    ordered = [n for n in _AUDIO_LABELS if n in sounds] + [
        n for n in sounds if n not in _AUDIO_LABELS
    ]
    if ordered:
        parts.append('<h3>Listen</h3><div class="audio">')
        for name in ordered:
            label = _AUDIO_LABELS.get(name, name)
            src = _src(run.folder / name, page_folder)
            parts.append(
                f"<figure><figcaption><code>{_e(name)}</code>: {_e(label)}</figcaption>"
                f'<audio controls preload="metadata" src="{src}"></audio></figure>'
            )
        parts.append("</div>")
    for name in (n for n in run.media if n.endswith(_VIDEO_SUFFIXES)):
        src = _src(run.folder / name, page_folder)
        parts.append(
            f'<h3>Video</h3><video controls preload="metadata" src="{src}"></video>'
            f"<p><code>{_e(name)}</code></p>"
        )
    if VELOCITIES in run.media:
        src = _src(run.folder / VELOCITIES, page_folder)
        parts.append(
            f'<h3>Loudness</h3><img class="velocities" src="{src}" alt="performed against '
            'score velocity of each matched note">'
        )
    if run.provenance:
        parts.append('<h3>Song</h3><dl class="provenance">')
        for label, text in run.provenance:
            parts.append(f"<dt>{_e(label)}</dt><dd>{_e(text)}</dd>")
        parts.append("</dl>")
    parts.append('<details class="all-metrics"><summary>All metrics</summary>')
    parts.append(_metrics_table(run.metrics))
    parts.append("</details>")
    if run.missed is None or run.wrong is None:
        parts.append(
            f'<p class="no-notes">No key record ({KEY_RECORD}) in this folder: it was written '
            "before pianist recorded one; play the song again for the missed and wrong notes."
            "</p>"
        )
    else:
        parts.append(f"<h3>Missed notes ({len(run.missed)})</h3>")
        parts.append(_note_table(run.missed, "missed-notes", missed=True))
        parts.append(f"<h3>Wrong notes ({len(run.wrong)})</h3>")
        parts.append(_note_table(run.wrong, "wrong-notes", missed=False))
    parts.append("</section>")
    return "\n".join(parts)


def _summary_table(run: RunReport) -> str:
    """The run at a glance (at most 12 rows): what was played, how well, against what these
    hands allow, how long it took, and the result in words."""
    m = run.metrics
    rows: list[tuple[str, str, str]] = []

    def add(key: str, label: str, text: str | None = None) -> None:
        if key in m:
            rows.append((key, label, text if text is not None else _format(m[key])))

    add("song", "song")
    add("controller", "controller")
    add("physics", "physics")
    if "excerpt_start_s" in m:
        start, length = m["excerpt_start_s"], m.get("excerpt_seconds", 0.0)
        rows.append(("excerpt", "excerpt", f"{_format(length)} s from {_format(start)} s"))
    add("f1", "F1")
    add("precision", "precision")
    add("recall", "recall")
    add("song_f1", "song-only F1")
    add("reach_ceiling_f1", "most these hands allow (F1)")
    if m.get("velocity_mae") is not None:
        rho = m.get("velocity_rank_correlation")
        order = "" if rho is None else f", rank correlation {rho:.2f}"
        rows.append(
            (
                "velocity_mae",
                "loudness against the score",
                f"off by {m['velocity_mae']:.1f} of 127 on average{order}",
            )
        )
    if "wall_seconds" in m:
        speed = m.get("realtime_factor")
        how_fast = f" ({realtime_text(speed)} real time)" if isinstance(speed, int | float) else ""
        rows.append(("wall_seconds", "wall time", f"{m['wall_seconds']:.1f} s{how_fast}"))
    missed = None if run.missed is None else len(run.missed)
    wrong = None if run.wrong is None else len(run.wrong)
    rows.append(("in_words", "in words", in_words(m, missed, wrong)))
    body = "".join(
        f'<tr data-key="{_e(key)}"><th scope="row">{_e(label)}</th><td>{_e(text)}</td></tr>'
        for key, label, text in rows
    )
    return f'<table class="summary"><tbody>{body}</tbody></table>'


def _metrics_table(metrics: Mapping[str, Any]) -> str:
    """Every entry of metrics.json: its label, its value and what it means."""
    rows = []
    for key, label in _METRIC_LABELS.items():
        if key in metrics:
            rows.append((key, label, metrics[key]))
    rows += [(key, key, value) for key, value in metrics.items() if key not in _METRIC_LABELS]
    body = "".join(
        f'<tr data-key="{_e(key)}"><th scope="row">{_e(label)}</th>'
        f'<td>{_e(_format(value))}</td><td class="meaning">{_e(metric_text(key))}</td></tr>'
        for key, label, value in rows
    )
    return f'<table class="metrics"><tbody>{body}</tbody></table>'


def _note_table(rows: Sequence[NoteRow], css: str, *, missed: bool) -> str:
    if not rows:
        return f'<table class="{css} notes"><tbody><tr><td>none</td></tr></tbody></table>'
    last = "sounded" if missed else "kind"
    head = (
        "<thead><tr><th>time (s)</th><th>duration (s)</th><th>key</th><th>pitch</th>"
        f"<th>hand</th><th>finger</th><th>{last}</th></tr></thead>"
    )
    body = []
    for row in rows[:MAX_ROWS]:
        extra = f"{row.sounded:.0%}" if missed and row.sounded is not None else row.kind
        body.append(
            f"<tr><td>{row.time_s:.2f}</td><td>{row.duration_s:.2f}</td>"
            f"<td>{row.pitch - LOWEST_PITCH + 1}</td><td>{_e(_pitch_name(row.pitch))}</td>"
            f"<td>{_e(row.hand or '?')}</td><td>{_e(_finger_name(row.finger))}</td>"
            f"<td>{_e(extra)}</td></tr>"
        )
    more = ""
    if len(rows) > MAX_ROWS:
        more = f'<p class="more">... and {len(rows) - MAX_ROWS} more (first {MAX_ROWS} shown)</p>'
    return f'<table class="{css} notes">{head}<tbody>{"".join(body)}</tbody></table>{more}'


def _comparison(runs: Sequence[RunReport]) -> str:
    head = "".join(
        f'<th scope="col"><a href="#run-{i}">{i}. {_e(run.name.name)}</a></th>'
        for i, run in enumerate(runs, start=1)
    )
    body = []
    for key in (*_COMPARED, *_COMPARED_INFO):
        values = [run.metrics.get(key) for run in runs]
        if all(v is None for v in values):
            continue
        numbers = [v for v in values if isinstance(v, int | float) and not isinstance(v, bool)]
        best = max(numbers) if key in _COMPARED and len(numbers) > 1 else None
        cells = "".join(
            f"<td><strong>{_e(_format(v))}</strong></td>"
            if best is not None and v == best
            else f"<td>{_e('-' if v is None else _format(v))}</td>"
            for v in values
        )
        label = _METRIC_LABELS.get(key, key)
        body.append(f'<tr data-key="{_e(key)}"><th scope="row">{_e(label)}</th>{cells}</tr>')
    for name, pick in (("missed notes", "missed"), ("wrong notes", "wrong")):
        cells = "".join(
            f"<td>{'-' if getattr(run, pick) is None else len(getattr(run, pick))}</td>"
            for run in runs
        )
        body.append(f'<tr data-key="{pick}"><th scope="row">{name}</th>{cells}</tr>')
    return (
        '<h2>Comparison</h2><table class="comparison"><thead><tr><th></th>'
        f"{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    )


def _format(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) >= 1e4 or value != round(value, 3) else f"{value:g}"
    if isinstance(value, int | str):
        return str(value)
    return json.dumps(value, sort_keys=True)


def _pitch_name(pitch: int) -> str:
    return f"{_NAMES[pitch % 12]}{pitch // 12 - 1}"


def _finger_name(finger: int | None) -> str:
    if finger is None:
        return "?"
    number = finger % 5
    return f"{number + 1} ({_FINGER_NAMES[number]})"


def _src(path: Path, page_folder: Path) -> str:
    """``path`` relative to the page's folder, as an escaped URL."""
    relative = os.path.relpath(path.resolve(), page_folder.resolve())
    return _e(quote(Path(relative).as_posix()))


def _e(text: str) -> str:
    return html.escape(str(text), quote=True)


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 70em; padding: 0 1em;
  color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; }
th[scope=row] { background: #f4f4f4; font-weight: normal; }
thead th { background: #e8eef6; }
td { font-variant-numeric: tabular-nums; }
td.meaning { color: #555; font-size: 0.9em; font-variant-numeric: normal; }
table.summary th[scope=row] { min-width: 12em; }
details.all-metrics > summary { cursor: pointer; font-weight: 600; margin: 1em 0 0.5em; }
img.pianoroll, video { max-width: 100%; border: 1px solid #ccc; }
.audio figure { margin: 0.5em 0; }
.audio audio { width: 30em; max-width: 100%; }
dl.provenance { display: grid; grid-template-columns: max-content auto; gap: 0.2em 1em; }
dl.provenance dt { color: #555; }
dl.provenance dd { margin: 0; }
section.run { border-top: 2px solid #999; margin-top: 2em; }
footer { margin-top: 3em; color: #555; font-size: 0.9em; }
"""
