"""Note events: when keys start and stop sounding, at substep resolution.

Events are (n, 3) float64 arrays, one row per event: simulation time (s), key 0-87 (or -1 for
the sustain pedal), and 1.0 for on / 0.0 for off. Plain float arrays keep ``info`` comparable
with Gymnasium's checkers and cheap to concatenate into an episode record.
"""

from __future__ import annotations

import numpy as np

SUSTAIN_EVENT_KEY = -1
TIME, KEY, ON = 0, 1, 2  # column indices
EMPTY_EVENTS = np.zeros((0, 3))
EMPTY_EVENTS.flags.writeable = False


def key_events(
    previous: np.ndarray, active: np.ndarray, times_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Events between successive activation snapshots.

    Args:
        previous: (88,) bool, activation before the first snapshot.
        active: (S, 88) bool, activation after each of S substeps.
        times_s: (S,) simulation time after each substep.
    Returns:
        (events, last): an (n, 3) event array sorted by time then key, and a copy of active[-1].
    """
    last = active[-1].copy()
    if (active == previous).all():  # the common case: nothing started or stopped sounding
        return EMPTY_EVENTS, last
    changed = active != np.concatenate([previous[None], active[:-1]], axis=0)
    step, key = np.nonzero(changed)
    if step.size == 0:
        return EMPTY_EVENTS, last
    events = np.empty((step.size, 3))
    events[:, TIME] = times_s[step]
    events[:, KEY] = key
    events[:, ON] = active[step, key]
    return events, last


def sustain_event(time_s: float, on: bool) -> np.ndarray:
    """A single pedal event, shape (1, 3)."""
    return np.array([[time_s, SUSTAIN_EVENT_KEY, float(on)]])
