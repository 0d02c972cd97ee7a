"""A dataset sweep's recorded episodes as one Minari dataset.

``pianist sweep --task dataset`` records one demonstration episode per cell (song x
controller x physics x seed) on Ray, each in its cell's ``episode/`` folder
(:mod:`pianist.sweep.tasks`); :func:`assemble_sweep` then writes the finished ones as one
dataset, as ``pianist dataset build`` would have (:func:`pianist.data.build.assemble`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pianist.data.build import BuildReport, BuildSettings, EpisodeTask, assemble
from pianist.data.minari_io import check_dataset_id, dataset_dir, default_root
from pianist.sweep.tasks import CELL_RECORD, CELLS_DIR, EPISODE_DIR, OK


def finished_dataset_cells(out: str | Path) -> list[dict[str, Any]]:
    """The records of the sweep's finished ``dataset`` cells, by song then seed."""
    records = []
    for path in sorted((Path(out) / CELLS_DIR).glob(f"*/{CELL_RECORD}")):
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue  # not finished
        if record.get("task") == "dataset" and record.get("status") == OK:
            records.append(record)
    return sorted(records, key=lambda r: (r["song"], r["seed"]))


def assemble_sweep(out: str | Path, dataset_id: str, root: str | Path | None = None) -> BuildReport:
    """Write the finished episodes of the dataset sweep in ``out`` as Minari dataset
    ``dataset_id`` under ``root`` (default: Minari's datasets folder).

    Raises:
        ValueError: no finished dataset cell, cells of several controllers or physics
            presets (one dataset is one controller's), a bad or existing dataset id.
    """
    check_dataset_id(dataset_id)
    root = Path(root) if root is not None else default_root()
    if dataset_dir(dataset_id, root).exists():
        raise ValueError(f"dataset {dataset_id} already exists in {root}")
    if not Path(out).is_dir():
        raise FileNotFoundError(f"no sweep folder {out}")
    records = finished_dataset_cells(out)
    if not records:
        raise ValueError(f"{out} holds no finished cell of a dataset sweep")
    for key in ("variant", "physics"):
        values = sorted({str(r[key]) for r in records})
        if len(values) > 1:
            raise ValueError(
                f"{out} holds episodes of several {key}s ({', '.join(values)}): one dataset "
                "holds one controller's episodes in one physics"
            )
    first = records[0]
    noises = [float(r["metrics"].get("noise", 0.0)) for r in records]
    settings = BuildSettings(
        controller=first["variant"],
        physics=first["physics"],
        noise=max(noises),
        seed=min(r["seed"] for r in records),
    )
    tasks = [
        EpisodeTask(
            song=r["song"],
            index=r["seed"],
            seed=r["seed"],
            noise=noise,
            out_dir=Path(out) / CELLS_DIR / r["id"] / EPISODE_DIR,
        )
        for r, noise in zip(records, noises, strict=True)
    ]
    return assemble(dataset_id, tasks, settings, root, recorded=len(tasks))
