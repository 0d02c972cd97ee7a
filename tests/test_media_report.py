"""The report page: what a run's report.html shows, from a real run, and Chromium reading it."""

import json
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from pianist.cli import main
from pianist.eval.metrics import precision_recall_f1
from pianist.media.report import (
    KEY_RECORD,
    LOWEST_PITCH,
    REPORT,
    load_run,
    missed_notes,
    render_report,
    song_provenance,
    wrong_notes,
)

SONG = "c-major-chords"  # the shortest debug song (4 s)


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pianist.cli", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real short run: the planner plays the shortest debug song with fast physics, with a
    small video, and writes its report."""
    out = tmp_path_factory.mktemp("report") / "chords"
    args = ["play", SONG, "--physics", "fast", "--out", str(out), "--report"]
    assert main([*args, "--video", "--fps", "10", "--size", "64", "96"]) == 0
    return out


class _Elements(HTMLParser):
    """Collects (tag, attributes) of every start tag and the text of table cells by table."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str]]] = []
        self.tables: dict[str, list[list[str]]] = {}
        self._table: str | None = None
        self._row: list[str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attributes = {k: v or "" for k, v in attrs}
        self.tags.append((tag, attributes))
        if tag == "table":
            self._table = attributes.get("class", "").split()[0]
            self.tables[self._table] = []
        elif tag == "tr" and self._table:
            self._row = []
            self.tables[self._table].append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)

    def all(self, tag: str) -> list[dict[str, str]]:
        return [attrs for t, attrs in self.tags if t == tag]


def _parse(page: str) -> _Elements:
    parser = _Elements()
    parser.feed(page)
    return parser


def test_play_report_shows_the_runs_metrics_media_and_notes(run_dir):
    metrics = json.loads((run_dir / "metrics.json").read_text())
    page = (run_dir / REPORT).read_text()
    parsed = _parse(page)
    rows = {row[0]: row[1] for row in parsed.tables["metrics"]}
    assert float(rows["F1"]) == pytest.approx(metrics["f1"], abs=5e-4)
    assert float(rows["precision"]) == pytest.approx(metrics["precision"], abs=5e-4)
    assert float(rows["sustain F1"]) == pytest.approx(metrics["sustain_f1"], abs=5e-4)
    assert int(rows["steps"]) == metrics["steps"] == 81
    assert rows["physics"] == "fast" and rows["controller"] == "planner" and rows["seed"] == "0"
    assert float(rows["real-time factor"]) == pytest.approx(metrics["realtime_factor"], rel=1e-3)
    assert "forearm_dofs" in rows["env_options"]  # every other entry of metrics.json is shown
    # The page opens with the summary: what was played, how well, in words.
    summary = {row[0]: row[1] for row in parsed.tables["summary"]}
    assert list(parsed.tables)[0] == "summary" and len(parsed.tables["summary"]) <= 12
    assert summary["song"] == metrics["song"] and summary["controller"] == "planner"
    assert float(summary["F1"]) == pytest.approx(metrics["f1"], abs=5e-4)
    assert "most these hands allow (F1)" in summary and "wall time" in summary
    missed = (
        len(parsed.tables["missed-notes"]) - 1
        if parsed.tables["missed-notes"][0] != ["none"]
        else 0
    )
    assert summary["in words"].startswith(f"Missed {missed} of {int(metrics['notes'])} notes")
    # Every metric says what it means (a third cell), folded under "All metrics".
    assert all(len(row) == 3 and row[2] for row in parsed.tables["metrics"])
    assert page.index('class="summary"') < page.index("pianoroll.png") < page.index("<details")
    # Media by relative path, each a file of the folder.
    sounds = sorted(a["src"] for a in parsed.all("audio"))
    assert sounds == sorted(p.name for p in run_dir.glob("*.wav"))
    assert {"score.wav", "performance.wav"} <= set(sounds)
    assert [v["src"] for v in parsed.all("video")] == ["performance.mp4"]
    assert [i["src"] for i in parsed.all("img")] == ["pianoroll.png", "velocities.png"]
    loudness = {row[0]: row[1] for row in parsed.tables["summary"]}["loudness against the score"]
    assert f"off by {metrics['velocity_mae']:.1f} of 127" in loudness
    # The temporary folder the result was written in is never named.
    assert f"<code>{run_dir}</code>" in page and "/." + run_dir.name not in page
    # Provenance of a built-in song: its description.
    assert "C major chords I-IV-V-I" in page
    assert "missed-notes" in parsed.tables and "wrong-notes" in parsed.tables


def test_the_key_record_is_the_runs_own_and_the_tables_follow_from_it(run_dir):
    metrics = json.loads((run_dir / "metrics.json").read_text())
    with np.load(run_dir / KEY_RECORD, allow_pickle=False) as archive:
        record = {name: archive[name] for name in archive.files}
    # Scoring the recorded keys gives the run's metrics: the record is what was played.
    scores = precision_recall_f1(record["active_keys"], record["goal_keys"])
    assert scores["f1"] == pytest.approx(metrics["f1"])
    assert scores["precision"] == pytest.approx(metrics["precision"])
    assert len(record["score_pitch"]) == 16  # the song's notes
    # Every sounding key has the finger nearest it; silent keys none.
    fingers = record["finger_at_key"]
    assert (fingers[record["active_keys"]] >= 0).all()
    assert (fingers[~record["active_keys"]] == -1).all()
    # The wrong-note table covers exactly the key-steps sounding while not due.
    wrong = wrong_notes(record)
    dt = float(record["control_timestep_s"])
    wrong_steps = np.count_nonzero(record["active_keys"] & ~record["goal_keys"])
    assert sum(round(row.duration_s / dt) for row in wrong) == wrong_steps
    page_rows = _parse((run_dir / REPORT).read_text()).tables["wrong-notes"][1:]
    if wrong:
        assert len(page_rows) == len(wrong)
        first = wrong[0]
        assert page_rows[0][3] == _name(first.pitch) and page_rows[0][4] == first.hand
    else:
        assert page_rows == [["none"]]


def _name(pitch: int) -> str:
    names = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
    return f"{names[pitch % 12]}{pitch // 12 - 1}"


def _record(goal: np.ndarray, active: np.ndarray, notes, fingers=None) -> dict:
    """A key record of 0.05 s steps; ``notes`` as (pitch, onset_s, offset_s, finger, hand)."""
    return {
        "goal_keys": goal,
        "active_keys": active,
        "finger_at_key": np.where(active, 2 if fingers is None else fingers, -1).astype(np.int8),
        "control_timestep_s": np.float64(0.05),
        "score_pitch": np.array([n[0] for n in notes]),
        "score_onset_s": np.array([n[1] for n in notes], dtype=float),
        "score_offset_s": np.array([n[2] for n in notes], dtype=float),
        "score_finger": np.array([n[3] for n in notes]),
        "score_hand": np.array([n[4] for n in notes], dtype="<U5"),
    }


def test_missed_notes_are_score_notes_mostly_silent():
    steps = 20
    goal = np.zeros((steps, 88), dtype=bool)
    active = np.zeros_like(goal)
    c4, e4 = 60 - LOWEST_PITCH, 64 - LOWEST_PITCH
    goal[0:11, c4] = True  # C4 due 0-0.5 s: frames 0..10
    goal[10:21, e4] = True  # E4 due 0.5-1.0 s
    active[0:11, c4] = True  # C4 played throughout
    active[18:20, e4] = True  # E4 only at the end: 2 of its 10 steps
    notes = [(60, 0.0, 0.5, 0, "right"), (64, 0.5, 1.0, 7, "left")]
    missed = missed_notes(_record(goal, active, notes))
    assert len(missed) == 1
    row = missed[0]
    assert (row.pitch, row.time_s, row.finger, row.hand) == (64, 0.5, 7, "left")
    assert row.sounded == pytest.approx(2 / 10)


def test_wrong_notes_are_kinded_early_held_or_extra_with_their_finger():
    steps = 30
    goal = np.zeros((steps, 88), dtype=bool)
    active = np.zeros_like(goal)
    goal[10:20, 39] = True
    active[8:23, 39] = True  # pressed 2 steps early, released 3 steps late
    active[5:7, 50] = True  # never due
    fingers = np.full(goal.shape, -1)
    fingers[:, 50] = 6  # left index
    fingers[:, 39] = 1
    rows = wrong_notes(_record(goal, active, [], fingers))
    kinds = [(r.pitch - LOWEST_PITCH, r.kind, round(r.duration_s / 0.05)) for r in rows]
    assert kinds == [(50, "extra", 2), (39, "early", 2), (39, "held", 3)]
    assert (rows[0].finger, rows[0].hand) == (6, "left")
    assert (rows[1].finger, rows[1].hand) == (1, "right")


def test_text_is_escaped(tmp_path):
    folder = tmp_path / "r"
    folder.mkdir()
    song = "<script>alert(1)</script>.mid"
    (folder / "metrics.json").write_text(json.dumps({"song": song, "f1": 0.5, "x<y": "a&b"}))
    page = render_report([load_run(folder)], folder)
    assert "<script>" not in page and "&lt;script&gt;" in page
    assert "x&lt;y" in page and "a&amp;b" in page


def test_open_library_songs_show_their_provenance():
    rows = dict(song_provenance({"song": "bach-prelude-c-major-bwv846"}))
    assert rows["composer"] == "Johann Sebastian Bach (1685-1750)"
    assert "music21" in rows["source"] and rows["segment"] == "measures 1-12"
    assert "Apache-2.0" in rows["licence"]
    assert dict(song_provenance({"song": "my/piece.mid"}))["file"] == "MIDI file"


def test_report_cli_rewrites_one_page_and_compares_several(run_dir, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    (copy / REPORT).unlink()
    result = _cli("report", str(copy))
    assert result.returncode == 0, result.stderr
    assert (copy / REPORT).read_text().count("<audio") == len(list(copy.glob("*.wav")))
    # A folder written before the key record existed still gets a page, without note tables.
    old = tmp_path / "old"
    shutil.copytree(run_dir, old)
    (old / KEY_RECORD).unlink()
    assert _cli("report", str(old)).returncode == 0
    old_page = (old / REPORT).read_text()
    assert "No key record" in old_page and "missed-notes" not in old_page
    # Several folders: one page elsewhere, media referenced relative to it.
    page = tmp_path / "pages" / "both.html"
    page.parent.mkdir()
    result = _cli("report", str(copy), str(old), "--out", str(page))
    assert result.returncode == 0, result.stderr
    parsed = _parse(page.read_text())
    compared = {row[0]: row[1:] for row in parsed.tables["comparison"]}
    metrics = json.loads((copy / "metrics.json").read_text())
    assert [float(v) for v in compared["F1"]] == pytest.approx([metrics["f1"]] * 2, abs=5e-4)
    assert compared["missed notes"][1] == "-"  # the old folder has no record
    for audio in parsed.all("audio"):
        assert (page.parent / audio["src"]).is_file(), audio["src"]
    assert len(parsed.all("audio")) == 2 * len(list(copy.glob("*.wav")))
    # The page is written again in place; any other file there is not overwritten.
    assert _cli("report", str(copy), str(old), "--out", str(page)).returncode == 0
    metrics_text = (copy / "metrics.json").read_text()
    for target in (copy / "metrics.json", tmp_path / "notes.py"):
        target.write_text(metrics_text if target.suffix == ".json" else "print('keep')")
        result = _cli("report", str(copy), "--out", str(target))
        assert result.returncode == 1 and "is not a report page" in result.stderr
    assert (copy / "metrics.json").read_text() == metrics_text
    # The same folder twice (however spelt) is no comparison.
    result = _cli("report", str(copy), f"{copy}/", "--out", str(page))
    assert result.returncode == 1 and "is given twice" in result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (lambda d: [str(d)], "is not a result folder"),
        (lambda d: [str(d / "missing")], "no such result folder"),
        (lambda d: [str(d), str(d)], "needs --out"),
    ],
)
def test_report_cli_refuses_bad_folders_in_one_line(tmp_path, args, message):
    (tmp_path / "notes.txt").write_text("not a result")
    result = _cli("report", *args(tmp_path))
    assert result.returncode == 1
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_chromium_loads_the_page_and_finds_its_elements(run_dir, tmp_path):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.fail(
            "chromium is not installed: apt-get install -y --no-install-recommends chromium "
            "(.ci/run installs it)"
        )
    url = (run_dir / REPORT).resolve().as_uri()
    result = subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--dump-dom",
            url,
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    dom = _parse(result.stdout)
    # What the browser built from the page: the tables with their rows, the players.
    metrics = json.loads((run_dir / "metrics.json").read_text())
    rows = {row[0]: row[1] for row in dom.tables["metrics"]}
    assert float(rows["F1"]) == pytest.approx(metrics["f1"], abs=5e-4)
    # The first table the browser shows is the summary, of at most 12 rows.
    assert list(dom.tables)[0] == "summary" and 1 < len(dom.tables["summary"]) <= 12
    assert len(dom.all("audio")) == len(list(run_dir.glob("*.wav"))) >= 2
    assert all(a.get("controls") is not None for a in dom.all("audio"))
    assert "missed-notes" in dom.tables and "wrong-notes" in dom.tables
    header = dom.tables["wrong-notes"][0]
    assert header == ["none"] or header[:4] == ["time (s)", "duration (s)", "key", "pitch"]
    assert re.search(r"<video[^>]*src=\"performance.mp4\"", result.stdout)
