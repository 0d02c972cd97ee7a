"""Residual learning on top of the planner: the anchored preset starts as the planner, explores
near it, and the run keeps its best evaluated policy."""

import dataclasses
import json
import math

import numpy as np
import pytest

from pianist.agents import PolicyController, get_preset, train
from pianist.agents.checkpoint import best_evaluation, latest_checkpoint
from pianist.agents.envs import Featurizer, make_agent_env
from pianist.agents.policy import NumpyActor
from pianist.control.planner import IKPlanner
from pianist.eval import run_episode

SONG = "twinkle-twinkle"  # right hand only: 161 steps
BASE = get_preset("residual-anchored")
TINY = dataclasses.replace(
    BASE,
    agent=dataclasses.replace(BASE.agent, hidden_dims=(16, 16), batch_size=16),
    seed_steps=100,
    steps_per_iteration=1,
    eval_interval=100,
    checkpoint_interval=1000,
    replay_capacity=1000,
)
STEPS = 322  # two episodes


def _initial_actor(config):
    import jax

    from pianist.agents.sac import actor_weights, make_agent

    env = make_agent_env(SONG, config.task)
    features = Featurizer(env, config.task)
    agent = make_agent(features.obs_dim, features.action_dim, config.agent)
    zeros = np.zeros((1, features.obs_dim), np.float32)
    params = agent.actor_def.init(jax.random.PRNGKey(config.seed), zeros)["params"]
    a = config.agent
    weights = actor_weights(params)
    return env, features, NumpyActor(weights, a.activation, a.log_std_min, a.log_std_max)


def test_the_zero_initialised_residual_policy_plays_the_planner():
    env, features, actor = _initial_actor(TINY)
    obs, _ = env.reset(seed=0)
    features.reset(env, 0)
    planner = IKPlanner()
    planner.reset(env, 0)
    x = features(obs)
    policy_action = features.env_action(actor.mean_action(x).astype(np.float32))
    np.testing.assert_array_equal(policy_action, planner.act(obs))
    # The initial std is state independent and exp(init_log_std) in every dimension.
    rng = np.random.default_rng(0)
    _, log_std = actor.distribution(rng.standard_normal((5, features.obs_dim), np.float32))
    np.testing.assert_allclose(log_std, TINY.agent.init_log_std, atol=1e-6)
    # And the whole episode scores what the planner scores.
    ours = run_episode(env, PolicyController.from_actor(TINY, actor), seed=0).metrics()
    theirs = run_episode(env, IKPlanner(), seed=0).metrics()
    assert ours["f1"] == theirs["f1"] and ours["recall"] == theirs["recall"]


def test_the_residual_penalty_adds_the_mean_actions_size_to_the_actor_loss():
    jax = pytest.importorskip("jax")
    from pianist.agents.replay import Batch
    from pianist.agents.sac import SAC

    D, A, B, weight = 6, 3, 4, 2.5
    agent_cfg = dataclasses.replace(
        TINY.agent, zero_mean_init=False, init_log_std=None, residual_penalty=weight
    )
    agent = SAC(D, A, agent_cfg)
    state = jax.jit(agent.init)(3)  # compiled: faster than running the init op by op
    rng = np.random.default_rng(1)
    obs = rng.standard_normal((B, D), np.float32)
    batch = Batch(obs, np.zeros((B, A), np.float32), np.zeros(B), np.ones(B), obs)
    loss, terms = jax.jit(agent.actor_loss)(state.actor, state, batch, jax.random.PRNGKey(0))
    mean, _ = agent.actor_def.apply({"params": state.actor}, obs)
    size = np.sum(np.tanh(np.asarray(mean)) ** 2, axis=-1)
    assert size.min() > 0  # Xavier-initialised here: a non-zero mean action
    np.testing.assert_allclose(np.asarray(terms["size"]), size, rtol=1e-5)
    temperature = float(np.exp(state.log_temp))
    plain = np.mean(temperature * np.asarray(terms["log_prob"]) - np.asarray(terms["q"]))
    np.testing.assert_allclose(float(loss), plain + weight * size.mean(), rtol=1e-4)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("residual")
    result = train(SONG, TINY, STEPS, out, progress=False)
    return out, result


def test_seed_steps_sample_the_initial_actor_near_the_planner(run_dir):
    out, _ = run_dir
    with np.load(latest_checkpoint(out) / "replay.npz") as replay:
        seed_actions = replay["action"][: TINY.seed_steps]
    # tanh(N(0, 0.1^2)): centred, std ~0.1, nothing near the uniform's +-1.
    assert abs(seed_actions.mean()) < 0.01
    assert 0.08 < seed_actions.std() < 0.12
    assert np.abs(seed_actions).max() < 0.6


def test_the_run_keeps_its_best_evaluated_policy(run_dir):
    out, result = run_dir
    rows = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
    evals = [r for r in rows if r["kind"] == "eval"]
    assert [r["step"] for r in evals] == [100, 200, 300, STEPS]
    best = best_evaluation(out)
    assert best is not None and best == result.best_eval
    assert best["f1"] == max(r["f1"] for r in evals)
    first_best = next(r for r in evals if r["f1"] == best["f1"])
    assert best["step"] == first_best["step"]  # ties keep the earlier policy
    # No update before the first evaluation: it scores the planner alone.
    env = make_agent_env(SONG, TINY.task)
    planner_f1 = run_episode(env, IKPlanner(), seed=TINY.seed).metrics()["f1"]
    assert evals[0]["updates"] == 0 and math.isclose(evals[0]["f1"], planner_f1)
    # The kept policy is a run directory of its own: re-evaluating it gives its F1 again.
    controller = PolicyController(out / "best")
    assert controller.step == best["step"]
    again = run_episode(controller.make_env(SONG), controller, seed=TINY.seed).metrics()
    assert again["f1"] == best["f1"]


def test_a_new_run_starts_without_an_old_best(tmp_path):
    (tmp_path / "best").mkdir()
    (tmp_path / "best" / "stale").write_text("x")
    short = dataclasses.replace(TINY, eval_interval=1000)
    train(SONG, short, 20, tmp_path, progress=False)
    assert not (tmp_path / "best" / "stale").exists()
    assert best_evaluation(tmp_path)["step"] == 20
