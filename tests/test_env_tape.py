"""Steps recorded on a fork and played back by the environment (pianist.env.tape): the same
episode as simulating every step, on and off the tape, at a fraction of the physics."""

import copy
import dataclasses

import numpy as np
import pytest

from pianist.control.base import BaseController
from pianist.control.planner import IKPlanner, PlannerConfig, forget_plans
from pianist.env import PianoEnv
from pianist.env.tape import StepTape
from pianist.eval import run_episode
from pianist.eval.session import make_env

SONG = "c-major-scale-right"
STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "sensordata", "history")


class _Watch(BaseController):
    """The planner's actions (one joint nudged at ``nudge_at``), every observation it is
    given, and at step ``look_at`` the environment's state taken as ``look`` says: a
    ``snapshot``, a ``fork``, or a step taken the vector environment's way (``apply_action``,
    ``advance_physics``, ``finish_step``) with the planner's action."""

    def __init__(self, tape: bool, nudge_at: int = -1, look_at: int = -1, look: str = "") -> None:
        self.planner = IKPlanner(PlannerConfig().with_fields(replay_tape=tape))
        self.nudge_at, self.look_at, self.look, self.steps = nudge_at, look_at, look, 0
        self.seen, self.observations = None, []

    def reset(self, env, seed=None):
        self.env = env.unwrapped
        self.planner.reset(env, seed=seed)

    def act(self, observation):
        self.observations.append({k: np.array(v) for k, v in observation.items()})
        if self.steps == self.look_at and self.look == "snapshot":
            self.seen = self.env.snapshot().data
        elif self.steps == self.look_at and self.look == "fork":
            self.seen = self.env.fork().data
        action = np.array(self.planner.act(observation))
        if self.steps == self.nudge_at:
            action[-2] = np.clip(action[-2] + 0.5, -1.0, 1.0)
        self.steps += 1
        if self.steps - 1 == self.look_at and self.look == "vector":
            self.env.apply_action(action)  # this step, as the vector environment takes it
            self.env.advance_physics()
            self.env.finish_step()
            self.seen = self.env.data
            action = np.array(self.planner.act(None))  # and the next one as usual
            self.steps += 1
        return action


def _play(controller, song=SONG):
    env = make_env(song, IKPlanner(), physics="fast")
    episode = run_episode(env, controller, seed=0)
    return episode, env.unwrapped


def _assert_same_state(a, b):
    for name in STATE_FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def _assert_same(a, b, watched=None):
    (ep_a, env_a), (ep_b, env_b) = a, b
    for name in ("actions", "active_keys", "qpos", "rewards", "note_events"):
        np.testing.assert_array_equal(getattr(ep_a, name), getattr(ep_b, name), err_msg=name)
    for name, values in ep_a.reward_terms.items():
        np.testing.assert_array_equal(values, ep_b.reward_terms[name], err_msg=name)
    assert ep_a.end_time_s == ep_b.end_time_s
    _assert_same_state(env_a.data, env_b.data)  # the final state whole
    if watched is not None:  # every observation the controllers were given
        obs_a, obs_b = watched[0].observations, watched[1].observations
        assert len(obs_a) == len(obs_b) == len(ep_a.actions)
        for x, y in zip(obs_a, obs_b, strict=True):
            for name in x:
                np.testing.assert_array_equal(x[name], y[name], err_msg=name)


@pytest.mark.parametrize("nudge_at", [-1, 40])
def test_a_played_back_episode_is_the_simulated_one_on_and_off_the_tape(nudge_at):
    taped, simulated = _Watch(tape=True, nudge_at=nudge_at), _Watch(tape=False, nudge_at=nudge_at)
    _assert_same(_play(taped), _play(simulated), (taped, simulated))


@pytest.mark.parametrize("look", ["snapshot", "fork", "vector"])
def test_the_state_looked_at_while_the_tape_plays_is_the_simulated_one(look):
    taped = _Watch(tape=True, look_at=25, look=look)
    simulated = _Watch(tape=False, look_at=25, look=look)
    _assert_same(_play(taped), _play(simulated), (taped, simulated))
    _assert_same_state(taped.seen, simulated.seen)


def test_the_tape_spares_the_performance_its_physics_also_in_a_second_episode(monkeypatch):
    simulated_steps = {True: [], False: []}
    episodes = {True: [], False: []}
    original = PianoEnv.advance_physics
    for tape in (True, False):
        forget_plans()
        planner = IKPlanner(PlannerConfig().with_fields(replay_tape=tape))
        env = make_env(SONG, planner, physics="fast")
        base, count = env.unwrapped, [0]

        def counted(self, base=base, count=count):
            count[0] += self is base  # the environment's own steps, not its forks'
            original(self)

        monkeypatch.setattr(PianoEnv, "advance_physics", counted)
        for _ in range(2):  # the second episode reuses the plan and its rehearsal's tape
            count[0] = 0
            episodes[tape].append(run_episode(env, planner, seed=0))
            simulated_steps[tape].append(count[0])
    # The rehearsals step forks, not the environment: with the tape it takes no step.
    assert simulated_steps == {True: [0, 0], False: [base.num_steps] * 2}
    for taped in episodes[True]:
        np.testing.assert_array_equal(taped.qpos, episodes[False][0].qpos)
        np.testing.assert_array_equal(taped.rewards, episodes[False][0].rewards)


def _tape_of_three(env):
    """A closed tape of three steps recorded on a fork of ``env`` (just reset), the actions
    and what each step returned (deep copies)."""
    fork = env.fork()
    tape = StepTape.begin(fork)
    actions = [np.full(env.action_space.shape, v) for v in (0.0, 0.2, -0.3)]
    recorded = [copy.deepcopy(tape.record(fork, a)) for a in actions]
    return tape.finish(fork), actions, recorded, fork


def test_a_tape_plays_back_twice_whatever_the_caller_does_with_its_outputs():
    env = make_env(SONG, IKPlanner(), physics="fast").unwrapped
    env.reset(seed=0)
    tape, actions, recorded, fork = _tape_of_three(env)
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
        assert env._tape is None  # used up: the environment is at the fork's final state
        _assert_same_state(env.data, fork.data)


def test_a_tape_of_another_state_goal_or_configuration_is_refused():
    env = make_env(SONG, IKPlanner(), physics="fast").unwrapped
    env.reset(seed=0)
    fork = env.fork()
    tape = StepTape.begin(fork)
    for _ in range(3):
        tape.record(fork, np.zeros(env.action_space.shape))
    assert not env.play_tape(tape)  # not closed
    tape.finish(fork)
    env.data.qvel[env.scene.key_dof[40]] = 1e-9  # the same step, another state
    assert not env.play_tape(tape)
    env.reset(seed=0)
    env.step(np.full(env.action_space.shape, 0.1))
    assert not env.play_tape(tape)  # the environment has moved on
    # The same goal frames in an environment of another configuration.
    other = PianoEnv(env.goal, config=dataclasses.replace(env.config, lookahead=3))
    assert other.goal is env.goal
    other.reset(seed=0)
    assert not other.play_tape(tape)
    env.reset(seed=0)
    assert env.play_tape(tape)


def test_bad_actions_on_the_tape_fail_as_they_would_without_it():
    env = make_env(SONG, IKPlanner(), physics="fast").unwrapped
    env.reset(seed=0)
    tape, actions, _, fork = _tape_of_three(env)
    assert env.play_tape(tape)
    env.step(actions[0])
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full(env.action_space.shape, np.nan))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3))
    # Left at the first of them, exactly where one simulated step puts the environment.
    for action in actions[1:]:
        env.step(action)
    _assert_same_state(env.data, fork.data)
    # And past the episode's end, a tape refuses as the environment does.
    env.reset(seed=0)
    end = env.fork()
    tape = StepTape.begin(end)
    while end.step_index < end.num_steps:
        tape.record(end, np.zeros(env.action_space.shape))
    assert env.play_tape(tape.finish(end))
    for _ in range(env.num_steps):
        env.step(np.zeros(env.action_space.shape))
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(np.zeros(env.action_space.shape))


def test_the_segment_search_hands_its_winners_look_ahead_to_the_environment(monkeypatch):
    """Each segment is played back from the winning candidate's recorded look-ahead: the
    environment simulates none of its own steps, and the episode is the simulated one."""
    from pianist.control.search import SegmentSearch

    original = PianoEnv.advance_physics
    episodes, home_steps = {}, {}
    for tape in (True, False):
        forget_plans()
        search = SegmentSearch(IKPlanner(PlannerConfig().with_fields(replay_tape=tape)))
        env = make_env("c-major-chords", search, physics="fast")
        base, count = env.unwrapped, [0]

        def counted(self, base=base, count=count):
            count[0] += self is base
            original(self)

        monkeypatch.setattr(PianoEnv, "advance_physics", counted)
        episodes[tape] = run_episode(env, search, seed=0)
        home_steps[tape] = count[0]
        assert search._segments > 1
    assert home_steps == {True: 0, False: base.num_steps}
    for name in ("actions", "active_keys", "qpos", "rewards", "note_events"):
        np.testing.assert_array_equal(
            getattr(episodes[True], name), getattr(episodes[False], name), err_msg=name
        )
