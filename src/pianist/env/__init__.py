"""The Gymnasium environment, its rewards and its registered ids."""

from pianist.env.config import EnvConfig, RewardWeights, make_config
from pianist.env.piano_env import EnvState, PianoEnv, SimulationUnstableError
from pianist.env.registration import register_envs

__all__ = [
    "EnvConfig",
    "EnvState",
    "PianoEnv",
    "RewardWeights",
    "SimulationUnstableError",
    "make_config",
    "register_envs",
]

register_envs()
