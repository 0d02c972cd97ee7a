"""Evaluation of piano playing: RoboPianist's precision / recall / F1 metrics."""

from pianist.eval.metrics import (
    per_step_precision_recall_f1,
    precision_recall_f1,
    sustain_metrics,
)

__all__ = ["per_step_precision_recall_f1", "precision_recall_f1", "sustain_metrics"]
