"""The environment as an agent sees it: extra observation entries, and flat vectors.

:class:`AgentEnv` wraps a :class:`pianist.env.PianoEnv` and adds, as the task asks,
``prev_action`` (A,) and ``prev_reward`` (1,) (the paper's runs feed both back), and
``finger_targets`` (n, F, 4): for frames t..t+n-1 and each of the F fingers of the scene's
hands, 1 if the finger is due on a key, then the vector from its fingertip to that key's
target point in decimetres (zeros when not due). :class:`Featurizer` turns such an observation
into the float32 vector the networks read, adding the planner's action for residual policies.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import mujoco
import numpy as np

from pianist.agents.config import TaskConfig
from pianist.env import PianoEnv
from pianist.env.handle import control_handle
from pianist.env.piano_env import EnvState
from pianist.music import GoalFrames, Song, load_song

if TYPE_CHECKING:
    from pianist.control.planner.hand import FingerMemory

TARGET_SCALE = 10.0  # m -> dm: fingertip-to-key vectors of a few cm become ~0.1-1
HAND_FINGERS = {"right": range(0, 5), "left": range(5, 10)}


@dataclass(frozen=True)
class AgentEnvState:
    """An :class:`AgentEnv`'s episode state between two steps (:meth:`AgentEnv.snapshot`):
    the piano's, and the previous action and reward that its next observation shows."""

    env: EnvState
    prev_action: np.ndarray
    prev_reward: float


class AgentEnv(gym.Wrapper):
    """A PianoEnv, or a wrapper of one, with the observation entries of :class:`TaskConfig`
    added (module docstring).

    The action is the environment's. ``config``, ``data``, ``model``, ``goal``, ``scene``,
    ``step_index`` and ``num_steps`` are the wrapped environment's, so rollouts and
    controllers written for :class:`PianoEnv` work on it.
    """

    def __init__(self, env: gym.Env, task: TaskConfig) -> None:
        super().__init__(env)
        self.task = task
        self.handle = base = control_handle(env)
        self._action_shape = _box(env.action_space).shape
        self._prev: tuple[np.ndarray, float] = (np.zeros(self._action_shape, np.float32), 0.0)
        A = self._action_shape[0]
        assert isinstance(env.observation_space, gym.spaces.Dict)  # as a PianoEnv's
        spaces = dict(env.observation_space.spaces)
        if task.action_reward_observation:
            spaces["prev_action"] = gym.spaces.Box(-1.0, 1.0, (A,), np.float32)
            spaces["prev_reward"] = gym.spaces.Box(-np.inf, np.inf, (1,), np.float32)
        n = task.finger_target_frames
        if n > 0:
            self._fingers = np.array(
                [f for hand in base.scene.hands for f in HAND_FINGERS[hand.side]]
            )
            self._tip_keys = [
                f"{'rh' if h.side == 'right' else 'lh'}_fingertips" for h in base.scene.hands
            ]
            F = len(self._fingers)
            spaces["finger_targets"] = gym.spaces.Box(-np.inf, np.inf, (n, F, 4), np.float32)
            # Key index each finger is due on at each frame (-1: none), padded past the end.
            fingers = base.goal.fingers  # (T, 88), -1 = no finger
            T = fingers.shape[0]
            self._finger_key = np.full((T + n, 10), -1, np.intp)
            frames, keys = np.nonzero(fingers >= 0)
            self._finger_key[frames, fingers[frames, keys]] = keys
            self._finger_key = self._finger_key[:, self._fingers]
            # Key target points with every key at rest.
            scratch = mujoco.MjData(base.model)
            mujoco.mj_kinematics(base.model, scratch)
            self._key_target = scratch.site_xpos[base.scene.key_sites].astype(np.float32)
        self.observation_space = gym.spaces.Dict(spaces)

    # The wrapped environment's attributes, as a PianoEnv has them.
    config = property(lambda self: self.handle.config)
    data = property(lambda self: self.handle.data)
    model = property(lambda self: self.handle.model)
    goal = property(lambda self: self.handle.goal)
    scene = property(lambda self: self.handle.scene)
    step_index = property(lambda self: self.handle.step_index)
    num_steps = property(lambda self: self.handle.num_steps)
    action_names = property(lambda self: self.handle.action_names)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode at step 0, or with ``options={"start": state}`` go on from an
        :class:`AgentEnvState` (:meth:`snapshot`): the same observations, rewards and
        physics follow as after the snapshot."""
        start = (options or {}).get("start")
        if start is None:
            obs, info = self.env.reset(seed=seed, options=options)
            action, reward = np.zeros(self._action_shape, np.float32), 0.0
        else:
            obs, info = self.env.reset(seed=seed, options={**(options or {}), "start": start.env})
            action, reward = start.prev_action.copy(), start.prev_reward
        self._prev = (action, reward)
        return self._augment(obs, action, reward), info

    def step(self, action: np.ndarray):
        obs, reward, terminated, truncated, info = self.env.step(action)
        action = np.clip(np.asarray(action, np.float32), -1.0, 1.0)
        self._prev = (action, float(reward))
        return self._augment(obs, action, float(reward)), reward, terminated, truncated, info

    def snapshot(self) -> AgentEnvState:
        """The episode's state now (a copy), to go on from with ``reset(options={"start":
        state})``."""
        action, reward = self._prev
        return AgentEnvState(self.handle.snapshot(), action.copy(), reward)

    def _augment(self, obs: dict[str, np.ndarray], action: np.ndarray, reward: float):
        if self.task.action_reward_observation:
            obs["prev_action"] = action
            obs["prev_reward"] = np.array([reward], np.float32)
        n = self.task.finger_target_frames
        if n > 0:
            t = self.handle.step_index
            keys = self._finger_key[t : t + n]  # (n, F)
            due = keys >= 0
            tips = np.concatenate([obs[k] for k in self._tip_keys])  # (F, 3)
            delta = (self._key_target[keys] - tips[None]) * TARGET_SCALE
            out = np.zeros((n, len(self._fingers), 4), np.float32)
            out[..., 0] = due
            out[..., 1:] = np.where(due[..., None], delta, 0.0)
            obs["finger_targets"] = out
        return obs


def _box(space: gym.spaces.Space) -> gym.spaces.Box:
    """``space``, a Box (as every action and observation entry of a PianoEnv is)."""
    assert isinstance(space, gym.spaces.Box), space
    return space


def fingered_song(song: Song | GoalFrames | str | Path) -> Song | GoalFrames:
    """``song`` itself, or the song of a name or file with its missing fingers estimated
    (``fingering="auto"``, as ``pianist play`` loads it): a MIDI file carries no fingering,
    and a task without it has neither the fingering reward nor its hands."""
    return song if isinstance(song, (Song, GoalFrames)) else load_song(song, fingering="auto")


def song_hands(song: Song | GoalFrames | str | Path) -> tuple[str, ...]:
    """The hands a song's notes are fingered for, ('right',), ('left',) or both (or ())."""
    song = fingered_song(song)
    if isinstance(song, GoalFrames):
        fingers = song.fingers[song.fingers >= 0]
        hands = {"right" if f < 5 else "left" for f in fingers.tolist()}
    else:
        hands = set(song.hands)
    return tuple(sorted(hands, reverse=True))


def make_agent_env(song: Song | GoalFrames | str | Path, task: TaskConfig) -> AgentEnv:
    """The wrapped environment of ``task`` for ``song`` (a name, a file, a Song; a file's
    missing fingers estimated, see :func:`fingered_song`)."""
    song = fingered_song(song)
    hands = song_hands(song) if task.hands == "song" else ()
    return AgentEnv(PianoEnv(song, **task.env_options(hands)), task)


class Featurizer:
    """Observation dict -> flat float32 vector (D,), plus the planner for residual policies.

    Entries are concatenated in sorted key order; ``goal`` keeps its first
    ``goal_frames_observed`` rows. With ``task.residual`` the planner's action for the current
    state is appended and :meth:`env_action` adds the agent's scaled action to it.
    """

    def __init__(self, env: gym.Env, task: TaskConfig) -> None:
        self.task = task
        space = env.observation_space
        assert isinstance(space, gym.spaces.Dict)  # as a PianoEnv's or an AgentEnv's
        self.keys = sorted(space.spaces)
        goal_shape = _box(space["goal"]).shape
        goal_rows = goal_shape[0]
        self.goal_rows = min(task.goal_frames_observed or goal_rows, goal_rows)
        self.action_dim = int(_box(env.action_space).shape[0])
        sizes = [
            self.goal_rows * goal_shape[1] if k == "goal" else int(np.prod(_box(space[k]).shape))
            for k in self.keys
        ]
        self.obs_dim = int(sum(sizes)) + (self.action_dim if task.residual else 0)
        self._planner: Any = None
        self._base = np.zeros(self.action_dim, np.float32)

    def memory(self) -> list[FingerMemory] | None:
        """A copy of what the residual's planner remembers between steps (None: no planner)."""
        return None if self._planner is None else self._planner.memory()

    def set_memory(self, memory: list[FingerMemory] | None) -> None:
        """Give the planner a :meth:`memory` copy, after :meth:`reset`, to go on from a
        snapshot of the environment taken with it."""
        if memory is not None:
            self._planner.set_memory(memory)

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        """Call after ``env.reset``: restarts the planner of a residual policy."""
        if self.task.residual:
            from pianist.control.planner import IKPlanner

            self._env = control_handle(env)
            self._planner = IKPlanner()
            self._planner.reset(env, seed)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Flat features of ``obs`` (and, residual, the planner's action for this state)."""
        parts = [
            obs[k][: self.goal_rows].ravel() if k == "goal" else np.ravel(obs[k]) for k in self.keys
        ]
        if self.task.residual:
            env = self._env
            if env.step_index < env.num_steps:
                self._base = np.asarray(self._planner.act(obs), np.float32)
            else:  # the state after the last step: no action follows, the planner has no frame
                self._base = np.zeros(self.action_dim, np.float32)
            parts.append(self._base)
        return np.concatenate(parts).astype(np.float32, copy=False)

    def env_action(self, agent_action: np.ndarray) -> np.ndarray:
        """The action sent to the environment for the agent's action in [-1, 1]^A."""
        if not self.task.residual:
            return agent_action
        scaled = self._base + self.task.residual_scale * agent_action
        return np.clip(scaled, -1.0, 1.0).astype(np.float32)
