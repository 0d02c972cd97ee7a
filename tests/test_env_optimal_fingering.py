"""The label-free fingering reward: fingertips matched to due keys by optimal assignment."""

from __future__ import annotations

import numpy as np
import pytest

from pianist.env import PianoEnv
from pianist.env.config import make_config
from pianist.env.rewards import fingering_reward, optimal_fingering_reward
from pianist.music import get_song, strip_fingering


def test_any_fingertip_may_take_any_key() -> None:
    keys = np.array([[0.0, 0.0, 0.0], [0.0, 0.1, 0.0]])
    tips = np.array([[0.0, 0.1, 0.0], [0.5, 0.5, 0.5], [0.0, 0.0, 0.0]])
    assert optimal_fingering_reward(tips, keys) == pytest.approx(1.0)
    # The labelled reward with the wrong labels scores far less.
    assert fingering_reward(tips[:2], keys) < 0.5


def test_matches_the_labelled_reward_when_labels_are_optimal() -> None:
    rng = np.random.default_rng(0)
    keys = rng.uniform(-0.3, 0.3, size=(3, 3))
    tips = keys + rng.normal(0, 0.02, size=(3, 3))
    far = np.full((7, 3), 5.0)  # other fingertips far away
    expected = fingering_reward(tips, keys)
    assert optimal_fingering_reward(np.concatenate([far, tips]), keys) == pytest.approx(expected)


def test_more_keys_than_fingertips_and_nothing_due() -> None:
    keys = np.zeros((3, 3))
    assert optimal_fingering_reward(np.zeros((2, 3)), keys) == pytest.approx(2 / 3)
    assert optimal_fingering_reward(np.zeros((10, 3)), np.zeros((0, 3))) == 0.0


def test_environment_option_without_labels() -> None:
    song = strip_fingering(get_song("c-major-chords"))
    env = PianoEnv(song, physics="fast", lookahead=1, fingering_reward="optimal")
    assert env.config.fingering_reward == "optimal"
    env.reset(seed=0)
    terms = []
    for _ in range(5):
        _, _, _, _, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        terms.append(info["reward_terms"]["fingering"])
    assert all(0.0 < t <= 1.0 for t in terms)
    labelled = PianoEnv(song, physics="fast", lookahead=1)
    labelled.reset(seed=0)
    _, _, _, _, info = labelled.step(np.zeros(labelled.action_space.shape, dtype=np.float32))
    assert info["reward_terms"]["fingering"] == 0.0  # no labels: the paper's term is empty


def test_unknown_option() -> None:
    with pytest.raises(ValueError, match="fingering_reward"):
        make_config(fingering_reward="greedy")
