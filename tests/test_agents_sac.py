"""SAC/DroQ/REDQ: loss term shapes, learning on a fixed batch, determinism, NumPy actor."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pianist.agents.config import SACConfig
from pianist.agents.policy import NumpyActor
from pianist.agents.replay import Batch
from pianist.agents.sac import actor_weights, make_agent, tanh_gaussian_sample

D, A, B = 7, 3, 16
TINY = SACConfig(
    hidden_dims=(16, 16),
    critic_dropout=0.01,
    critic_layer_norm=True,
    discount=0.8,
    batch_size=B,
    critic_lr=3e-3,
)
REDQ = dataclasses.replace(TINY, num_qs=4, num_min_qs=2, critic_dropout=0.0)


def _batch(seed=0, k=None):
    rng = np.random.default_rng(seed)
    lead = (B,) if k is None else (k, B)
    return Batch(
        obs=rng.standard_normal((*lead, D), dtype=np.float32),
        action=rng.uniform(-1, 1, (*lead, A)).astype(np.float32),
        reward=rng.standard_normal(lead, dtype=np.float32),
        discount=np.ones(lead, np.float32),
        next_obs=rng.standard_normal((*lead, D), dtype=np.float32),
    )


K = 4  # updates per jitted call in these tests: one compilation serves them all


@pytest.mark.parametrize("config", [TINY, REDQ], ids=["droq", "redq"])
def test_every_loss_term_has_its_shape(config):
    # Shapes by abstract evaluation: no compilation, so the tests stay fast.
    agent = make_agent(D, A, config)
    state = jax.eval_shape(agent.init, 0)
    batch = _batch()
    key = jax.random.PRNGKey(1)
    loss, terms = jax.eval_shape(agent.critic_loss, state.critic, state, batch, key)
    assert loss.shape == () and loss.dtype == jnp.float32
    assert terms["q"].shape == (config.num_qs, B)  # per critic and sample
    assert terms["target"].shape == (B,)
    assert terms["next_log_prob"].shape == (B,)
    loss, terms = jax.eval_shape(agent.actor_loss, state.actor, state, batch, key)
    assert loss.shape == ()
    assert terms["log_prob"].shape == (B,) and terms["q"].shape == (B,)
    entropy = jax.ShapeDtypeStruct((), jnp.float32)
    assert jax.eval_shape(agent.temperature_loss, state.log_temp, entropy).shape == ()
    assert agent.target_entropy == -A / 2
    new_state, metrics = jax.eval_shape(agent.update, state, batch)
    assert all(m.shape == () for m in metrics.values())
    assert jax.tree_util.tree_structure(new_state) == jax.tree_util.tree_structure(state)


def test_tanh_gaussian_log_prob_matches_the_change_of_variables():
    mean = jnp.array([[0.3, -1.0, 2.0]])
    log_std = jnp.array([[-0.5, 0.0, 0.2]])
    action, log_prob = tanh_gaussian_sample(mean, log_std, jax.random.PRNGKey(0))
    u = np.arctanh(np.asarray(action, np.float64))
    std = np.exp(np.asarray(log_std, np.float64))
    normal = -0.5 * ((u - np.asarray(mean)) / std) ** 2 - np.log(std) - 0.5 * np.log(2 * np.pi)
    expected = np.sum(normal - np.log(1 - np.tanh(u) ** 2), axis=-1)
    assert action.shape == (1, 3) and log_prob.shape == (1,)
    np.testing.assert_allclose(log_prob, expected, rtol=1e-4)


def test_updates_lower_the_critic_loss_on_a_fixed_batch():
    agent = make_agent(D, A, TINY)
    state = agent.init(0)
    fixed = Batch(*(np.stack([x] * K) for x in _batch(3)))
    state, first = agent.update_many(state, fixed)
    for _ in range(15):
        state, last = agent.update_many(state, fixed)
    assert int(state.updates) == 16 * K
    assert np.isfinite(float(last["critic_loss"]))
    assert float(last["critic_loss"]) < 0.5 * float(first["critic_loss"])


def test_same_seed_same_result():
    agent = make_agent(D, A, TINY)
    batches = _batch(4, k=K)
    one, _ = agent.update_many(agent.init(7), batches)
    two, _ = agent.update_many(agent.init(7), batches)
    for a, b in zip(jax.tree_util.tree_leaves(one), jax.tree_util.tree_leaves(two), strict=True):
        np.testing.assert_array_equal(a, b)
    other, _ = agent.update_many(agent.init(8), batches)
    assert not np.array_equal(other.actor["mean"]["kernel"], one.actor["mean"]["kernel"])


def test_numpy_actor_matches_the_flax_actor():
    agent = make_agent(D, A, TINY)
    state = agent.init(0)
    obs = _batch().obs
    mean, log_std = agent.actor_def.apply({"params": state.actor}, obs)
    actor = NumpyActor(actor_weights(state.actor), "gelu", TINY.log_std_min, TINY.log_std_max)
    np_mean, np_log_std = actor.distribution(obs)
    np.testing.assert_allclose(np_mean, mean, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(np_log_std, log_std, rtol=1e-4, atol=1e-5)
    sample = actor.sample(obs[0], np.random.default_rng(0))
    assert sample.shape == (A,) and np.all(np.abs(sample) <= 1)
