"""Key and sustain precision / recall / F1, hand-computed cases and the zero-division rules."""

from __future__ import annotations

import numpy as np
import pytest

from pianist.eval import per_step_precision_recall_f1, precision_recall_f1, sustain_metrics


def _rows(*steps: tuple[set[int], set[int]], keys: int = 88) -> tuple[np.ndarray, np.ndarray]:
    """(pressed, goal) arrays from per-step (pressed key set, due key set)."""
    pressed = np.zeros((len(steps), keys), dtype=bool)
    goal = np.zeros((len(steps), keys), dtype=bool)
    for t, (p, g) in enumerate(steps):
        pressed[t, list(p)] = True
        goal[t, list(g)] = True
    return pressed, goal


def _prf(*steps: tuple[set[int], set[int]]) -> tuple[float, float, float]:
    result = precision_recall_f1(*_rows(*steps))
    return result["precision"], result["recall"], result["f1"]


def test_nothing_due_nothing_pressed() -> None:
    assert _prf((set(), set())) == (1.0, 1.0, 1.0)


def test_nothing_due_wrong_press() -> None:
    assert _prf(({5}, set())) == (0.0, 1.0, 0.0)


def test_due_key_missed_nothing_pressed() -> None:
    assert _prf((set(), {5})) == (1.0, 0.0, 0.0)


def test_all_wrong_gives_zero_f1() -> None:
    assert _prf(({1}, {2})) == (0.0, 0.0, 0.0)


def test_perfect() -> None:
    assert _prf(({1, 2, 3}, {1, 2, 3})) == (1.0, 1.0, 1.0)


def test_partial_step() -> None:
    # Pressed {0, 1, 2}, due {1, 2, 3, 4}: tp 2, P = 2/3, R = 1/2, F1 = 2*(1/3)/(7/6) = 4/7.
    p, r, f = _prf(({0, 1, 2}, {1, 2, 3, 4}))
    assert (p, r, f) == pytest.approx((2 / 3, 1 / 2, 4 / 7))


def test_f1_is_mean_of_per_step_f1() -> None:
    # Step 1 scores 0/1/0, step 2 scores 1/1/1: mean P 0.5, R 1, F1 0.5 (not 2/3).
    p, r, f = _prf(({7}, set()), ({3}, {3}))
    assert (p, r, f) == (0.5, 1.0, 0.5)


def test_per_step_arrays() -> None:
    pressed, goal = _rows((set(), set()), ({1}, set()), (set(), {1}), ({1, 2}, {2}))
    precision, recall, f1 = per_step_precision_recall_f1(pressed, goal)
    assert precision.tolist() == [1.0, 0.0, 1.0, 0.5]
    assert recall.tolist() == [1.0, 1.0, 0.0, 1.0]
    assert f1 == pytest.approx([1.0, 0.0, 0.0, 2 / 3])
    assert precision.shape == recall.shape == f1.shape == (4,)


def test_matches_loop_reference_on_random_data() -> None:
    rng = np.random.default_rng(0)
    pressed = rng.random((300, 88)) < 0.03
    goal = rng.random((300, 88)) < 0.03
    expected = []
    for p_row, g_row in zip(pressed, goal, strict=True):
        tp = np.sum(p_row & g_row)
        p = tp / p_row.sum() if p_row.sum() else 1.0
        r = tp / g_row.sum() if g_row.sum() else 1.0
        expected.append((p, r, 2 * p * r / (p + r) if p + r else 0.0))
    means = np.mean(expected, axis=0)
    result = precision_recall_f1(pressed, goal)
    assert [result["precision"], result["recall"], result["f1"]] == pytest.approx(means.tolist())


def test_integer_inputs_accepted() -> None:
    result = precision_recall_f1(np.array([[1, 0]]), np.array([[1, 1]]))
    assert result == pytest.approx({"precision": 1.0, "recall": 0.5, "f1": 2 / 3})
    assert all(isinstance(v, float) for v in result.values())


def test_sustain_metrics() -> None:
    pressed = np.array([False, True, True, False])
    goal = np.array([False, False, True, True])
    # Steps: (none, none) 1/1/1; (pressed, not due) 0/1/0; hit 1/1/1; missed 1/0/0.
    assert sustain_metrics(pressed, goal) == pytest.approx(
        {"precision": 0.75, "recall": 0.75, "f1": 0.5}
    )


@pytest.mark.parametrize(
    ("pressed", "goal", "match"),
    [
        (np.zeros((3, 88), bool), np.zeros((3, 87), bool), "same shape"),
        (np.zeros(88, bool), np.zeros(88, bool), r"\(T, K\)"),
        (np.zeros((0, 88), bool), np.zeros((0, 88), bool), "empty"),
        (np.zeros((2, 88)), np.zeros((2, 88)), "dtype"),
    ],
)
def test_key_validation(pressed: np.ndarray, goal: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        precision_recall_f1(pressed, goal)


def test_sustain_validation() -> None:
    with pytest.raises(ValueError, match=r"\(T,\)"):
        sustain_metrics(np.zeros((2, 1), bool), np.zeros((2, 1), bool))
    with pytest.raises(ValueError, match="empty"):
        sustain_metrics(np.zeros(0, bool), np.zeros(0, bool))
    with pytest.raises(ValueError, match="same shape"):
        sustain_metrics(np.zeros(2, bool), np.zeros(3, bool))
