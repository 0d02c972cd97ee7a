"""Action sequences as splines through a few knots (the search space of predictive sampling).

A plan over a horizon is ``K`` knots evenly spaced in time from 0 to the horizon, each an
action vector. Every interpolation used here is linear in the knot values, so evaluating a
plan at fixed times is one matrix product: ``values = weights @ knots`` with
``weights = interpolation_weights(times, ...)`` of shape (T, K). Outside the knots the plan
holds its first / last value.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

Interpolation = Literal["zero", "linear", "cubic"]
INTERPOLATIONS: tuple[str, ...] = ("zero", "linear", "cubic")


def knot_times(num_knots: int, horizon_s: float) -> np.ndarray:
    """(K,) knot times in s, evenly spaced over [0, horizon_s] (a single knot sits at 0)."""
    if num_knots < 1:
        raise ValueError(f"a spline needs at least one knot, not {num_knots}")
    if not horizon_s > 0:
        raise ValueError(f"the horizon must be positive, not {horizon_s} s")
    if num_knots == 1:
        return np.zeros(1)
    return np.linspace(0.0, horizon_s, num_knots)


def _slope_matrix(times: np.ndarray) -> np.ndarray:
    """(K, K) map from knot values to finite-difference slopes at the knots.

    Interior knots take the centred difference (p[i+1] - p[i-1]) / (t[i+1] - t[i-1]), the two
    ends the one-sided difference; with two knots the cubic is then exactly the straight line.
    """
    K = len(times)
    D = np.zeros((K, K))
    for i in range(K):
        lo, hi = max(i - 1, 0), min(i + 1, K - 1)
        D[i, hi] += 1.0 / (times[hi] - times[lo])
        D[i, lo] -= 1.0 / (times[hi] - times[lo])
    return D


def interpolation_weights(
    t: np.ndarray, times: np.ndarray, interpolation: Interpolation = "cubic"
) -> np.ndarray:
    """Weights that evaluate a spline at times ``t``.

    Args:
        t: (T,) evaluation times in s.
        times: (K,) increasing knot times in s.
        interpolation: ``zero`` (hold the last knot at or before t), ``linear``, or ``cubic``
            (Hermite with finite-difference slopes; C1, passes through every knot).
    Returns:
        (T, K) array W: the spline's values at ``t`` are ``W @ knots`` for knots of shape (K, A).
    """
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"unknown interpolation {interpolation!r}; use one of {INTERPOLATIONS}")
    t = np.atleast_1d(np.asarray(t, dtype=float))
    times = np.asarray(times, dtype=float)
    K = len(times)
    W = np.zeros((len(t), K))
    if K == 1:
        W[:, 0] = 1.0
        return W
    if np.any(np.diff(times) <= 0):
        raise ValueError("knot times must be strictly increasing")
    tc = np.clip(t, times[0], times[-1])
    # Segment i covers [times[i], times[i+1]); the last knot belongs to the last segment.
    seg = np.clip(np.searchsorted(times, tc, side="right") - 1, 0, K - 2)
    width = times[seg + 1] - times[seg]
    s = (tc - times[seg]) / width
    rows = np.arange(len(t))
    if interpolation == "zero":
        at_end = tc >= times[-1]
        W[rows, np.where(at_end, K - 1, seg)] = 1.0
        return W
    if interpolation == "linear":
        W[rows, seg] += 1.0 - s
        W[rows, seg + 1] += s
        return W
    # Cubic Hermite basis on the unit interval; slopes scaled by the segment width.
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    D = _slope_matrix(times)
    W[rows, seg] += h00
    W[rows, seg + 1] += h01
    W += (h10 * width)[:, None] * D[seg] + (h11 * width)[:, None] * D[seg + 1]
    return W


def evaluate(
    knots: np.ndarray, times: np.ndarray, t: np.ndarray, interpolation: Interpolation = "cubic"
) -> np.ndarray:
    """Values of the spline(s) through ``knots`` at times ``t``.

    Args:
        knots: (..., K, A) knot values.
        times: (K,) knot times in s.
        t: (T,) evaluation times in s.
    Returns:
        (..., T, A) values.
    """
    return interpolation_weights(t, times, interpolation) @ knots
