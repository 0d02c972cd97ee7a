"""How loud a key struck: its strike speed, and the MIDI velocity that speed sounds.

The simulation has no hammer, so a note's loudness is estimated from its key's motion as a
real piano's action turns key speed into hammer speed. A key sounds once its angle reaches
its activation threshold (:data:`pianist.sim.constants.KEY_ACTIVATION_THRESHOLD_RAD` above
the bottom of its travel), so the strike speed of a note that sounded at time t_on, in the
control step that started at t_s with the key at angle q_s, is the finite difference

    speed = lever * (threshold - q_s) / (t_on - t_s)      [m/s]

the mean downward speed of the key's front edge (``lever``: hinge-to-front length, 0.15 m
for a white key, 0.09 m for a black one, so both kinds compare in m/s) over the part of the
step before it sounded; the same over the window from the previous step's start is taken
when it is larger (a key that went most of the way down in the previous step). A key that
rested for part of the window reads slower than it struck: the estimate is a lower bound,
with the event times resolved to a physics substep (5 ms).

:func:`speed_to_velocity` maps the speed to MIDI velocity with a logarithmic curve (loudness
in dB grows about linearly with log hammer speed): 1 at :data:`SOFTEST_SPEED_M_S` or slower,
127 at :data:`LOUDEST_SPEED_M_S` or faster. The environment scores the loudness of its
strikes with these (the ``velocity`` reward term); :mod:`pianist.media.dynamics` measures a
whole performance's.
"""

from __future__ import annotations

import math

import numpy as np

from pianist.sim import constants as C

#: Key speed (m/s, at the key's front edge) that maps to MIDI velocity 1.
SOFTEST_SPEED_M_S = 0.02
#: Key speed (m/s) that maps to MIDI velocity 127.
LOUDEST_SPEED_M_S = 0.6
KEY_LEVER_M = np.where(C.BLACK_KEY_MASK, C.BLACK_KEY_LENGTH_M, C.WHITE_KEY_LENGTH_M)
"""(88,) hinge-to-front length of each key, metres."""


def strike_speeds(
    note_events: np.ndarray,
    key_angles: np.ndarray,
    control_timestep_s: float,
    threshold_rad: np.ndarray,
    lever_m: np.ndarray = KEY_LEVER_M,
) -> np.ndarray:
    """The strike speed of every key-on event (see the module docstring).

    Args:
        note_events: (n, 3) rows (time s, key 0-87 or -1 for the pedal, 1 on / 0 off).
        key_angles: (T + 1, 88) key hinge angles (rad) at times 0, dt, ..., T dt.
        control_timestep_s: dt, seconds.
        threshold_rad: (88,) angle at which each key sounds.
        lever_m: (88,) hinge-to-front length of each key, metres.
    Returns:
        (n,) m/s for key-on rows, NaN for key-off and pedal rows.
    """
    events = np.asarray(note_events, dtype=np.float64).reshape(-1, 3)
    angles = np.asarray(key_angles, dtype=np.float64)
    speeds = np.full(len(events), np.nan)
    on = np.flatnonzero((events[:, 1] >= 0) & (events[:, 2] != 0))
    if on.size == 0:
        return speeds
    keys = events[on, 1].astype(int)
    times = events[on, 0]
    threshold = np.asarray(threshold_rad, dtype=np.float64)[keys]
    # The step whose span (t_s, t_s + dt] holds the event: event times are substep ends.
    step = np.clip(np.ceil(times / control_timestep_s - 1e-9).astype(int) - 1, 0, len(angles) - 2)
    rate = np.zeros(len(on))
    # Windows from the start of that step and of the one before: a key that went most of the
    # way down in the previous step and tipped over its threshold at the first substep of this
    # one moved fast, which only the longer window sees. The key accelerates under the
    # finger, so a window's mean speed is at most the speed at the strike: take the larger.
    for back in (0, 1):
        first = step - back
        valid = first >= 0
        first = np.maximum(first, 0)
        travel = threshold - angles[first, keys]
        elapsed = times - first * control_timestep_s
        ok = valid & (travel > 0) & (elapsed > 1e-9)
        rate = np.where(ok, np.maximum(rate, travel / np.maximum(elapsed, 1e-9)), rate)
    # A key at or above its threshold at both starts (it bounced near the bottom and sounded
    # again) keeps 0: the softest velocity.
    speeds[on] = rate * np.asarray(lever_m, dtype=np.float64)[keys]
    return speeds


def speed_to_velocity(speed_m_s: np.ndarray | float) -> np.ndarray:
    """MIDI velocity 1..127 of a key speed: 1 + 126 * clip(log(v / soft) / log(loud / soft)).

    Monotone (non-decreasing) in the speed; NaN or non-positive speeds give 1.

    Args:
        speed_m_s: key speeds, m/s, any shape.
    Returns:
        int velocities of the same shape.
    """
    speed = np.asarray(speed_m_s, dtype=np.float64)
    safe = np.where(np.isfinite(speed) & (speed > 0), speed, SOFTEST_SPEED_M_S)
    x = np.log(safe / SOFTEST_SPEED_M_S) / math.log(LOUDEST_SPEED_M_S / SOFTEST_SPEED_M_S)
    return (1 + np.round(126 * np.clip(x, 0.0, 1.0))).astype(int)


def velocity_to_speed(velocity: np.ndarray | float) -> np.ndarray:
    """The key speed (m/s at the key's front edge) that :func:`speed_to_velocity` maps to
    ``velocity`` (MIDI 1..127, clipped to it): the inverse of the curve.

    Args:
        velocity: MIDI velocities, any shape.
    Returns:
        float speeds of the same shape, from :data:`SOFTEST_SPEED_M_S` to
        :data:`LOUDEST_SPEED_M_S`.
    """
    x = (np.clip(np.asarray(velocity, dtype=np.float64), 1.0, 127.0) - 1.0) / 126.0
    return SOFTEST_SPEED_M_S * (LOUDEST_SPEED_M_S / SOFTEST_SPEED_M_S) ** x
