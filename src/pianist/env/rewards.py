"""Reward terms as small pure functions (facts page, section 3).

Each returns a float; :func:`pianist.env.piano_env.PianoEnv` weights and sums them and reports
every raw term in ``info["reward_terms"]``.
"""

from __future__ import annotations

import math

import numpy as np

KEY_PRESS_BOUNDS = (0.0, 0.05)
KEY_PRESS_MARGIN = 0.5
FINGERING_BOUNDS_M = (0.0, 0.01)
FINGERING_MARGIN_M = 0.1
SUSTAIN_BOUNDS = (0.0, 0.05)
SUSTAIN_MARGIN = 0.5
FOREARM_CLEAR_REWARD = 0.5
# dm_control's convention: the Gaussian falls to this value one margin outside the bounds.
VALUE_AT_MARGIN = 0.1
_GAUSSIAN_SCALE = math.sqrt(-2.0 * math.log(VALUE_AT_MARGIN))


def tolerance(x: np.ndarray | float, bounds: tuple[float, float], margin: float) -> np.ndarray:
    """1 inside ``bounds``, a Gaussian falling to 0.1 at ``margin`` outside them.

    Args:
        x: values, any shape.
        bounds: (lower, upper), lower <= upper.
        margin: distance outside the bounds at which the value is 0.1; 0 gives a hard step.
    Returns:
        Array of x's shape with values in [0, 1].
    """
    x = np.asarray(x, dtype=float)
    lower, upper = bounds
    # Distance outside the bounds, 0 inside: one expression covers both sides.
    outside = np.maximum(np.maximum(lower - x, x - upper), 0.0)
    if margin <= 0:
        return (outside == 0.0).astype(float)
    return np.exp(-0.5 * (outside * (_GAUSSIAN_SCALE / margin)) ** 2)


def _scalar_tolerance(x: float, bounds: tuple[float, float], margin: float) -> float:
    """:func:`tolerance` of one number, without NumPy's per-call overhead."""
    outside = max(bounds[0] - x, x - bounds[1], 0.0)
    if margin <= 0:
        return float(outside == 0.0)
    return math.exp(-0.5 * (outside * _GAUSSIAN_SCALE / margin) ** 2)


def key_press_reward(
    key_state: np.ndarray,
    due: np.ndarray,
    active: np.ndarray,
    due_keys: np.ndarray | None = None,
) -> float:
    """Press the due keys, and sound nothing else.

    Args:
        key_state: (88,) normalised key depression in [0, 1].
        due: (88,) bool, keys the goal wants sounding this step.
        active: (88,) bool, keys sounding now.
        due_keys: ``np.flatnonzero(due)`` if the caller has it already.
    Returns:
        0.5 * mean over due keys of tolerance(1 - state) (0 when nothing is due) plus 0.5 when
        no key that is not due sounds: a constant penalty, whatever the number of wrong keys.
    """
    if due_keys is None:
        due_keys = np.flatnonzero(due)
    pressed = 0.0
    if due_keys.size:
        closeness = tolerance(1.0 - key_state[due_keys], KEY_PRESS_BOUNDS, KEY_PRESS_MARGIN)
        pressed = float(closeness.sum()) / due_keys.size
    no_wrong = not np.any(active > due)  # a key sounding that is not due
    return 0.5 * pressed + 0.5 * float(no_wrong)


def fingering_reward(fingertip_pos: np.ndarray, key_target_pos: np.ndarray) -> float:
    """Bring each assigned fingertip to its key.

    Args:
        fingertip_pos: (n, 3) m, the fingertip assigned to each due key.
        key_target_pos: (n, 3) m, the strike point of each of those keys.
    Returns:
        Mean tolerance of the distances (0 when n = 0).
    """
    n = len(fingertip_pos)
    if n == 0:
        return 0.0
    distance = np.sqrt(np.square(fingertip_pos - key_target_pos).sum(axis=-1))
    return float(tolerance(distance, FINGERING_BOUNDS_M, FINGERING_MARGIN_M).sum()) / n


def optimal_fingering_reward(fingertip_pos: np.ndarray, key_target_pos: np.ndarray) -> float:
    """Bring the fingertips to the due keys, whichever fingertip goes to whichever key.

    Each step, fingertips are matched one-to-one to the due keys by a minimum total distance
    assignment (Hungarian algorithm, ``scipy.optimize.linear_sum_assignment``), and the
    matched distances are scored as in :func:`fingering_reward` (RP1M's label-free reward).

    Args:
        fingertip_pos: (m, 3) m, every fingertip that may play (10 with both hands).
        key_target_pos: (n, 3) m, the strike point of each due key.
    Returns:
        Sum of the tolerances of the matched distances divided by n (a key left without a
        fingertip, when n > m, scores 0); 0 when n = 0.
    """
    from scipy.optimize import linear_sum_assignment

    n = len(key_target_pos)
    if n == 0 or len(fingertip_pos) == 0:
        return 0.0
    distance = np.sqrt(
        np.square(fingertip_pos[:, None, :] - key_target_pos[None, :, :]).sum(axis=-1)
    )  # (m, n)
    rows, cols = linear_sum_assignment(distance)
    matched = distance[rows, cols]
    return float(tolerance(matched, FINGERING_BOUNDS_M, FINGERING_MARGIN_M).sum()) / n


def energy(actuator_force: np.ndarray, actuator_velocity: np.ndarray) -> float:
    """Mechanical power spent by the actuators, sum |force| |velocity| (W); weight it < 0."""
    return float(np.abs(actuator_force) @ np.abs(actuator_velocity))


def sustain_reward(goal_sustain: bool, sustain_active: bool) -> float:
    """1 when the pedal matches the goal, 0.1**(1.9**2) ~ 0 otherwise."""
    return _scalar_tolerance(
        float(goal_sustain) - float(sustain_active), SUSTAIN_BOUNDS, SUSTAIN_MARGIN
    )


def forearm_reward(forearms_touch: bool) -> float:
    """0.5 while the two forearms are apart."""
    return 0.0 if forearms_touch else FOREARM_CLEAR_REWARD


def velocity_reward(played: np.ndarray, target: np.ndarray) -> float:
    """Minus the mean absolute difference, over the due keys struck this step, between the
    MIDI velocity each sounded (``played`` (n,)) and the score's (``target`` (n,)), divided
    by 127: 0 when every strike is as loud as written (or none was made), -1 at worst."""
    if len(played) == 0:
        return 0.0
    diff = np.abs(np.asarray(played, dtype=np.float64) - np.asarray(target, dtype=np.float64))
    return -float(diff.mean()) / 127.0
