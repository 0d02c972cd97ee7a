"""The metric's per-step F1, for controllers that score what they look ahead at.

The same convention as :mod:`pianist.eval.metrics` (which scores episodes, downstream of the
controllers): a step's F1 is that of its sounding keys against its due keys, and a step with
nothing due and nothing sounding scores 1. Arrays in, arrays out.
"""

from __future__ import annotations

import numpy as np


def step_f1(active: np.ndarray, due: np.ndarray) -> np.ndarray:
    """(T,) each step's F1 of the sounding keys ``active`` (T, 88) bool against the ``due``
    keys (T, 88) bool."""
    hits = np.count_nonzero(active & due, axis=-1)
    total = np.count_nonzero(active, axis=-1) + np.count_nonzero(due, axis=-1)
    return np.where(total > 0, 2.0 * hits / np.maximum(total, 1), 1.0)


def step_f1_loss(due: np.ndarray, active: np.ndarray) -> float:
    """1 - F1 of one step's sounding keys ``active`` (88,) bool against the ``due`` keys (88,)
    bool (nothing due and nothing sounding: F1 1)."""
    return 1.0 - float(step_f1(active, due))
