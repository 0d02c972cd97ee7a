"""Evaluation of piano playing: RoboPianist's metrics, episode records and rollouts."""

from pianist.eval.episode import Episode
from pianist.eval.errors import error_masks, f1_lost, f1_lost_by_kind, note_errors
from pianist.eval.metrics import (
    per_step_precision_recall_f1,
    precision_recall_f1,
    sustain_metrics,
)
from pianist.eval.rollout import run_episode

__all__ = [
    "Episode",
    "error_masks",
    "f1_lost",
    "f1_lost_by_kind",
    "note_errors",
    "per_step_precision_recall_f1",
    "precision_recall_f1",
    "run_episode",
    "sustain_metrics",
]
