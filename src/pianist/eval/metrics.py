"""Key-press and sustain precision / recall / F1 as RoboPianist reports them (pure NumPy).

Per control step, binary precision, recall and F1 of the pressed (active) bits against the goal
bits; each is then averaged over the steps (F1 is the mean of per-step F1, not recomputed from
the mean precision and recall). Zero-division convention per step:

- nothing pressed: precision 1 (nothing pressed wrongly);
- nothing due: recall 1 (nothing missed);
- F1 = 2PR / (P + R), and 0 when P + R = 0.

So nothing due and nothing pressed scores 1/1/1, a press when nothing is due 0/1/0, and a missed
key with nothing pressed 1/0/0.
"""

from __future__ import annotations

import numpy as np


def _as_bool_pair(pressed: np.ndarray, goal: np.ndarray, ndim: int) -> tuple[np.ndarray, ...]:
    pressed = np.asarray(pressed)
    goal = np.asarray(goal)
    if pressed.shape != goal.shape:
        raise ValueError(
            f"pressed and goal must have the same shape, got {pressed.shape} and {goal.shape}"
        )
    if pressed.ndim != ndim:
        expected = "(T, K)" if ndim == 2 else "(T,)"
        raise ValueError(f"expected {expected} arrays, got shape {pressed.shape}")
    if pressed.shape[0] == 0:
        raise ValueError("cannot score an empty episode (T = 0 steps)")
    for name, array in (("pressed", pressed), ("goal", goal)):
        if array.dtype != np.bool_ and not np.issubdtype(array.dtype, np.integer):
            raise ValueError(f"{name} must be bool (or 0/1 integers), got dtype {array.dtype}")
    return pressed.astype(bool), goal.astype(bool)


def per_step_precision_recall_f1(
    pressed: np.ndarray, goal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-step precision, recall and F1.

    Args:
        pressed: (T, K) bool, bit k active at step t (e.g. K = 88 keys).
        goal: (T, K) bool, bit k due at step t.

    Returns:
        Three (T,) float64 arrays: precision, recall, F1 (module docstring: zero division).
    """
    pressed, goal = _as_bool_pair(pressed, goal, ndim=2)
    true_pos = np.count_nonzero(pressed & goal, axis=1)
    num_pressed = np.count_nonzero(pressed, axis=1)
    num_due = np.count_nonzero(goal, axis=1)
    # np.maximum(..., 1) only avoids division warnings; np.where picks the convention value.
    precision = np.where(num_pressed > 0, true_pos / np.maximum(num_pressed, 1), 1.0)
    recall = np.where(num_due > 0, true_pos / np.maximum(num_due, 1), 1.0)
    total = precision + recall
    f1 = np.where(total > 0, 2 * precision * recall / np.where(total > 0, total, 1.0), 0.0)
    return precision, recall, f1


def precision_recall_f1(pressed: np.ndarray, goal: np.ndarray) -> dict[str, float]:
    """Episode precision, recall and F1: per-step values averaged over the T steps.

    Args:
        pressed: (T, K) bool active bits; goal: (T, K) bool due bits; T >= 1.

    Returns:
        ``{"precision": p, "recall": r, "f1": f}``, each in [0, 1].
    """
    precision, recall, f1 = per_step_precision_recall_f1(pressed, goal)
    return {
        "precision": float(precision.mean()),
        "recall": float(recall.mean()),
        "f1": float(f1.mean()),
    }


def sustain_metrics(pressed: np.ndarray, goal: np.ndarray) -> dict[str, float]:
    """Precision, recall and F1 of the sustain pedal bit, same convention as the keys.

    Args:
        pressed: (T,) bool pedal active; goal: (T,) bool pedal due; T >= 1.

    Returns:
        ``{"precision": p, "recall": r, "f1": f}`` (callers add a ``sustain_`` prefix if needed).
    """
    pressed, goal = _as_bool_pair(pressed, goal, ndim=1)
    return precision_recall_f1(pressed[:, None], goal[:, None])
