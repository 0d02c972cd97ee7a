"""Practising the hard parts: window episodes started from snapshots, the window sampler, and a
short training run with windows that resumes exactly."""

import dataclasses
import json

import numpy as np
import pytest

from pianist.agents import get_preset, train
from pianist.agents.checkpoint import latest_checkpoint, load_state
from pianist.agents.envs import Featurizer, make_agent_env
from pianist.agents.windows import (
    Windows,
    WindowStart,
    record_windows,
    start_window,
    window_starts,
)

SONG = "twinkle-twinkle"  # 161 steps of 0.05 s, right hand
WINDOW, STRIDE = 40, 20  # steps: 2 s windows every second


def _play(env, features, obs, actions=None, steps=None):
    """Features and rewards of the steps from ``obs`` on: the residual policy with a zero
    correction (the planner), or the given env actions."""
    zero = np.zeros(features.action_dim, np.float32)
    xs, rewards, played = [], [], []
    done = False
    while not done and (steps is None or len(rewards) < steps):
        xs.append(features(obs))
        a = features.env_action(zero) if actions is None else actions[len(rewards)]
        played.append(a)
        obs, reward, terminated, truncated, _ = env.step(a)
        rewards.append(reward)
        done = terminated or truncated
    xs.append(features(obs))
    return np.stack(xs), np.array(rewards), np.stack(played)


@pytest.mark.parametrize("preset", ["residual-windows", "fast"])
def test_a_window_started_from_a_snapshot_repeats_the_continuous_run(preset):
    task = get_preset(preset).task
    env = make_agent_env(SONG, task)
    features = Featurizer(env, task)
    windows, f1 = record_windows(env, features, WINDOW, STRIDE, seed=3)
    assert [s.step for s in windows.starts] == window_starts(env.num_steps, WINDOW, STRIDE)
    assert windows.starts[-1].step == env.num_steps - WINDOW and f1.shape == (env.num_steps,)
    # The uninterrupted episode: the planner acts (through the residual's own planner, or, for
    # the plain task, a planner's actions replayed).
    obs, _ = env.reset(seed=3)
    features.reset(env, 3)
    actions = None
    if not task.residual:
        from pianist.control.planner import IKPlanner

        planner = IKPlanner()
        planner.reset(env, 3)
        actions = []
        for _ in range(env.num_steps):
            actions.append(planner.act(obs))
            obs, *_ = env.step(actions[-1])
        obs, _ = env.reset(seed=3)
        features.reset(env, 3)
    xs, rewards, _ = _play(env, features, obs, actions)
    assert rewards.std() > 0  # a real performance, with notes pressed and missed
    for i in range(len(windows)):  # the planner's memory matters at some of them
        start = windows.starts[i]
        obs = start_window(env, features, start, seed=99)  # another seed: the state decides
        assert env.step_index == start.step
        tail = None if actions is None else actions[start.step :]
        wx, wr, _ = _play(env, features, obs, tail, steps=int(windows.ends[i]) - start.step)
        n = len(wr)
        assert n == WINDOW
        np.testing.assert_array_equal(wx, xs[start.step : start.step + n + 1])
        np.testing.assert_array_equal(wr, rewards[start.step : start.step + n])


def _windows(errors):
    starts = [WindowStart(10 * i, None, None) for i in range(len(errors))]
    return Windows(starts, np.array([10 * i + 20 for i in range(len(errors))]), np.array(errors))


def test_the_sampler_draws_windows_with_errors_more_often_and_every_window_sometimes():
    errors = [0.0, 0.0, 0.6, 0.0, 0.15, 0.0, 0.0, 0.0]
    windows = _windows(errors)
    rng = np.random.default_rng(0)
    n = 8000
    counts = np.bincount([windows.draw(rng, 1.0, 0.2) for _ in range(n)], minlength=len(errors))
    np.testing.assert_array_equal(counts, windows.draws)
    p = windows.probabilities(1.0, 0.2)
    assert abs(p.sum() - 1) < 1e-12
    # The counts follow the probabilities (within 5 standard deviations)...
    assert np.all(np.abs(counts - n * p) < 5 * np.sqrt(n * p * (1 - p)))
    # ...which favour the errors: the worst window most, then the next, the clean ones least.
    assert counts[2] > counts[4] > counts[[0, 1, 3, 5, 6, 7]].max()
    assert counts[2] > 0.4 * n and counts.min() > 0.02 * n  # the uniform share reaches all
    # Power 0 or an all-uniform share: uniform.
    np.testing.assert_allclose(windows.probabilities(0.0, 0.2), 1 / len(errors))
    np.testing.assert_allclose(windows.probabilities(2.0, 1.0), 1 / len(errors))
    # The same seed draws the same windows.
    a, b = _windows(errors), _windows(errors)
    ra, rb = np.random.default_rng(5), np.random.default_rng(5)
    assert [a.draw(ra, 2.0, 0.1) for _ in range(200)] == [b.draw(rb, 2.0, 0.1) for _ in range(200)]


def test_window_errors_follow_the_evaluation_and_the_window_episodes():
    windows = _windows([1.0, 1.0, 1.0])  # windows [0, 20), [10, 30), [20, 40)
    f1 = np.ones(40)
    f1[25:30] = 0.0  # five bad steps
    windows.record_evaluation(f1)
    np.testing.assert_allclose(windows.errors, [0.0, 0.25, 0.25])
    windows.record_evaluation(f1[:30])  # ended early: the unplayed steps count as F1 0
    np.testing.assert_allclose(windows.errors, [0.0, 0.25, 0.75])
    windows.record_episode(0, np.full(20, 0.5))
    assert windows.errors[0] == pytest.approx(0.25)  # halfway to the episode's 0.5
    state = json.loads(json.dumps(windows.state()))
    other = _windows([1.0, 1.0, 1.0])
    other.load_state(state)
    np.testing.assert_array_equal(other.errors, windows.errors)
    with pytest.raises(ValueError, match="windows"):
        _windows([1.0, 1.0]).load_state(state)


def test_window_starts_cover_the_piece():
    assert window_starts(161, 40, 20) == [0, 20, 40, 60, 80, 100, 120, 121]
    assert window_starts(160, 40, 20) == [0, 20, 40, 60, 80, 100, 120]
    assert window_starts(30, 40, 20) == [0]
    with pytest.raises(ValueError):
        window_starts(100, 0, 20)


BASE = get_preset("residual-windows")
TINY = dataclasses.replace(
    BASE,
    agent=dataclasses.replace(BASE.agent, hidden_dims=(16, 16), batch_size=16),
    seed_steps=60,
    steps_per_iteration=1,
    eval_interval=200,
    checkpoint_interval=100,
    replay_capacity=2000,
    window_s=2.0,
    window_stride_s=1.0,
    window_share=0.6,
)
STEPS = 420


def _rows(path, kind):
    rows = [json.loads(x) for x in (path / "log.jsonl").read_text().splitlines()]
    return [
        {k: v for k, v in r.items() if k not in ("wall_s", "steps_per_s")}
        for r in rows
        if r["kind"] == kind
    ]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("windows")
    train(SONG, TINY, STEPS, out, progress=False)
    return out


def test_a_run_with_windows_trains_on_windows_and_evaluates_the_whole_piece(run_dir):
    episodes = _rows(run_dir, "episode")
    windowed = [r for r in episodes if "window" in r]
    whole = [r for r in episodes if "window" not in r]
    assert windowed and whole, "both kinds of episode, at a share of 0.6"
    steps = np.diff([0] + [r["step"] for r in episodes])
    for r, n in zip(episodes, steps, strict=True):
        assert n == (WINDOW if "window" in r else 161)  # windows are truncated after 2 s
        assert 0 <= r["f1"] <= 1
    for r in windowed:
        assert r["start_step"] == window_starts(161, WINDOW, STRIDE)[r["window"]]
    evals = _rows(run_dir, "eval")
    assert [r["step"] for r in evals] == [200, 400, STEPS]
    state = load_state(latest_checkpoint(run_dir))["windows"]
    # The windows of the finished episodes, and maybe that of the one cut at STEPS.
    assert len(windowed) <= sum(state["draws"]) <= len(windowed) + 1
    assert all(state["draws"][r["window"]] > 0 for r in windowed)
    assert len(state["errors"]) == 8 and all(0 <= e <= 1 for e in state["errors"])


def test_a_run_with_windows_resumes_exactly(run_dir, tmp_path):
    out = tmp_path / "resumed"
    first = train(SONG, TINY, STEPS, out, progress=False, stop_after_s=0.0)
    assert first.step < STEPS
    second = train(None, None, STEPS, out, resume=True, progress=False)
    assert second.resumed_from == first.step
    for kind in ("episode", "train"):
        assert _rows(out, kind) == _rows(run_dir, kind)
    assert [r for r in _rows(out, "eval") if r["step"] > first.step] == _rows(run_dir, "eval")
    windows = [load_state(latest_checkpoint(d))["windows"] for d in (out, run_dir)]
    assert windows[0] == windows[1]
    a = np.load(latest_checkpoint(run_dir) / "agent.npz")
    b = np.load(latest_checkpoint(out) / "agent.npz")
    for key in a.files:
        np.testing.assert_array_equal(a[key], b[key])


def test_windows_are_off_in_the_other_presets():
    assert get_preset("residual-anchored").windows is False
    config = get_preset("residual-windows")
    assert config.windows and config.task == get_preset("residual-anchored").task
    with pytest.raises(ValueError, match="window_share"):
        get_preset("residual-windows", window_share=1.5)
