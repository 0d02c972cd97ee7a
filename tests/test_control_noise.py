"""NoisyController: another controller's actions plus seeded Gaussian noise, clipped."""

import numpy as np
import pytest

from pianist.control import NoisyController, ZeroController
from pianist.env import PianoEnv
from pianist.eval import run_episode


def _actions(sigma, seed):
    env = PianoEnv("c-major-chords", physics="fast")
    return run_episode(env, NoisyController(ZeroController(), sigma), seed=seed).actions


def test_noise_has_the_asked_std_and_stays_in_range():
    base = run_episode(PianoEnv("c-major-chords", physics="fast"), ZeroController(), seed=0)
    noisy = _actions(0.05, seed=0)
    assert noisy.shape == base.actions.shape
    assert np.all(np.abs(noisy) <= 1.0)
    # The pedal sits at -1, so its noise is clipped on one side: look at the joints only.
    diff = noisy[:, :-1] - base.actions[:, :-1]
    assert 0.04 < diff.std() < 0.06 and abs(diff.mean()) < 0.01


def test_same_seed_same_noise_other_seed_other_noise():
    np.testing.assert_array_equal(_actions(0.01, seed=3), _actions(0.01, seed=3))
    assert not np.array_equal(_actions(0.01, seed=3), _actions(0.01, seed=4))


def test_negative_std_is_refused():
    with pytest.raises(ValueError, match="noise std"):
        NoisyController(ZeroController(), -0.1)
