"""A sweep's results: one row per cell, rebuilt from the cells' folders, and a summary.

The table is never appended to: :func:`collect_rows` reads every cell's ``cell.json`` again,
so a rerun, a retried cell or a crashed driver can neither duplicate nor lose a row. Files
written into the sweep's folder (each atomically):

- ``results.csv`` and ``results.json``: one row per cell of the grid, in grid order: the cell
  (id, task, suite, song, variant, physics, seed), its status (``ok``, ``failed``, or
  ``missing`` for a cell that has not finished), the one-line error of a failed cell, its
  scalar metrics (F1 first), and where and how long it ran;
- ``summary.json``: per suite and variant (and physics preset): mean F1 over the finished
  cells, how many finished and failed, and each song's mean F1 over the seeds;
- ``summary.png``: per suite, a bar per song and variant (the mean F1 over seeds; a line
  from the lowest to the highest seed's F1; a red cross where a cell failed), as in the
  paper's per-song figure.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pianist.files import atomic_path, write_json_atomic, write_text_atomic
from pianist.sweep.grid import Cell
from pianist.sweep.tasks import FAILED, OK, read_record

RESULTS_CSV = "results.csv"
RESULTS_JSON = "results.json"
SUMMARY_JSON = "summary.json"
SUMMARY_PNG = "summary.png"
MISSING = "missing"

CELL_COLUMNS = ("id", "task", "suite", "song", "variant", "physics", "seed", "status", "error")
#: Metrics shown first, in this order, when present.
FIRST_METRICS = ("f1", "precision", "recall", "sustain_f1", "song_f1", "best_f1")
#: Where and how long each cell ran, shown last.
RUN_COLUMNS = ("cell_seconds", "host", "node", "pid", "finished_at")
# Entries of metrics.json that repeat a cell column or are not results.
_SKIPPED_METRICS = {"song", "controller", "seed", "run"}


def row_of(cell: Cell, record: dict[str, Any] | None) -> dict[str, Any]:
    """The table row of ``cell`` from its record (None: not finished)."""
    row: dict[str, Any] = {**cell.as_dict(), "status": MISSING, "error": None}
    if record is None:
        return row
    row["status"] = record.get("status", MISSING)
    row["error"] = record.get("error")
    for key, value in (record.get("metrics") or {}).items():
        if key not in _SKIPPED_METRICS and _is_scalar(value):
            row[key] = value
    for key in RUN_COLUMNS:
        row[key] = record.get(key)
    return row


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, str | int | float | bool)


def collect_rows(out: str | Path, cells: Sequence[Cell]) -> list[dict[str, Any]]:
    """One row per cell, in the order of ``cells``, read from the cells' folders in ``out``."""
    return [row_of(cell, read_record(out, cell)) for cell in cells]


def columns_of(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The table's columns: the cell, the first metrics, the other metrics sorted, then the
    run's place and time."""
    present = {key for row in rows for key in row}
    metrics = sorted(present - set(CELL_COLUMNS) - set(FIRST_METRICS) - set(RUN_COLUMNS))
    first = [key for key in FIRST_METRICS if key in present]
    run = [key for key in RUN_COLUMNS if key in present]
    return [*CELL_COLUMNS, *first, *metrics, *run]


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_tables(out: str | Path, rows: Sequence[dict[str, Any]]) -> list[Path]:
    """Write results.csv, results.json, summary.json and summary.png into ``out``; their paths."""
    out = Path(out)
    columns = columns_of(rows)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({key: "" if row.get(key) is None else row[key] for key in columns})
    write_text_atomic(buffer.getvalue(), out / RESULTS_CSV)
    json_rows = [{key: _json_safe(row.get(key)) for key in columns} for row in rows]
    write_json_atomic(json_rows, out / RESULTS_JSON)
    summary = summarize(rows)
    write_json_atomic(summary, out / SUMMARY_JSON)
    plot_summary(summary, out / SUMMARY_PNG)
    return [out / name for name in (RESULTS_CSV, RESULTS_JSON, SUMMARY_JSON, SUMMARY_PNG)]


def _mean(values: Sequence[float]) -> float | None:
    return sum(values) / len(values) if values else None


def summarize(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (suite, variant, physics) group, in order of first appearance.

    Returns:
        A list of groups: ``suite``, ``variant``, ``physics``, ``mean_f1`` (the mean over the
        group's finished cells, None if none), ``ok``, ``failed``, ``missing`` (cell counts)
        and ``songs``: per song, in order, ``mean_f1``, ``min_f1``, ``max_f1`` over its seeds
        (None where no seed finished), ``seeds`` (how many finished) and ``failed`` (whether a
        seed failed).
    """
    groups: dict[tuple[Any, ...], dict[str, Any]] = {}
    for row in rows:
        key = (row["suite"], row["variant"], row["physics"])
        group = groups.setdefault(
            key,
            {
                "suite": key[0],
                "variant": key[1],
                "physics": key[2],
                "f1": [],
                "ok": 0,
                "failed": 0,
                "missing": 0,
                "songs": {},
                "failed_songs": set(),
            },
        )
        scores = group["songs"].setdefault(row["song"], [])
        status = row["status"]
        group[status if status in (OK, FAILED) else "missing"] += 1
        if status == FAILED:
            group["failed_songs"].add(row["song"])
        f1 = row.get("f1")
        if status == OK and isinstance(f1, int | float) and math.isfinite(f1):
            group["f1"].append(float(f1))
            scores.append(float(f1))
    summary = []
    for group in groups.values():
        failed_songs = group.pop("failed_songs")
        songs = [
            {
                "song": song,
                "mean_f1": _mean(scores),
                "min_f1": min(scores) if scores else None,
                "max_f1": max(scores) if scores else None,
                "seeds": len(scores),
                "failed": song in failed_songs,
            }
            for song, scores in group.pop("songs").items()
        ]
        f1 = group.pop("f1")
        summary.append({**group, "mean_f1": _mean(f1), "songs": songs})
    return summary


def _label(group: dict[str, Any]) -> str:
    physics = f" ({group['physics']})" if group["physics"] else ""
    mean = group["mean_f1"]
    score = "no result" if mean is None else f"mean F1 {mean:.3f}"
    failed = f", {group['failed']} failed" if group["failed"] else ""
    return f"{group['variant'] or 'default'}{physics}: {score}{failed}"


def plot_summary(summary: Sequence[dict[str, Any]], path: str | Path) -> None:
    """Per suite, one bar per song and variant: the mean F1 over seeds, a line from the
    lowest to the highest seed's F1 where more than one seed finished; the legend gives each
    variant's mean F1 over the suite. Written atomically to ``path`` (PNG)."""
    from matplotlib.figure import Figure

    suites = list(dict.fromkeys(group["suite"] for group in summary)) or ["(empty)"]
    songs_per_suite = {
        suite: list(
            dict.fromkeys(s["song"] for g in summary if g["suite"] == suite for s in g["songs"])
        )
        for suite in suites
    }
    widest = max((len(songs) for songs in songs_per_suite.values()), default=1)
    width_in = min(40.0, max(7.0, 0.45 * widest + 2.5))
    fig = Figure(figsize=(width_in, 3.4 * len(suites)), dpi=100, layout="constrained")
    axes = fig.subplots(len(suites), 1, squeeze=False)[:, 0]
    for ax, suite in zip(axes, suites, strict=True):
        songs = songs_per_suite[suite]
        groups = [g for g in summary if g["suite"] == suite]
        bar_w = 0.8 / max(1, len(groups))
        for index, group in enumerate(groups):
            by_song = {s["song"]: s for s in group["songs"]}
            xs, heights, low, high, failed = [], [], [], [], []
            for x, song in enumerate(songs):
                entry = by_song.get(song)
                if entry is not None and entry["failed"]:
                    failed.append(x - 0.4 + bar_w * (index + 0.5))
                if entry is None or entry["mean_f1"] is None:
                    continue
                xs.append(x - 0.4 + bar_w * (index + 0.5))
                heights.append(entry["mean_f1"])
                low.append(entry["mean_f1"] - entry["min_f1"])
                high.append(entry["max_f1"] - entry["mean_f1"])
            spread = any(low) or any(high)
            ax.bar(
                xs,
                heights,
                width=bar_w,
                label=_label(group),
                yerr=[low, high] if spread else None,
                capsize=2 if spread else 0,
            )
            # A failed cell: a red cross at the foot of its song's bar.
            ax.plot(failed, [0.02] * len(failed), "x", color="#d62728", markersize=7)
        ax.set_xticks(range(len(songs)))
        ax.set_xticklabels([Path(s).stem if "/" in s else s for s in songs], rotation=35)
        for label in ax.get_xticklabels():
            label.set_horizontalalignment("right")
        ax.set_ylim(0.0, 1.05)
        ax.set_ylabel("F1")
        ax.set_title(suite)
        ax.grid(axis="y", alpha=0.3)
        if groups:
            ax.legend(loc="lower right", fontsize="small")
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
