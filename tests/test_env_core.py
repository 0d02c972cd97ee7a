"""PianoEnv: spaces, episode length, termination, determinism, rewards, actions, observations."""

from __future__ import annotations

import copy
import math
import warnings

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from pianist.env import PianoEnv, RewardWeights, SimulationUnstableError
from pianist.env.piano_env import WAKE_VELOCITY_RAD_S
from pianist.music import Note, Song, goal_frames

C4, C3, C8 = 60, 48, 108

# 0.3 s long -> T = int(0.3 * 20 + 1) = 7 frames; a right-hand and a left-hand note and pedal.
TINY = Song(
    (Note(C4, 0.0, 0.2, finger=1), Note(C3, 0.1, 0.3, finger=6)),
    sustain=((0.05, 0.15),),
    name="tiny",
)
TINY_T = 7
# One note on the top key, far away from both hands: any other key sounding is wrong.
FAR = Song((Note(C8, 0.0, 0.3, finger=4),), name="far")


def hold_action(env: PianoEnv, sustain: float = -1.0) -> np.ndarray:
    """The action that keeps every servo at its current target (the reset pose)."""
    low, high = env.model.actuator_ctrlrange.T
    return np.append((env.data.ctrl - low) / ((high - low) / 2) - 1.0, sustain)


def sound_key(env: PianoEnv, key: int) -> None:
    """Make ``key`` sound during the next step: put it at the bottom moving down fast.

    Measured: with qvel = 20 rad/s the joint limit holds the key at the bottom for the whole
    control step (it is active after each of the 10 substeps) and the spring brings it back up
    during the following step. (A bare qpos at the bottom is pushed back up by the preloaded
    spring within 2-3 substeps.)
    """
    env.data.qpos[env.scene.key_qpos[key]] = env.scene.key_max_angle_rad[key]
    env.data.qvel[env.scene.key_dof[key]] = 20.0


def event_rows(events: object) -> list[tuple[float, int, bool]]:
    """info["note_events"] as (time s rounded to 1 us, key or -1 for the pedal, on) rows;
    accepts an (n, 3) array or a sequence of triples."""
    return [(round(float(t), 6), int(k), bool(on)) for t, k, on in events]  # type: ignore[attr-defined]


def random_actions(env: PianoEnv, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1, 1, env.action_space.shape).astype(np.float32) for _ in range(n)]


@pytest.fixture(scope="module")
def chords_env() -> PianoEnv:
    return PianoEnv("c-major-chords")


@pytest.fixture(scope="module")
def tiny_env() -> PianoEnv:
    return PianoEnv(TINY, lookahead=3)


# --------------------------------------------------------------------------------- spaces


def test_gymnasium_env_checker_passes() -> None:
    env = PianoEnv("c-major-chords")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no spec": the env is not made through gym.make
        check_env(env, skip_render_check=True)


def test_observation_matches_space_and_table(chords_env: PianoEnv) -> None:
    obs, info = chords_env.reset(seed=0)
    expected = {
        "goal": (11, 89),  # lookahead 10 by default
        "fingers_due": (10,),
        "piano_keys": (88,),
        "piano_sustain": (1,),
        "rh_joints": (23,),
        "lh_joints": (23,),
        "rh_fingertips": (5, 3),
        "lh_fingertips": (5, 3),
        "rh_forearm": (3,),
        "lh_forearm": (3,),
    }
    space = chords_env.observation_space
    assert isinstance(space, gym.spaces.Dict)
    assert set(space.spaces) == set(expected) == set(obs)
    for key, shape in expected.items():
        assert space[key].shape == shape, key
        assert space[key].dtype == np.float32, key
        assert obs[key].shape == shape and obs[key].dtype == np.float32, key
    assert space.contains(obs)
    obs, *_ = chords_env.step(hold_action(chords_env))
    assert space.contains(obs)
    assert not info["active_keys"].any() and info["sustain"] is False


def test_lookahead_sets_goal_rows(tiny_env: PianoEnv) -> None:
    obs, _ = tiny_env.reset(seed=0)
    assert obs["goal"].shape == (4, 89)
    assert tiny_env.observation_space["goal"].shape == (4, 89)
    env0 = PianoEnv(TINY, lookahead=0)
    assert env0.reset()[0]["goal"].shape == (1, 89)


def test_full_action_space_sizes() -> None:
    env = PianoEnv(TINY, reduced_action_space=False)
    obs, _ = env.reset(seed=0)
    assert obs["rh_joints"].shape == (26,) and obs["lh_joints"].shape == (26,)
    assert env.action_space.shape == (45,)
    assert env.observation_space.contains(obs)


@pytest.mark.parametrize(
    ("hands", "prefix", "other"), [("right", "rh", "lh"), ("left", "lh", "rh")]
)
def test_one_hand_env(hands: str, prefix: str, other: str) -> None:
    env = PianoEnv(TINY, hands=hands, lookahead=2)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {
        "goal",
        "fingers_due",
        "piano_keys",
        "piano_sustain",
        f"{prefix}_joints",
        f"{prefix}_fingertips",
        f"{prefix}_forearm",
    }
    assert not any(k.startswith(other) for k in env.observation_space.spaces)
    assert env.action_space.shape == (20,)  # 19 actuators + sustain
    assert all(n.startswith(prefix + "/") for n in env.action_names[:-1])
    obs, reward, *_ = env.step(hold_action(env))
    assert env.observation_space.contains(obs) and math.isfinite(reward)


def test_action_space(chords_env: PianoEnv) -> None:
    space = chords_env.action_space
    assert isinstance(space, gym.spaces.Box)
    assert space.shape == (chords_env.model.nu + 1,) == (39,)
    np.testing.assert_array_equal(space.low, -1.0)
    np.testing.assert_array_equal(space.high, 1.0)
    names = chords_env.action_names
    assert len(names) == 39 and names[-1] == "sustain"
    m = chords_env.model
    assert names[:-1] == [m.actuator(i).name for i in range(m.nu)]
    # Right hand first, then left; each hand's forearm actuators after its fingers.
    assert names[:19] == [n for n in names[:-1] if n.startswith("rh/")]
    assert names[17:19] == ["rh/A_forearm_tx", "rh/A_forearm_ty"]
    assert names[36:38] == ["lh/A_forearm_tx", "lh/A_forearm_ty"]


# --------------------------------------------------------------------------------- episode


def test_episode_truncates_after_goal_frames(tiny_env: PianoEnv) -> None:
    frames = goal_frames(TINY, dt=0.05)
    assert frames.num_frames == TINY_T == tiny_env.num_steps
    tiny_env.reset(seed=0)
    action = hold_action(tiny_env)
    for t in range(TINY_T):
        assert tiny_env.step_index == t
        _, _, terminated, truncated, info = tiny_env.step(action)
        assert terminated is False
        assert truncated is (t == TINY_T - 1)
        assert info["step"] == t + 1
    with pytest.raises(RuntimeError):
        tiny_env.step(action)
    tiny_env.reset(seed=0)
    tiny_env.step(action)  # a reset starts a new episode


def test_final_observation_is_in_the_observation_space(tiny_env: PianoEnv) -> None:
    """The observation returned with truncated=True must still fit the space (vector envs
    batch it). Its goal window is all past the end of the song: L + 1 zero rows."""
    tiny_env.reset(seed=0)
    action = hold_action(tiny_env)
    for _ in range(TINY_T):
        obs, _, _, truncated, _ = tiny_env.step(action)
    assert truncated
    assert obs["goal"].shape == (4, 89)
    assert not obs["goal"].any()
    assert not obs["fingers_due"].any()
    assert tiny_env.observation_space.contains(obs)


def test_wrong_press_terminates() -> None:
    """A key that is not due sounding ends the episode as terminated; the due key does not."""
    env = PianoEnv(FAR, wrong_press_termination=True)
    env.reset(seed=0)
    action = hold_action(env)
    _, _, terminated, truncated, info = env.step(action)
    assert not terminated and not info["active_keys"].any()

    sound_key(env, 87)  # the due key (C8): not wrong
    _, _, terminated, _, info = env.step(action)
    assert info["active_keys"][87] and info["goal_keys"][87]
    assert not terminated

    env.reset(seed=0)
    sound_key(env, 0)  # A0 is not due
    _, reward, terminated, truncated, info = env.step(action)
    assert info["active_keys"][0] and not info["goal_keys"][0]
    assert terminated is True and truncated is False
    assert info["reward_terms"]["key_press"] <= 0.5

    off = PianoEnv(FAR, wrong_press_termination=False)
    off.reset(seed=0)
    sound_key(off, 0)
    _, _, terminated, _, info = off.step(hold_action(off))
    assert info["active_keys"][0] and terminated is False


# --------------------------------------------------------------------------------- determinism


def _rollout(env: PianoEnv, actions: list[np.ndarray], seed: int) -> list:
    obs, _ = env.reset(seed=seed)
    record = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        record.append((obs, reward, terminated, truncated, info["active_keys"]))
    return record


def _assert_same(a: object, b: object) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys()
        for k in a:
            _assert_same(a[k], b[k])
    elif isinstance(a, tuple | list):
        assert len(a) == len(b)  # type: ignore[arg-type]
        for x, y in zip(a, b, strict=True):  # type: ignore[call-overload]
            _assert_same(x, y)
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b


def test_same_seed_and_actions_give_identical_episodes(chords_env: PianoEnv) -> None:
    other = PianoEnv("c-major-chords")
    actions = random_actions(chords_env, 25, seed=3)
    first = _rollout(chords_env, actions, seed=11)
    second = _rollout(other, actions, seed=11)
    _assert_same(first, second)
    again = _rollout(chords_env, actions, seed=11)  # the same env after a reset
    _assert_same(first, again)
    # The hands did move: the comparison is not between two resting states.
    assert not np.allclose(first[0]["rh_fingertips"], first[-1][0]["rh_fingertips"], atol=1e-3)


def test_reset_with_seed_repeats_the_first_observation(chords_env: PianoEnv) -> None:
    first, _ = chords_env.reset(seed=5)
    for a in random_actions(chords_env, 5, seed=0):
        chords_env.step(a)
    second, _ = chords_env.reset(seed=5)
    _assert_same(first, second)


def test_randomized_hand_positions() -> None:
    env = PianoEnv(TINY, randomize_hand_positions=True)
    a, _ = env.reset(seed=1)
    b, _ = env.reset(seed=2)
    a2, _ = env.reset(seed=1)
    _assert_same(a, a2)
    for prefix, home_y in (("rh", 0.15), ("lh", -0.15)):
        assert a[f"{prefix}_forearm"][1] != b[f"{prefix}_forearm"][1]
        for obs in (a, b):
            x, y, z = obs[f"{prefix}_forearm"]
            assert abs(y - home_y) <= 0.05 + 1e-6
            assert x == pytest.approx(0.4) and z == pytest.approx(0.13)
            assert obs[f"{prefix}_joints"][0] == pytest.approx(y - home_y, abs=1e-6)
    fixed = PianoEnv(TINY)
    for seed in (1, 2):
        obs, _ = fixed.reset(seed=seed)
        np.testing.assert_allclose(obs["rh_forearm"], [0.4, 0.15, 0.13], atol=1e-6)
        np.testing.assert_allclose(obs["lh_forearm"], [0.4, -0.15, 0.13], atol=1e-6)


# --------------------------------------------------------------------------------- rewards


def test_reward_is_the_weighted_sum_of_terms(chords_env: PianoEnv) -> None:
    custom = RewardWeights(key_press=2.0, fingering=0.5, energy=-1.0, sustain=3.0, forearm=0.0)
    other = PianoEnv("c-major-chords", rewards=custom)
    default = RewardWeights()
    assert default.as_dict() == {
        "key_press": 1.0,
        "fingering": 1.0,
        "energy": -5e-3,
        "sustain": 1.0,
        "forearm": 1.0,
        "velocity": 1.0,  # its term 0 without velocity_goal
    }
    actions = random_actions(chords_env, 10, seed=4)
    chords_env.reset(seed=0)
    other.reset(seed=0)
    for a in actions:
        _, r_default, *_, info_default = chords_env.step(a)
        _, r_custom, *_, info_custom = other.step(a)
        terms = info_default["reward_terms"]
        assert set(terms) == {"key_press", "fingering", "energy", "sustain", "forearm", "velocity"}
        assert terms == info_custom["reward_terms"]  # weights do not change the physics
        expected = {
            w: sum(getattr(weights, name) * value for name, value in terms.items())
            for w, weights in (("default", default), ("custom", custom))
        }
        assert r_default == pytest.approx(expected["default"], rel=1e-12, abs=1e-12)
        assert r_custom == pytest.approx(expected["custom"], rel=1e-12, abs=1e-12)
    assert terms["energy"] > 0  # random actions spend power: the weights are exercised
    assert r_default != pytest.approx(r_custom)


def test_reward_terms_at_rest(tiny_env: PianoEnv) -> None:
    """Holding still, nothing sounds: key press = 0.5 (no wrong key) + 0 for the due C4."""
    tiny_env.reset(seed=0)
    _, _, _, _, info = tiny_env.step(hold_action(tiny_env))
    terms = info["reward_terms"]
    # C4 is due at frame 0 and not pressed: 0.5 * tol(1.0) = 0.5 * 0.1 ** (1.9 ** 2).
    assert terms["key_press"] == pytest.approx(0.5 + 0.5 * 0.1 ** (1.9**2))
    assert terms["sustain"] == pytest.approx(1.0)  # pedal not due at frame 0, not pressed
    assert terms["forearm"] == pytest.approx(0.5)
    assert 0.0 < terms["fingering"] < 1.0
    assert terms["energy"] >= 0.0


# --------------------------------------------------------------------------------- goal


def test_goal_and_fingers_due_follow_the_frames(tiny_env: PianoEnv) -> None:
    frames = goal_frames(TINY, dt=0.05)
    L = 3
    table = np.zeros((TINY_T + L + 1, 89), dtype=np.float32)
    table[:TINY_T, :88] = frames.keys
    table[:TINY_T, 88] = frames.sustain
    assert frames.sustain.any() and frames.keys[:, C3 - 21].any()
    obs, _ = tiny_env.reset(seed=0)
    action = hold_action(tiny_env)
    for t in range(TINY_T):
        np.testing.assert_array_equal(obs["goal"], table[t : t + L + 1], err_msg=f"t={t}")
        np.testing.assert_array_equal(obs["fingers_due"], frames.finger_mask[t])
        obs, _, _, _, info = tiny_env.step(action)
        np.testing.assert_array_equal(info["goal_keys"], frames.keys[t])
        assert info["goal_sustain"] == bool(frames.sustain[t])
    # Past the end of the song the goal is zero-padded.
    assert not table[TINY_T:].any()


def test_fingers_due_marks_both_hands(tiny_env: PianoEnv) -> None:
    obs, _ = tiny_env.reset(seed=0)
    action = hold_action(tiny_env)
    np.testing.assert_array_equal(np.flatnonzero(obs["fingers_due"]), [1])  # right index
    for _ in range(2):
        obs, *_ = tiny_env.step(action)
    np.testing.assert_array_equal(np.flatnonzero(obs["fingers_due"]), [1, 6])  # + left index


# --------------------------------------------------------------------------------- actions


def test_sustain_action(tiny_env: PianoEnv) -> None:
    tiny_env.reset(seed=0)
    obs, _, _, _, info = tiny_env.step(hold_action(tiny_env, sustain=0.0))
    assert info["sustain"] is True
    np.testing.assert_array_equal(obs["piano_sustain"], [1.0])
    assert event_rows(info["note_events"]) == [(0.0, -1, True)]  # down at the step's start
    obs, _, _, _, info = tiny_env.step(hold_action(tiny_env, sustain=-0.01))
    assert info["sustain"] is False
    np.testing.assert_array_equal(obs["piano_sustain"], [0.0])
    assert event_rows(info["note_events"]) == [(0.05, -1, False)]
    _, _, _, _, info = tiny_env.step(hold_action(tiny_env, sustain=1.0))
    # Frame 2 wants the pedal down (0.05-0.15 s covers frames 1..3).
    assert info["goal_sustain"] is True and info["reward_terms"]["sustain"] == pytest.approx(1.0)


@pytest.mark.parametrize("value", [-1.0, 0.0, 1.0, 7.0, -7.0])
def test_action_maps_linearly_onto_ctrlrange(tiny_env: PianoEnv, value: float) -> None:
    tiny_env.reset(seed=0)
    tiny_env.step(np.full(tiny_env.action_space.shape, value, dtype=np.float32))
    low, high = tiny_env.model.actuator_ctrlrange.T
    expected = {-1.0: low, 0.0: (low + high) / 2, 1.0: high, 7.0: high, -7.0: low}[value]
    np.testing.assert_allclose(tiny_env.data.ctrl, expected, rtol=0, atol=1e-12)


def test_action_maps_each_dimension_to_its_actuator(tiny_env: PianoEnv) -> None:
    tiny_env.reset(seed=0)
    action = np.linspace(-1, 1, tiny_env.action_space.shape[0])
    tiny_env.step(action)
    low, high = tiny_env.model.actuator_ctrlrange.T
    np.testing.assert_allclose(tiny_env.data.ctrl, low + (action[:-1] + 1) / 2 * (high - low))


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(38),
        np.zeros(40),
        np.zeros((1, 39)),
        np.full(39, np.nan),
        np.append(np.zeros(38), np.inf),
    ],
    ids=["short", "long", "2d", "nan", "inf-sustain"],
)
def test_bad_actions_raise(tiny_env: PianoEnv, bad: np.ndarray) -> None:
    tiny_env.reset(seed=0)
    with pytest.raises(ValueError):
        tiny_env.step(bad)


# --------------------------------------------------------------------------------- state


def test_observation_is_consistent_with_qpos(chords_env: PianoEnv) -> None:
    """Positions are those of the final qpos, not one integration behind (facts, section 8)."""
    chords_env.reset(seed=0)
    for a in random_actions(chords_env, 8, seed=7):
        obs, *_ = chords_env.step(a)
    m, d = chords_env.model, chords_env.data
    hand_dofs = [
        m.jnt_dofadr[j] for j in range(m.njnt) if m.joint(j).name.startswith(("rh/", "lh/"))
    ]
    assert np.abs(d.qvel[hand_dofs]).max() > 0.5  # moving: a stale position would differ
    fresh = copy.copy(d)
    mujoco.mj_kinematics(m, fresh)
    for hand in chords_env.scene.hands:
        p = "rh" if hand.side == "right" else "lh"
        np.testing.assert_allclose(
            obs[f"{p}_fingertips"], fresh.site_xpos[hand.fingertip_sites], rtol=0, atol=1e-6
        )
        np.testing.assert_allclose(
            obs[f"{p}_forearm"], fresh.xpos[hand.forearm_body], rtol=0, atol=1e-6
        )
        np.testing.assert_array_equal(
            obs[f"{p}_joints"], d.qpos[hand.joint_qpos].astype(np.float32)
        )
    keys = chords_env.scene.key_qpos
    state = np.clip(d.qpos[keys], 0, chords_env.scene.key_max_angle_rad)
    np.testing.assert_allclose(
        obs["piano_keys"], state / chords_env.scene.key_max_angle_rad, atol=1e-6
    )


@pytest.mark.parametrize(
    "velocity", [1e9, np.nan], ids=["huge-velocity-BADQACC", "nan-velocity-BADQVEL"]
)
def test_diverging_state_raises(velocity: float) -> None:
    """MuJoCo warns and silently resets the whole simulation to the home pose when the state
    blows up (a huge finger velocity gives a huge acceleration; a NaN velocity is caught
    before that): the env must raise instead of carrying on from the reset state."""
    env = PianoEnv(TINY)
    env.reset(seed=0)
    action = hold_action(env)
    for _ in range(3):
        env.step(action)
    env.data.qvel[env.model.joint("rh/FFJ3").dofadr[0]] = velocity
    with pytest.raises(SimulationUnstableError):
        env.step(action)


def test_divergence_in_the_first_substep_raises() -> None:
    """The same blow-up right after reset(): MuJoCo's reset sends time back to 0, which is
    also where the episode started, so a clock-based check cannot see it."""
    env = PianoEnv(TINY)
    env.reset(seed=0)
    env.data.qvel[env.model.joint("rh/FFJ3").dofadr[0]] = 1e9
    with pytest.raises(SimulationUnstableError):
        env.step(hold_action(env))


def test_energy_term_is_the_actuator_power(chords_env: PianoEnv) -> None:
    chords_env.reset(seed=0)
    for a in random_actions(chords_env, 3, seed=9):
        _, _, _, _, info = chords_env.step(a)
        d = chords_env.data
        power = float(np.abs(d.actuator_force) @ np.abs(d.actuator_velocity))
        assert power > 0
        assert info["reward_terms"]["energy"] == pytest.approx(power, rel=1e-9)


def test_invalid_configuration_raises() -> None:
    from pianist.env import make_config

    with pytest.raises(ValueError):
        PianoEnv(TINY, lookahead=-1)
    with pytest.raises(ValueError):
        PianoEnv(TINY, control_timestep_s=0.012)  # not a multiple of 5 ms
    with pytest.raises(ValueError):
        PianoEnv(TINY, physics="warp-speed")
    with pytest.raises(ValueError):
        PianoEnv(TINY, hands="none")
    with pytest.raises(ValueError):
        PianoEnv(TINY, forearm_dofs=("tx", "spin"))
    with pytest.raises(ValueError):
        PianoEnv(TINY, render_mode="human")
    with pytest.raises(ValueError):
        PianoEnv(goal_frames(TINY, dt=0.1))  # goal frames at another control step
    with pytest.raises(TypeError):
        PianoEnv(TINY, config=make_config(), lookahead=3)


@pytest.mark.parametrize("hands", ["both", "right"])
def test_fingering_term_uses_the_labelled_fingertips(hands: str) -> None:
    """Finger 1 is the right index (rh/fftip), finger 6 the left index (lh/fftip); a finger of
    a hand missing from the scene is not scored."""
    from pianist.env.rewards import fingering_reward

    env = PianoEnv(TINY, hands=hands)
    env.reset(seed=0)
    action = hold_action(env)
    m = env.model
    c4, c3 = m.site("key_39").id, m.site("key_27").id
    for t in range(3):
        _, _, _, _, info = env.step(action)
        fresh = copy.copy(env.data)
        mujoco.mj_kinematics(m, fresh)
        tips, targets = [m.site("rh/fftip").id], [c4]  # C4, finger 1, frames 0..4
        if t >= 2 and hands == "both":  # C3, finger 6, from frame 2
            tips.append(m.site("lh/fftip").id)
            targets.append(c3)
        expected = fingering_reward(fresh.site_xpos[tips], fresh.site_xpos[targets])
        assert info["reward_terms"]["fingering"] == pytest.approx(expected, rel=1e-9)
        assert 0 < expected < 1


def test_a_key_left_asleep_below_its_stop_is_woken_before_the_next_step():
    # Fast preset (sleeping islands): a key could fall asleep held down past its stop by a
    # finger and, its spring not evaluated while it slept, sound on after the finger left (in
    # Schoenberg op. 19 no. 2, F#3 for 18 s). Such a key gets a small upward velocity, which
    # wakes it; a key at rest, or one moved by hand since the step, is left alone.
    import mujoco

    env = PianoEnv("c-major-chords", physics="fast")
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.r_[np.zeros(env.model.nu), -1.0].astype(np.float32))
    data, model, scene = env.data, env.model, env.scene
    stuck, resting, moved = 33, 40, 45
    trees = model.body_treeid[
        model.jnt_bodyid[
            [
                int(np.flatnonzero(model.jnt_qposadr == scene.key_qpos[k])[0])
                for k in (stuck, resting, moved)
            ]
        ]
    ]
    data.qpos[scene.key_qpos[[stuck, moved]]] = 0.07  # held down, past the stop
    data.qvel[scene.key_dof[[stuck, resting, moved]]] = 0.0
    env._key_qpos_after_step = data.qpos[scene.key_qpos].copy()  # as the last step left them
    data.qpos[scene.key_qpos[moved]] = 0.05  # moved by hand since
    data.tree_asleep[trees] = trees  # asleep (each tree its own island)
    env._wake_pressed_keys()
    velocity = data.qvel[scene.key_dof[[stuck, resting, moved]]]
    assert velocity.tolist() == [-WAKE_VELOCITY_RAD_S, 0.0, 0.0]
    assert mujoco.mjtEnableBit.mjENBL_SLEEP & model.opt.enableflags


@pytest.mark.parametrize("physics", ["faithful", "fast"])
def test_a_restored_snapshot_replays_the_steps_exactly(physics):
    # Snapshot mid-episode, play on; restore (here and in a fork) and play the same actions:
    # the same states, rewards and note events, step for step (sleeping keys included).
    env = PianoEnv("twinkle-twinkle", physics=physics)
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (30, env.action_space.shape[0])).astype(np.float32)
    for action in actions[:10]:
        env.step(action)
    state = env.snapshot()

    def play_on(target):
        out = []
        for action in actions[10:]:
            obs, reward, _, _, info = target.step(action)
            out.append((target.data.qpos.copy(), reward, info["active_keys"], info["note_events"]))
        return out

    first = play_on(env)
    fork_env = env.fork()
    fork_env.restore(state)
    env.restore(state)
    for again in (play_on(env), play_on(fork_env)):
        for (q1, r1, a1, e1), (q2, r2, a2, e2) in zip(first, again, strict=True):
            np.testing.assert_array_equal(q1, q2)
            assert r1 == r2
            np.testing.assert_array_equal(a1, a2)
            assert e1 == e2
    assert env.step_index == fork_env.step_index == 30


def test_a_snapshot_that_reuses_an_earlier_ones_copy_restores_as_a_new_one():
    # snapshot(reuse=old) overwrites old's simulator copy instead of allocating one; the new
    # state restores exactly as a fresh snapshot does (a fork's spent snapshot too), and one
    # of another environment is not reused.
    env = PianoEnv("twinkle-twinkle", physics="fast")
    env.reset(seed=0)
    rng = np.random.default_rng(2)
    actions = rng.uniform(-1, 1, (16, env.action_space.shape[0])).astype(np.float32)
    spent = env.fork().snapshot()
    for action in actions[:8]:
        env.step(action)
    fresh, reused = env.snapshot(), env.snapshot(reuse=spent)
    assert reused.data is spent.data and fresh.data is not spent.data
    runs = []
    for state in (fresh, reused):
        env.restore(state)
        runs.append([env.step(action)[4]["active_keys"].tolist() for action in actions[8:]])
        runs[-1].append(env.data.qpos.tolist())
    assert runs[0] == runs[1]
    bigger = PianoEnv("twinkle-twinkle", physics="fast", forearm_dofs=("tx", "ty", "tz"))
    bigger.reset(seed=0)
    foreign = bigger.snapshot()
    own = env.snapshot(reuse=foreign)
    assert own.data is not foreign.data and own.data.qpos.shape == env.data.qpos.shape


def test_a_fork_is_independent_of_its_source():
    env = PianoEnv("twinkle-twinkle", physics="fast")
    env.reset(seed=0)
    other = env.fork()
    before = env.data.qpos.copy()
    for _ in range(3):
        other.step(np.ones(env.action_space.shape[0], dtype=np.float32))
    np.testing.assert_array_equal(env.data.qpos, before)
    assert env.step_index == 0 and other.step_index == 3
    bigger = PianoEnv("twinkle-twinkle", physics="fast", forearm_dofs=("tx", "ty", "tz"))
    bigger.reset(seed=0)
    with pytest.raises(ValueError, match="another environment"):
        env.restore(bigger.snapshot())


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"physics": 3}, "unknown physics preset"),
        ({"forearm_dofs": "tx"}, "forearm_dofs is a sequence"),
        ({"reduced_action_space": "no"}, "reduced_action_space must be True or False"),
        ({"rewards": {"key_press": 1.0}}, "rewards must be a RewardWeights"),
    ],
)
def test_make_env_refuses_options_of_the_wrong_kind(options, message) -> None:
    import pianist

    with pytest.raises(ValueError, match=message):
        pianist.make_env("c-major-chords", **options)
    # None is the default preset, as for pianist.eval.session.play.
    assert pianist.make_env("c-major-chords", physics=None).config.scene.physics == "faithful"
