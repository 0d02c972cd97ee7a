"""The pure reward functions, against hand-computed values (facts page, section 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pianist.env.config import RewardWeights
from pianist.env.rewards import (
    energy,
    fingering_reward,
    forearm_reward,
    key_press_reward,
    sustain_reward,
    tolerance,
)

# Gaussian tolerance: value 0.1 at one margin outside, so 0.1 ** (d ** 2) at d margins.


def gauss(d_margins: float) -> float:
    return 0.1 ** (d_margins**2)


# --------------------------------------------------------------------------------- tolerance


def test_tolerance_inside_bounds_is_one() -> None:
    x = np.array([0.0, 0.02, 0.05])
    np.testing.assert_array_equal(tolerance(x, (0.0, 0.05), 0.5), [1.0, 1.0, 1.0])
    assert float(tolerance(0.3, (0.3, 0.3), 0.1)) == 1.0


@pytest.mark.parametrize(
    ("x", "expected"),
    [
        (0.55, 0.1),  # one margin above the upper bound
        (-0.5, 0.1),  # one margin below the lower bound
        (0.3, gauss(0.5)),  # half a margin outside
        (1.05, gauss(2.0)),  # two margins: 1e-4
        (0.05 + 1e-12, 1.0),
    ],
)
def test_tolerance_gaussian_margin(x: float, expected: float) -> None:
    assert float(tolerance(x, (0.0, 0.05), 0.5)) == pytest.approx(expected, rel=1e-9)


def test_tolerance_shape_and_monotonic() -> None:
    x = np.linspace(0.05, 2.0, 50).reshape(5, 10)
    out = tolerance(x, (0.0, 0.05), 0.5)
    assert out.shape == (5, 10)
    flat = out.ravel()
    assert np.all(np.diff(flat) < 0) and np.all((flat > 0) & (flat <= 1))


def test_tolerance_zero_margin_is_a_step() -> None:
    x = np.array([-1e-9, 0.0, 0.5, 1.0, 1.0 + 1e-9, 5.0])
    np.testing.assert_array_equal(tolerance(x, (0.0, 1.0), 0.0), [0, 1, 1, 1, 0, 0])


# --------------------------------------------------------------------------------- key press


def _keys(*indices: int) -> np.ndarray:
    out = np.zeros(88, dtype=bool)
    out[list(indices)] = True
    return out


def test_key_press_all_due_pressed_nothing_wrong() -> None:
    due = _keys(39, 43, 46)
    state = due.astype(float)
    assert key_press_reward(state, due, due.copy()) == pytest.approx(1.0)
    # 96 % down is within the 0.05 bound: still full marks.
    assert key_press_reward(np.where(due, 0.96, 0.0), due, due.copy()) == pytest.approx(1.0)


def test_key_press_nothing_due_nothing_wrong() -> None:
    none = np.zeros(88, dtype=bool)
    assert key_press_reward(np.zeros(88), none, none) == pytest.approx(0.5)
    # A key pushed part way (not sounding) is not a wrong press.
    assert key_press_reward(np.where(_keys(10), 0.7, 0.0), none, none) == pytest.approx(0.5)


def test_key_press_partial_pressing() -> None:
    due = _keys(20, 21)
    state = np.zeros(88)
    state[20] = 1.0  # fully down
    state[21] = 0.55  # 1 - 0.55 = 0.45 -> 0.4 outside the bound, 0.8 margins
    expected = 0.5 * (1.0 + gauss(0.8)) / 2 + 0.5
    assert key_press_reward(state, due, _keys(20)) == pytest.approx(expected)
    # Nothing pressed: tolerance(1.0) = 0.1 ** (1.9 ** 2) for each due key.
    assert key_press_reward(np.zeros(88), due, np.zeros(88, bool)) == pytest.approx(
        0.5 * gauss(1.9) + 0.5
    )


def test_wrong_keys_cost_exactly_half_whatever_their_number() -> None:
    due = _keys(39)
    state = due.astype(float)
    clean = key_press_reward(state, due, due.copy())
    one_wrong = key_press_reward(state, due, _keys(39, 50))
    five_wrong = key_press_reward(state, due, _keys(39, 50, 51, 52, 60, 0))
    assert clean == pytest.approx(1.0)
    assert one_wrong == pytest.approx(clean - 0.5)
    assert five_wrong == pytest.approx(one_wrong)
    none = np.zeros(88, dtype=bool)
    assert key_press_reward(np.zeros(88), none, _keys(3)) == pytest.approx(0.0)


# --------------------------------------------------------------------------------- fingering


def test_fingering_reward_values() -> None:
    tip = np.array([[0.1, 0.2, 0.05]])
    assert fingering_reward(tip, tip.copy()) == pytest.approx(1.0)
    # 0.01 m is the edge of the bounds; 0.11 m is one margin (0.1 m) beyond it.
    assert fingering_reward(tip, tip + [0.0, 0.01, 0.0]) == pytest.approx(1.0)
    assert fingering_reward(tip, tip + [0.0, 0.0, 0.11]) == pytest.approx(0.1)
    # Euclidean distance: (0.066, 0.088, 0) is 0.11 m.
    assert fingering_reward(tip, tip + [0.066, 0.088, 0.0]) == pytest.approx(0.1)


def test_fingering_reward_mean_and_empty() -> None:
    tips = np.zeros((2, 3))
    targets = np.array([[0.0, 0.0, 0.0], [0.11, 0.0, 0.0]])
    assert fingering_reward(tips, targets) == pytest.approx(0.55)
    assert fingering_reward(np.zeros((0, 3)), np.zeros((0, 3))) == 0.0


# --------------------------------------------------------------------------------- others


def test_energy_is_sum_of_abs_force_times_abs_velocity() -> None:
    force = np.array([1.0, -2.0, 3.0, 0.0])
    velocity = np.array([-4.0, 0.5, 2.0, 100.0])
    assert energy(force, velocity) == pytest.approx(4.0 + 1.0 + 6.0)
    assert energy(np.zeros(3), np.ones(3)) == 0.0


def test_sustain_reward() -> None:
    assert sustain_reward(True, True) == pytest.approx(1.0)
    assert sustain_reward(False, False) == pytest.approx(1.0)
    # Due but not pressed: 1 - 0.05 = 0.95 outside, 1.9 margins.
    assert sustain_reward(True, False) == pytest.approx(gauss(1.9))
    assert sustain_reward(False, True) < 1e-3
    assert isinstance(sustain_reward(True, True), float)


def test_forearm_reward() -> None:
    assert forearm_reward(False) == 0.5
    assert forearm_reward(True) == 0.0


def test_default_weights() -> None:
    w = RewardWeights()
    assert (w.key_press, w.fingering, w.energy, w.sustain, w.forearm) == (1, 1, -5e-3, 1, 1)
    terms = ["key_press", "fingering", "energy", "sustain", "forearm", "velocity"]
    assert list(w.as_dict()) == terms
    assert math.isclose(RewardWeights(energy=-1.0).as_dict()["energy"], -1.0)
