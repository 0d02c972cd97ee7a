"""Environment configuration: frozen dataclasses whose defaults are the paper's settings."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pianist.sim import constants as C
from pianist.sim.hands import HandOptions
from pianist.sim.scene import SceneOptions

REWARD_TERMS = ("key_press", "fingering", "energy", "sustain", "forearm", "velocity")
FINGERING_REWARDS = ("assigned", "optimal")


@dataclass(frozen=True)
class RewardWeights:
    """Weight of each raw term in the total reward (energy's raw value is a power in W)."""

    key_press: float = 1.0
    fingering: float = 1.0
    energy: float = -5e-3
    sustain: float = 1.0
    forearm: float = 1.0
    velocity: float = 1.0
    """Its term is 0 unless ``velocity_goal`` is on (the paper's task has no loudness)."""

    def as_dict(self) -> dict[str, float]:
        return {name: getattr(self, name) for name in REWARD_TERMS}


@dataclass(frozen=True)
class EnvConfig:
    """Everything that defines a piano task apart from the song.

    The scene (hands, physics preset) lives in ``scene``; see :class:`SceneOptions` and
    :class:`HandOptions` for their fields.
    """

    lookahead: int = 10
    """Future goal frames in the observation beyond the current one (L)."""
    control_timestep_s: float = C.CONTROL_TIMESTEP_S
    wrong_press_termination: bool = False
    """End the episode (terminated) as soon as a key that is not due sounds."""
    randomize_hand_positions: bool = False
    """Start each forearm up to 5 cm along the keyboard from its home, drawn from the seed."""
    initial_buffer_s: float = 0.0
    """Silence before the song, rounded to whole control steps (the original's
    ``initial_buffer_time``, default 0 there too): time for the hands to reach the first
    notes, which the debug songs make due in the very first step. Its steps are scored like
    any other (nothing due); :meth:`pianist.eval.Episode.metrics` also scores the song's steps
    alone."""
    fingering_reward: str = "assigned"
    """"assigned": each due key's labelled finger is pulled to it (the paper); "optimal": the
    fingertips are matched to the due keys by a minimum-distance assignment each step, so no
    fingering labels are needed (RP1M; facts page section 3)."""
    velocity_goal: bool = False
    """Also observe the loudness asked for: ``goal_velocity``, the MIDI velocity / 127 of each
    note starting in the observed frames (off by default: the paper's task)."""
    scene: SceneOptions = field(default_factory=SceneOptions)
    rewards: RewardWeights = field(default_factory=RewardWeights)

    def __post_init__(self) -> None:
        if self.lookahead < 0:
            raise ValueError(f"lookahead must be >= 0, not {self.lookahead}")
        if self.fingering_reward not in FINGERING_REWARDS:
            raise ValueError(
                f"fingering_reward must be one of {', '.join(FINGERING_REWARDS)}, "
                f"not {self.fingering_reward!r}"
            )
        buffer = self.initial_buffer_s
        number = isinstance(buffer, int | float) and not isinstance(buffer, bool)
        if not (number and math.isfinite(buffer) and buffer >= 0):
            raise ValueError(f"initial_buffer_s must be a number of seconds >= 0, not {buffer!r}")
        timestep = self.scene.physics_preset.timestep_s
        ratio = self.control_timestep_s / timestep
        if self.control_timestep_s <= 0 or abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ValueError(
                f"control timestep {self.control_timestep_s} s must be a positive multiple of "
                f"the physics timestep {timestep} s"
            )

    @property
    def substeps(self) -> int:
        """Physics steps per control step."""
        return round(self.control_timestep_s / self.scene.physics_preset.timestep_s)

    @property
    def lead_in_steps(self) -> int:
        """Control steps of silence before the song (``initial_buffer_s`` rounded)."""
        return round(self.initial_buffer_s / self.control_timestep_s)


def make_config(
    *,
    lookahead: int = 10,
    hands: str = "both",
    physics: str | None = "faithful",
    reduced_action_space: bool = True,
    primitive_fingertip_collisions: bool = True,
    gravity_compensation: bool = True,
    hand_collisions: bool = True,
    forearm_dofs: tuple[str, ...] = ("tx", "ty"),
    wrong_press_termination: bool = False,
    randomize_hand_positions: bool = False,
    initial_buffer_s: float = 0.0,
    control_timestep_s: float = C.CONTROL_TIMESTEP_S,
    rewards: RewardWeights | None = None,
    fingering_reward: str = "assigned",
    velocity_goal: bool = False,
) -> EnvConfig:
    """Flat keyword options -> :class:`EnvConfig` (what ``pianist.make_env`` accepts).

    Raises:
        ValueError: an option of the wrong kind (a flag that is not a bool, ``forearm_dofs``
            given as one string, ``rewards`` that are not :class:`RewardWeights`) or value.
    """
    flags = {
        "reduced_action_space": reduced_action_space,
        "primitive_fingertip_collisions": primitive_fingertip_collisions,
        "gravity_compensation": gravity_compensation,
        "hand_collisions": hand_collisions,
        "wrong_press_termination": wrong_press_termination,
        "randomize_hand_positions": randomize_hand_positions,
        "velocity_goal": velocity_goal,
    }
    for name, value in flags.items():
        if not isinstance(value, bool | np.bool_):
            raise ValueError(f"{name} must be True or False, not {value!r}")
    if isinstance(forearm_dofs, str):
        raise ValueError(f"forearm_dofs is a sequence such as ('tx', 'ty'), not {forearm_dofs!r}")
    if rewards is not None and not isinstance(rewards, RewardWeights):
        raise ValueError(f"rewards must be a RewardWeights, not {type(rewards).__name__}")
    return EnvConfig(
        lookahead=lookahead,
        control_timestep_s=control_timestep_s,
        wrong_press_termination=wrong_press_termination,
        randomize_hand_positions=randomize_hand_positions,
        initial_buffer_s=initial_buffer_s,
        fingering_reward=fingering_reward,
        velocity_goal=velocity_goal,
        scene=SceneOptions(
            hands=hands,  # type: ignore[arg-type]
            physics="faithful" if physics is None else physics,
            hand=HandOptions(
                reduced_action_space=reduced_action_space,
                primitive_fingertip_collisions=primitive_fingertip_collisions,
                gravity_compensation=gravity_compensation,
                hand_collisions=hand_collisions,
                forearm_dofs=tuple(forearm_dofs),
            ),
        ),
        rewards=rewards or RewardWeights(),
    )
