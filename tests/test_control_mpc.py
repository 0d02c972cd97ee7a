"""Predictive-sampling MPC: splines, the kept nominal, rollout costs against the real env,
determinism, option parsing."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from pianist.control.mpc import MPCOptions, PredictiveSampling, make_mpc
from pianist.control.spline import evaluate, interpolation_weights, knot_times
from pianist.env import PianoEnv
from pianist.music import Note, Song

C4, D4, G3 = 60, 62, 55
# 0.4 s, both hands, fingered: frames 0..8 with notes due from frame 0.
DUET = Song(
    (
        Note(C4, 0.0, 0.2, finger=1),
        Note(D4, 0.2, 0.4, finger=2),
        Note(G3, 0.05, 0.3, finger=6),
    ),
    name="duet",
)
SMALL = MPCOptions(num_samples=4, horizon_s=0.1, iterations=1, threads=1, sigma=0.2)


@pytest.fixture(scope="module")
def env() -> PianoEnv:
    return PianoEnv(DUET, physics="faithful", lookahead=2)


# ------------------------------------------------------------------------------------- spline


@pytest.mark.parametrize("interpolation", ["zero", "linear", "cubic"])
@pytest.mark.parametrize("num_knots", [1, 2, 4])
def test_spline_passes_through_its_knots(interpolation, num_knots):
    rng = np.random.default_rng(0)
    times = knot_times(num_knots, 0.2)
    knots = rng.normal(size=(3, num_knots, 5))
    values = evaluate(knots, times, times, interpolation)
    np.testing.assert_allclose(values, knots, atol=1e-12)
    # Outside the knots the plan holds its end values.
    np.testing.assert_allclose(
        evaluate(knots, times, [-1.0, 5.0], interpolation)[:, 0], knots[:, 0]
    )
    np.testing.assert_allclose(evaluate(knots, times, [5.0], interpolation)[:, 0], knots[:, -1])


def test_cubic_spline_between_knots():
    times = knot_times(4, 0.3)
    t = np.linspace(0, 0.3, 31)
    # Two knots: the finite-difference cubic is the straight line.
    two = knot_times(2, 0.3)
    np.testing.assert_allclose(
        interpolation_weights(t, two, "cubic"), interpolation_weights(t, two, "linear"), atol=1e-12
    )
    # Four knots on a straight line reproduce it exactly; weights sum to one (constants kept).
    line = (2.0 * times - 0.1)[:, None]
    np.testing.assert_allclose(evaluate(line, times, t, "cubic")[:, 0], 2.0 * t - 0.1, atol=1e-12)
    np.testing.assert_allclose(interpolation_weights(t, times, "cubic").sum(axis=1), 1.0)
    # Zero-order hold: the last knot at or before t.
    W = interpolation_weights(np.array([0.0, 0.05, 0.1, 0.25]), times, "zero")
    assert W.argmax(axis=1).tolist() == [0, 0, 1, 2]


def test_spline_rejects_bad_input():
    with pytest.raises(ValueError, match="knot"):
        knot_times(0, 0.2)
    with pytest.raises(ValueError, match="interpolation"):
        interpolation_weights(np.zeros(1), knot_times(2, 0.2), "quintic")


# ---------------------------------------------------------------------------------- planning


def test_planning_never_worsens_the_nominal(env):
    env.reset(seed=0)
    mpc = PredictiveSampling(SMALL)
    mpc.reset(env, seed=1)
    improved = 0
    for _ in range(4):
        nominal = mpc.nominal.copy()
        before, after = mpc.plan_iteration()
        assert after <= before
        # The nominal was one of the candidates and its rollout is deterministic.
        np.testing.assert_allclose(mpc.rollout_costs(nominal[None]).mean(), before, rtol=1e-12)
        np.testing.assert_allclose(mpc.rollout_costs(mpc.nominal[None]).mean(), after, rtol=1e-12)
        improved += after < before
    assert mpc.last_costs.shape == (SMALL.num_samples,)
    assert improved > 0, "four iterations with sigma 0.2 found nothing better than holding still"
    mpc.close()


def _warm_up(env: PianoEnv, steps: int) -> None:
    """Reset and move the hands a little, so that the state has velocities and contacts."""
    env.reset(seed=0)
    rng = np.random.default_rng(7)
    low, high = env.model.actuator_ctrlrange.T
    hold = (env.data.ctrl - low) / ((high - low) / 2) - 1.0
    for _ in range(steps):
        env.step(np.append(np.clip(hold + rng.normal(0, 0.3, hold.shape), -1, 1), -1.0))


def test_rollout_cost_equals_the_cost_of_stepping_the_env(env):
    """Planning at the physics timestep, the rollouts' costs are the real environment's."""
    options = MPCOptions(num_samples=3, horizon_s=0.1, planning_timestep_s=0.005, threads=2)
    substeps = env.config.substeps
    _warm_up(env, 2)
    mpc = PredictiveSampling(options)
    mpc.reset(env, seed=0)
    knots = np.clip(
        mpc.nominal + np.random.default_rng(3).normal(0, 0.3, (3, 2, env.model.nu)), -1, 1
    )
    key = env.scene.key_qpos[C4 - 21]
    env.data.qvel[env.model.jnt_dofadr[np.flatnonzero(env.model.jnt_qposadr == key)[0]]] = 5.0
    saved_qvel = env.data.qvel.copy()
    costs = mpc.rollout_costs(knots)  # (3, 20)
    assert costs.shape == (3, 20)
    mpc.close()

    tips = np.concatenate([h.fingertip_sites for h in env.scene.hands])
    for b in range(3):
        _warm_up(env, 2)
        env.data.qvel[:] = saved_qvel
        mujoco.mj_forward(env.model, env.data)  # as after the controller's edit above
        start_frame = env.step_index
        actions = evaluate(
            knots[b],
            mpc.knot_times,
            np.array([0.0, env.config.control_timestep_s]),
            options.interpolation,
        )
        for c, action in enumerate(actions):
            env.step(np.append(action, -1.0).astype(np.float32))
            data = env.data  # the env brought site positions up to date after the step
            expected = mpc.cost.stage_costs(
                np.array([start_frame + c]),
                data.qpos[env.scene.key_qpos][None],
                data.site_xpos[tips][None],
                data.site_xpos[env.scene.key_sites][None],
            )[0]
            np.testing.assert_allclose(costs[b, (c + 1) * substeps - 1], expected, rtol=1e-12)
    assert np.ptp(costs[:, -1]) > 0, "different plans should reach different costs"


def test_same_seed_same_actions(env):
    def actions(seed: int) -> np.ndarray:
        obs, _ = env.reset(seed=0)
        mpc = make_mpc(SMALL)
        mpc.reset(env, seed=seed)
        out = []
        for _ in range(3):
            action = mpc.act(obs)
            assert action.shape == env.action_space.shape and np.all(np.abs(action) <= 1)
            obs, *_ = env.step(action)
            out.append(action)
        stats = mpc.stats()
        assert stats["mpc_steps"] == 3 and stats["mpc_iterations"] == 3
        assert stats["mpc_realtime_factor"] > 0
        mpc.close()
        return np.stack(out)

    first = actions(5)
    np.testing.assert_array_equal(first, actions(5))
    assert not np.array_equal(first, actions(6))


# ------------------------------------------------------------------------------------ options


def test_make_mpc_presets_and_overrides():
    assert make_mpc().options == MPCOptions()
    mpc = make_mpc("paper, num_samples=20, sigma=0.1, interpolation=linear, seed=3")
    assert (mpc.options.num_samples, mpc.options.sigma, mpc.options.seed) == (20, 0.1, 3)
    assert mpc.options.interpolation == "linear"
    assert make_mpc("iterations=2", threads=1).options.iterations == 2
    with pytest.raises(ValueError, match="preset"):
        make_mpc("fancy")
    with pytest.raises(ValueError, match="unknown mpc option 'samples'"):
        make_mpc("paper,samples=3")
    with pytest.raises(ValueError, match="num_samples needs a whole number, not 'many'"):
        make_mpc("num_samples=many")
    with pytest.raises(ValueError, match="multiple"):
        MPCOptions(horizon_s=0.205)
    with pytest.raises(ValueError, match="num_samples"):
        make_mpc(num_samples=0)
    # A value out of range in a spec says why, and fields are checked together as given.
    with pytest.raises(ValueError, match="num_samples must be >= 1, not 0"):
        make_mpc("paper,num_samples=0")
    with pytest.raises(ValueError, match="needs one of zero, linear, cubic, not 'bogus'"):
        make_mpc("interpolation=bogus")
    both = make_mpc("paper,planning_timestep_s=0.025,horizon_s=0.125").options
    assert (both.planning_timestep_s, both.horizon_s) == (0.025, 0.125)
    assert make_mpc("seed=none").options.seed is None


def test_rollouts_are_reproducible_with_the_fast_preset():
    """Sleeping islands keep state outside mjSTATE_FULLPHYSICS; the planner must not see it."""
    fast = PianoEnv(DUET, physics="fast", lookahead=2)
    fast.reset(seed=0)
    mpc = PredictiveSampling(SMALL)
    mpc.reset(fast, seed=1)
    knots = np.clip(
        mpc.nominal + np.random.default_rng(0).normal(0, 0.3, (4, 2, fast.model.nu)), -1, 1
    )
    first = mpc.rollout_costs(knots)  # on fresh MjData
    np.testing.assert_array_equal(first, mpc.rollout_costs(knots))
    np.testing.assert_array_equal(first, mpc.rollout_costs(knots[::-1])[::-1])
    mpc.close()
