"""What a controller may see of the environment it drives, and what it may ask of it.

A policy acts from observations alone; controllers that plan (the inverse-kinematics planner,
predictive sampling) also read the simulator's state and the whole song. They get it through a
:class:`ControlHandle`, built by :func:`control_handle` from a :class:`PianoEnv` or any
Gymnasium wrapper around one, instead of reaching into ``env.unwrapped`` themselves.

A controller that needs the environment built a certain way (the planner needs the forearm's
height slide) declares it with an ``env_options(song)`` method returning
:class:`PianoEnv` keyword options; :func:`pianist.eval.session.make_env` is the one place
that applies such declarations.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium as gym
import numpy as np

from pianist.env.piano_env import EnvState, PianoEnv, action_to_ctrl

if TYPE_CHECKING:
    import mujoco

    from pianist.env.config import EnvConfig
    from pianist.env.tape import StepTape
    from pianist.music import GoalFrames, Song
    from pianist.sim.scene import Scene


class ControlHandle:
    """A live, read-only view of one :class:`PianoEnv` for a controller.

    Attributes are the environment's own objects, not copies: ``data`` changes as the episode
    runs. Controllers read them and act only through the actions they return
    (:meth:`play_tape` changes how fast the environment takes its steps, not what they are).
    """

    def __init__(self, env: PianoEnv) -> None:
        self._env = env

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled scene (piano and hands)."""
        return self._env.model

    @property
    def data(self) -> mujoco.MjData:
        """The simulator state; consistent with ``qpos`` after every reset and step (while
        the environment plays a tape back, :mod:`pianist.env.tape`, only ``qpos``, ``qvel``,
        ``act``, ``ctrl``, ``userdata``, ``time`` and the poses derived from them are; the
        rest is brought up to date when the tape is left)."""
        return self._env.data

    @property
    def scene(self) -> Scene:
        """Indices into the model: hands (actuators, fingertip sites, forearm), keys."""
        return self._env.scene

    @property
    def goal(self) -> GoalFrames:
        """The goal frames of the episode (lead-in included), one per step."""
        return self._env.goal

    @property
    def song(self) -> Song | None:
        """The song played (None when the environment was built from goal frames)."""
        return self._env.song

    @property
    def config(self) -> EnvConfig:
        """The environment's resolved configuration."""
        return self._env.config

    @property
    def observation_space(self) -> gym.spaces.Dict:
        """The environment's own observation space (inside any wrapper)."""
        space = self._env.observation_space
        assert isinstance(space, gym.spaces.Dict)
        return space

    @property
    def action_space(self) -> gym.spaces.Box:
        """The environment's own action space (inside any wrapper)."""
        space = self._env.action_space
        assert isinstance(space, gym.spaces.Box)
        return space

    @property
    def control_timestep_s(self) -> float:
        """Seconds of simulated time per step (one goal frame)."""
        return self._env.config.control_timestep_s

    @property
    def step_index(self) -> int:
        """Index of the goal frame the next step will play (0 after reset)."""
        return self._env.step_index

    @property
    def num_steps(self) -> int:
        """Steps of a full episode (one per goal frame)."""
        return self._env.num_steps

    @property
    def action_names(self) -> list[str]:
        """Name of each action dimension: actuator names, then ``sustain``."""
        return self._env.action_names

    def action_to_ctrl(self, action: np.ndarray) -> np.ndarray:
        """Normalised actions (..., nu) in [-1, 1] (sustain excluded) -> actuator controls."""
        return action_to_ctrl(action, self._env.model.actuator_ctrlrange)

    def ctrl_to_action(self, ctrl: np.ndarray) -> np.ndarray:
        """Actuator controls (..., nu) -> normalised actions in [-1, 1] (clipped), the inverse
        of :meth:`action_to_ctrl` inside the control range."""
        low, high = self._env.model.actuator_ctrlrange.T
        return np.clip(2.0 * (np.asarray(ctrl) - low) / (high - low) - 1.0, -1.0, 1.0)

    def snapshot(self, reuse: EnvState | None = None) -> EnvState:
        """The environment's episode state now (a copy; see :meth:`PianoEnv.snapshot`, whose
        ``reuse`` takes over an earlier snapshot the caller is done with)."""
        return self._env.snapshot(reuse)

    def play_tape(self, tape: StepTape) -> bool:
        """Let the environment play back steps recorded (:class:`~pianist.env.tape.StepTape`)
        on a fork of it from its current state while the actions are the recorded ones,
        instead of simulating them (:meth:`PianoEnv.play_tape`: the episode is the same, only
        faster). Returns whether it took the tape (one of another goal, configuration or
        state is refused)."""
        return self._env.play_tape(tape)

    def fork(self, seed: int | None = None) -> PianoEnv:
        """A private copy of the environment in its current state, to look ahead in: step it
        and :meth:`PianoEnv.restore` it to any :meth:`snapshot` of this one (one with no
        episode started yet: reset with ``seed``, :meth:`PianoEnv.fork`)."""
        return self._env.fork(seed)


def control_handle(env: gym.Env) -> ControlHandle:
    """The :class:`ControlHandle` of a :class:`PianoEnv` or of a wrapper around one.

    Raises:
        TypeError: ``env`` is not a piano environment.
    """
    base = env.unwrapped
    if not isinstance(base, PianoEnv):
        raise TypeError(
            f"this controller plays a pianist PianoEnv (or a wrapper of one), not "
            f"{type(base).__name__}"
        )
    return ControlHandle(base)
