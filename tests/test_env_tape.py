"""Steps recorded on a fork and played back by the environment (pianist.env.tape): the same
episode as simulating every step, on and off the tape, at a fraction of the physics."""

import copy

import numpy as np
import pytest

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.env.tape import StepTape
from pianist.eval import run_episode
from pianist.eval.session import make_env

SONG = "c-major-scale-right"
STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "sensordata", "history")


class _Watch:
    """The planner's actions (one joint nudged at ``nudge_at``), and the environment's full
    simulator state after step ``snapshot_at`` (taken through ``snapshot``)."""

    def __init__(self, tape: bool, nudge_at: int = -1, snapshot_at: int = -1) -> None:
        self.planner = IKPlanner(PlannerConfig(replay_tape=tape))
        self.nudge_at, self.snapshot_at, self.steps = nudge_at, snapshot_at, 0
        self.snapshot = None

    def reset(self, env, seed=None):
        self.env = env.unwrapped
        self.planner.reset(env, seed=seed)

    def act(self, observation):
        if self.steps == self.snapshot_at:
            self.snapshot = self.env.snapshot()
        action = np.array(self.planner.act(observation))
        if self.steps == self.nudge_at:
            action[-2] = np.clip(action[-2] + 0.5, -1.0, 1.0)
        self.steps += 1
        return action


def _play(controller, song=SONG):
    env = make_env(song, IKPlanner(), physics="fast")
    episode = run_episode(env, controller, seed=0)
    return episode, env.unwrapped


def _assert_same(a, b):
    (ep_a, env_a), (ep_b, env_b) = a, b
    for name in ("actions", "active_keys", "qpos", "rewards", "note_events"):
        np.testing.assert_array_equal(getattr(ep_a, name), getattr(ep_b, name), err_msg=name)
    for name, values in ep_a.reward_terms.items():
        np.testing.assert_array_equal(values, ep_b.reward_terms[name], err_msg=name)
    assert ep_a.end_time_s == ep_b.end_time_s
    for name in STATE_FIELDS:  # the final state whole, not only what the episode records
        np.testing.assert_array_equal(
            getattr(env_a.data, name), getattr(env_b.data, name), err_msg=name
        )


@pytest.mark.parametrize("nudge_at", [-1, 40])
def test_a_played_back_episode_is_the_simulated_one_on_and_off_the_tape(nudge_at):
    taped = _play(_Watch(tape=True, nudge_at=nudge_at))
    simulated = _play(_Watch(tape=False, nudge_at=nudge_at))
    _assert_same(taped, simulated)


def test_a_snapshot_taken_while_the_tape_plays_is_the_simulated_state():
    taped, simulated = _Watch(tape=True, snapshot_at=25), _Watch(tape=False, snapshot_at=25)
    _assert_same(_play(taped), _play(simulated))
    assert taped.snapshot.step == simulated.snapshot.step == 25
    for name in STATE_FIELDS:
        np.testing.assert_array_equal(
            getattr(taped.snapshot.data, name), getattr(simulated.snapshot.data, name)
        )


def test_the_tape_spares_the_performance_its_physics(monkeypatch):
    simulated_steps = {True: 0, False: 0}
    for tape in (True, False):
        planner = IKPlanner(PlannerConfig(replay_tape=tape))
        env = make_env(SONG, planner, physics="fast")
        env.reset(seed=0)
        planner.reset(env, seed=0)  # rehearses on forks: the environment takes no step
        base = env.unwrapped
        original = base.advance_physics

        def counted(original=original, tape=tape):
            simulated_steps[tape] += 1
            original()

        monkeypatch.setattr(base, "advance_physics", counted)
        done = False
        while not done:
            *_, terminated, truncated, _ = env.step(planner.act(None))
            done = terminated or truncated
    assert simulated_steps == {True: 0, False: base.num_steps}


def test_a_tape_from_another_state_is_refused():
    env = make_env(SONG, IKPlanner(), physics="fast").unwrapped
    env.reset(seed=0)
    fork = env.fork()
    tape = StepTape.begin(fork)
    for _ in range(3):
        tape.record(fork, np.zeros(env.action_space.shape))
    assert not env.play_tape(tape)  # not closed
    tape.finish(fork)
    env.step(np.full(env.action_space.shape, 0.1))
    assert not env.play_tape(tape)  # the environment has moved on
    env.reset(seed=0)
    assert env.play_tape(tape)
    # Its steps played back: the environment is at the fork's state, the tape used up.
    for _ in range(3):
        env.step(np.zeros(env.action_space.shape))
    np.testing.assert_array_equal(env.data.qpos, fork.data.qpos)
    assert env._tape is None


def test_a_tape_plays_back_twice_whatever_the_caller_does_with_its_outputs():
    env = make_env(SONG, IKPlanner(), physics="fast").unwrapped
    env.reset(seed=0)
    fork = env.fork()
    tape = StepTape.begin(fork)
    actions = [np.full(env.action_space.shape, v) for v in (0.0, 0.2, -0.3)]
    recorded = [copy.deepcopy(tape.record(fork, a)) for a in actions]
    tape.finish(fork)
    for _ in range(2):
        env.reset(seed=0)
        assert env.play_tape(tape)
        for action, (obs, reward, _, _, info) in zip(actions, recorded, strict=True):
            got_obs, got_reward, _, _, got_info = env.step(action)
            assert got_reward == reward
            for name, value in obs.items():
                np.testing.assert_array_equal(got_obs[name], value)
                got_obs[name][...] = -7  # the caller's to change
            np.testing.assert_array_equal(got_info["active_keys"], info["active_keys"])
            got_info["active_keys"][...] = True
            got_info["reward_terms"]["key_press"] = -7.0
        assert env._tape is None
