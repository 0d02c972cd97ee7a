"""The controllers' per-step F1 is the metric's."""

import numpy as np

from pianist.control.scoring import step_f1, step_f1_loss
from pianist.eval.metrics import per_step_precision_recall_f1


def test_step_f1_is_the_metrics_per_step_f1():
    rng = np.random.default_rng(0)
    due = rng.random((200, 88)) < 0.04
    active = (due & (rng.random((200, 88)) < 0.8)) | (rng.random((200, 88)) < 0.01)
    due[:20] = False
    active[:10] = False  # nothing due, nothing sounding: 1; something sounding: 0
    expected = per_step_precision_recall_f1(active, due)[2]
    np.testing.assert_allclose(step_f1(active, due), expected, atol=1e-12)
    losses = [step_f1_loss(d, a) for d, a in zip(due, active, strict=True)]
    np.testing.assert_allclose(losses, 1.0 - expected, atol=1e-12)
