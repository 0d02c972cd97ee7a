"""Sweeps: one task (play, train, eval) over a grid of songs x variants x physics x seeds, each
cell a Ray task writing its own folder, resumable, with one results table.

``grid`` expands the cells and names them, ``tasks`` holds what one cell runs, ``runner``
schedules the cells on Ray (local or a cluster), ``table`` rebuilds the results table and its
summary from the cells' folders. Ray (``pip install 'pianist[scale]'``) is imported only when
a sweep runs. See docs/sweep.md.
"""

from __future__ import annotations

from pianist.sweep.grid import Cell, cell_id, expand, songs_of
from pianist.sweep.runner import SweepReport, run_sweep
from pianist.sweep.tasks import TASKS, SweepOptions

__all__ = [
    "TASKS",
    "Cell",
    "SweepOptions",
    "SweepReport",
    "cell_id",
    "expand",
    "run_sweep",
    "songs_of",
]
