"""The batched environment: same results as the single one, Gymnasium vector semantics."""

import numpy as np
import pytest

from pianist.env import PianoEnv
from pianist.env.vector import PianoVectorEnv
from pianist.music import Note, Song

TINY = Song(notes=(Note(60, 0.0, 0.1, finger=1), Note(64, 0.1, 0.2, finger=6)), name="tiny")


def test_batch_of_one_matches_single_env_bit_for_bit():
    single = PianoEnv(TINY, physics="fast")
    batched = PianoVectorEnv(TINY, 1, physics="fast")
    obs_s, _ = single.reset(seed=3)
    obs_b, _ = batched.reset(seed=3)
    actions = np.random.default_rng(0).uniform(-1, 1, (single.num_steps, 39))
    for action in actions:
        obs_s, r_s, term_s, trunc_s, info_s = single.step(action)
        obs_b, r_b, term_b, trunc_b, info_b = batched.step(action[None])
        for key in obs_s:
            np.testing.assert_array_equal(obs_b[key][0], obs_s[key])
        assert r_b[0] == r_s and term_b[0] == term_s and trunc_b[0] == trunc_s
        np.testing.assert_array_equal(info_b["active_keys"][0], info_s["active_keys"])
    batched.close()


def test_two_envs_on_threads_match_two_single_envs():
    batched = PianoVectorEnv(TINY, 2, physics="fast", num_threads=2)
    singles = [PianoEnv(TINY, physics="fast") for _ in range(2)]
    batched.reset(seed=0)
    for i, env in enumerate(singles):
        env.reset(seed=i)
    rng = np.random.default_rng(1)
    for _ in range(3):
        actions = rng.uniform(-1, 1, (2, 39))
        _, rewards, *_ = batched.step(actions)
        expected = [env.step(a)[1] for env, a in zip(singles, actions, strict=True)]
        np.testing.assert_array_equal(rewards, expected)
    batched.close()


def test_spaces_shapes_and_next_step_autoreset():
    venv = PianoVectorEnv(TINY, 3, physics="fast")
    obs, info = venv.reset(seed=0)
    assert venv.action_space.shape == (3, 39)
    assert obs["goal"].shape == (3, 11, 89)
    assert venv.observation_space.contains(obs)
    steps = PianoEnv(TINY).num_steps
    zero = np.zeros((3, 39))
    for _ in range(steps - 1):
        _, _, terminated, truncated, _ = venv.step(zero)
        assert not truncated.any() and not terminated.any()
    obs, rewards, terminated, truncated, info = venv.step(zero)
    assert truncated.all()
    # Next-step autoreset: the following step resets, returns the first observation, reward 0.
    obs, rewards, terminated, truncated, info = venv.step(zero)
    assert not truncated.any() and np.all(rewards == 0)
    np.testing.assert_array_equal(
        obs["goal"][:, 0, :88],
        np.repeat(PianoEnv(TINY).reset(seed=0)[0]["goal"][None, 0, :88], 3, axis=0),
    )
    venv.close()


def test_bad_action_shape_is_rejected():
    venv = PianoVectorEnv(TINY, 2, physics="fast")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((3, 39)))
    venv.close()


def test_single_env_works_inside_gymnasiums_own_vector_env():
    import gymnasium as gym

    venv = gym.vector.SyncVectorEnv([lambda: PianoEnv(TINY, physics="fast")] * 2)
    venv.reset(seed=0)
    steps = PianoEnv(TINY).num_steps
    for _ in range(steps):
        obs, rewards, terminated, truncated, info = venv.step(np.zeros((2, 39)))
    assert truncated.all()
    assert obs["goal"].shape == (2, 11, 89)
    assert len(info["note_events"]) == 2  # variable-length events survive the batching
    venv.close()
