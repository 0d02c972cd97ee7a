"""An episode record (what was asked, what was played) and the performance as a Song."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pianist.eval.metrics import precision_recall_f1, sustain_metrics
from pianist.music import Note, Song

LOWEST_PITCH = 21  # MIDI pitch of key 0 (A0)
PEDAL_KEY = -1


@dataclass
class Episode:
    """Everything one episode produced, as arrays over its T steps.

    Attributes:
        actions: (T, A) normalised actions.
        active_keys: (T, 88) bool, keys sounding at the end of each step.
        sustain: (T,) bool, pedal state of each step.
        goal_keys: (T, 88) bool, keys due at each step.
        goal_sustain: (T,) bool.
        rewards: (T,) total reward.
        reward_terms: name -> (T,) raw reward term.
        note_events: (n, 3) rows (time s, key 0-87 or -1 for the pedal, 1 on / 0 off).
        control_timestep_s: seconds per step.
        end_time_s: simulation time at the end of the episode.
        qpos: (T + 1, nq) joint positions after reset and after each step (for video), or
            None when not recorded.
        lead_in_steps: steps of silence before the song (``EnvConfig.initial_buffer_s``).
    """

    actions: np.ndarray
    active_keys: np.ndarray
    sustain: np.ndarray
    goal_keys: np.ndarray
    goal_sustain: np.ndarray
    rewards: np.ndarray
    reward_terms: dict[str, np.ndarray]
    note_events: np.ndarray
    control_timestep_s: float
    end_time_s: float
    qpos: np.ndarray | None = None
    lead_in_steps: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def num_steps(self) -> int:
        return len(self.actions)

    def metrics(self) -> dict[str, float]:
        """precision, recall, f1, sustain_precision/recall/f1 (facts section 5), plus steps,
        seconds (simulated) and return.

        Each metric is the mean over steps of that step's value (facts section 5), not
        recomputed from the means: a precision of 1.0 and a recall of 0.966 can average to an
        F1 of 0.967.

        When the episode starts with silent steps, a lead-in (``lead_in_steps`` > 0) or a file
        that begins with a rest, whose steps count like any other as in the original (nothing
        due, nothing pressed: F1 1), also song_precision, song_recall and song_f1: the same
        from the first step with a key due, which the silence does not inflate; and
        ``silent_start_steps``.
        """
        keys = precision_recall_f1(self.active_keys, self.goal_keys)
        pedal = sustain_metrics(self.sustain, self.goal_sustain)
        metrics = {
            **keys,
            **{f"sustain_{name}": value for name, value in pedal.items()},
            "steps": self.num_steps,
            "seconds": self.num_steps * self.control_timestep_s,
            "return": float(self.rewards.sum()),
        }
        if self.lead_in_steps > 0:
            metrics["lead_in_steps"] = self.lead_in_steps
        due = np.flatnonzero(self.goal_keys.any(axis=1))
        start = int(due[0]) if due.size else self.lead_in_steps
        if start > 0:
            metrics["silent_start_steps"] = start
            if self.num_steps > start:
                song = precision_recall_f1(self.active_keys[start:], self.goal_keys[start:])
                metrics.update({f"song_{name}": value for name, value in song.items()})
        return metrics

    def performance(self, name: str = "performance") -> Song:
        """The notes the hands played, from the note events (velocity is not simulated)."""
        notes: list[Note] = []
        open_notes: dict[int, float] = {}
        pedal_on: float | None = None
        sustain: list[tuple[float, float]] = []
        for time_s, key, on in self.note_events:
            key = int(key)
            if key == PEDAL_KEY:
                if on and pedal_on is None:
                    pedal_on = time_s
                elif not on and pedal_on is not None:
                    if time_s > pedal_on:
                        sustain.append((pedal_on, time_s))
                    pedal_on = None
            elif on:
                open_notes.setdefault(key, time_s)
            elif key in open_notes:
                start = open_notes.pop(key)
                if time_s > start:
                    notes.append(Note(LOWEST_PITCH + key, start, time_s))
        for key, start in open_notes.items():  # still sounding when the episode ended
            if self.end_time_s > start:
                notes.append(Note(LOWEST_PITCH + key, start, self.end_time_s))
        if pedal_on is not None and self.end_time_s > pedal_on:
            sustain.append((pedal_on, self.end_time_s))
        return Song(notes=tuple(notes), sustain=tuple(sustain), name=name)
