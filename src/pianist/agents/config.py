"""Agent and training configuration: frozen dataclasses and the named presets.

The defaults of :class:`SACConfig` are plain SAC as in the original training code; the preset
``droq-paper`` holds the settings of the paper's runs (facts page, sections 3 and 6). Importing
this module is cheap (no JAX).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

Hands = Literal["both", "right", "left", "song"]


@dataclass(frozen=True)
class SACConfig:
    """Soft actor-critic; DroQ and REDQ are settings of it (see :data:`PRESETS`)."""

    hidden_dims: tuple[int, ...] = (256, 256, 256)
    """Hidden layer sizes of the actor and of each critic."""
    activation: Literal["gelu", "relu", "tanh"] = "gelu"
    num_qs: int = 2
    """Critics in the ensemble."""
    num_min_qs: int | None = None
    """REDQ: the target takes the minimum over this many critics drawn at random (None: all)."""
    critic_dropout: float = 0.0
    """DroQ: dropout rate in the critics' hidden layers (before layer norm)."""
    critic_layer_norm: bool = False
    discount: float = 0.99
    tau: float = 0.005
    """Target critic EMA rate per update."""
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    temp_lr: float = 3e-4
    init_temperature: float = 1.0
    target_entropy_per_dim: float = -0.5
    """Target entropy = this * |A| (the original: -|A|/2)."""
    log_std_min: float = -20.0
    log_std_max: float = 2.0
    backup_entropy: bool = True
    """Subtract the next state's entropy bonus in the critic target."""
    batch_size: int = 256
    zero_mean_init: bool = False
    """Start the actor's mean head at zero weights: the first mean action is exactly 0 (for a
    residual policy, the planner's action)."""
    init_log_std: float | None = None
    """Start the actor's log-std head at zero weights and this bias (a small, state-independent
    initial std); None: Xavier weights and zero bias like the other layers."""
    residual_penalty: float = 0.0
    """Actor loss term: this * mean over the batch of sum_i tanh(mean_i)^2, pulling the mean
    action towards 0 (for a residual policy: towards the planner's action)."""

    def __post_init__(self) -> None:
        if self.num_qs < 1:
            raise ValueError(f"num_qs must be >= 1, not {self.num_qs}")
        if self.num_min_qs is not None and not 1 <= self.num_min_qs <= self.num_qs:
            raise ValueError(
                f"num_min_qs must be in 1..num_qs ({self.num_qs}), not {self.num_min_qs}"
            )
        if not 0.0 <= self.critic_dropout < 1.0:
            raise ValueError(f"critic_dropout must be in [0, 1), not {self.critic_dropout}")
        if not self.hidden_dims or min(self.hidden_dims) < 1:
            raise ValueError(f"hidden_dims must be positive sizes, not {self.hidden_dims}")
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, not {self.batch_size}")
        if self.residual_penalty < 0:
            raise ValueError(f"residual_penalty must be >= 0, not {self.residual_penalty}")
        if self.init_log_std is not None and not (
            self.log_std_min <= self.init_log_std <= self.log_std_max
        ):
            raise ValueError(
                f"init_log_std must be in [{self.log_std_min}, {self.log_std_max}], "
                f"not {self.init_log_std}"
            )


@dataclass(frozen=True)
class TaskConfig:
    """The environment the agent sees: env options plus the observation and action wrappers."""

    lookahead: int = 10
    hands: Hands = "both"
    """"song" uses only the hands that the song's notes are fingered for."""
    physics: Literal["faithful", "fast"] = "faithful"
    reduced_action_space: bool = True
    gravity_compensation: bool = True
    primitive_fingertip_collisions: bool = True
    forearm_dofs: tuple[str, ...] = ("tx", "ty")
    """Forearm joints (the paper's: slide along the keyboard and towards it)."""
    initial_buffer_s: float = 0.0
    """Seconds of silence before the song (the original's ``initial_buffer_time``)."""
    action_reward_observation: bool = True
    """Previous action and reward in the observation (the paper's runs)."""
    goal_frames_observed: int | None = None
    """Goal rows (88 keys + sustain) in the observation, from the current frame on; None: all
    L + 1 rows as in the paper."""
    finger_target_frames: int = 0
    """Compact goal: for frames t..t+n-1 and every finger, whether it is due and the vector from
    its fingertip to its key's target (m x 10). 0: off."""
    residual: bool = False
    """Act as a correction added to the inverse-kinematics planner's action, in the environment
    the planner declares (its ``env_options``, e.g. the forearm height slide, override the
    fields above)."""
    residual_scale: float = 0.3
    """The residual's range: final action = clip(planner + scale * agent action, -1, 1)."""

    def env_options(self, song_hands: tuple[str, ...] = ()) -> dict[str, Any]:
        """Keyword options of :class:`pianist.env.PianoEnv` (``song_hands``: the song's hands)."""
        hands: str = self.hands
        if hands == "song":
            hands = song_hands[0] if len(song_hands) == 1 else "both"
        options: dict[str, Any] = {
            "lookahead": self.lookahead,
            "hands": hands,
            "physics": self.physics,
            "reduced_action_space": self.reduced_action_space,
            "gravity_compensation": self.gravity_compensation,
            "primitive_fingertip_collisions": self.primitive_fingertip_collisions,
            "forearm_dofs": self.forearm_dofs,
            "initial_buffer_s": self.initial_buffer_s,
        }
        if self.residual:
            from pianist.control.planner import IKPlanner

            options.update(IKPlanner().env_options())
        return options


@dataclass(frozen=True)
class TrainConfig:
    """One training run: task, agent, and the loop's schedule. Steps are environment steps."""

    preset: str = "custom"
    task: TaskConfig = field(default_factory=TaskConfig)
    agent: SACConfig = field(default_factory=SACConfig)
    seed: int = 0
    seed_steps: int = 5000
    """Steps of ``seed_policy`` actions before the first update."""
    seed_policy: Literal["uniform", "actor"] = "uniform"
    """Actions of the seed steps: uniform in [-1, 1]^A, or samples of the initial actor (with
    a zero-initialised mean and a small std: the planner plus small noise for a residual)."""
    replay_capacity: int = 1_000_000
    updates_per_step: int = 1
    """Update-to-data ratio."""
    steps_per_iteration: int = 1
    """Environment steps between blocks of updates; a block is one jitted call (lax.scan) of
    steps_per_iteration * updates_per_step updates. 1 = the paper's act-update alternation."""
    pipeline: bool = False
    """Dispatch a block of updates, then act with the parameters from before it while it runs
    on the other core (the acting policy lags one block behind)."""
    eval_interval: int = 10_000
    """Evaluate one deterministic episode every this many steps (and at the end)."""
    eval_physics: Literal["faithful", "fast"] | None = None
    """The physics preset of those evaluations, which choose the policy kept in ``best/``
    (and that ``pianist eval`` plays in unless told); None: the one trained in. A policy
    trained on the fast preset and judged on the faithful one is best chosen there: the best
    fast-physics evaluation of a from-scratch run can transfer worse than a later policy."""
    checkpoint_interval: int = 10_000
    """Checkpoint at the first episode end after this many steps since the last one."""
    windows: bool = False
    """Practise the hard parts: a share of the training episodes are short windows that
    start mid-piece from states the planner reaches there, drawn more often where the policy
    loses F1 (:mod:`pianist.agents.windows`). Evaluation stays the whole piece."""
    window_s: float = 4.0
    """Seconds of a window episode (it is truncated after them, or at the piece's end)."""
    window_stride_s: float = 1.0
    """Seconds between two windows' starts."""
    window_share: float = 0.75
    """Share of the training episodes that are windows; the rest play the whole piece."""
    window_power: float = 2.0
    """A window is drawn with weight (its error + 0.01) ** power, error = 1 - its F1. The
    planner's errors on mozart-sonata-k545-allegro's 4 s windows lie in 0.11-0.24: power 1
    would draw the hardest only 1.8 times as often as the easiest, power 2 3.3 times."""
    window_uniform: float = 0.2
    """Share of the window draws made uniformly over all windows."""

    def __post_init__(self) -> None:
        for name in (
            "replay_capacity",
            "updates_per_step",
            "steps_per_iteration",
            "eval_interval",
            "checkpoint_interval",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, not {getattr(self, name)}")
        if self.seed_steps < 0:
            raise ValueError(f"seed_steps must be >= 0, not {self.seed_steps}")
        if self.eval_physics not in (None, "faithful", "fast"):
            raise ValueError(
                f"eval_physics must be 'faithful', 'fast' or None, not {self.eval_physics!r}"
            )
        if self.seed_policy not in ("uniform", "actor"):
            raise ValueError(f"seed_policy must be 'uniform' or 'actor', not {self.seed_policy!r}")
        if not (self.window_s > 0 and self.window_stride_s > 0 and self.window_power >= 0):
            raise ValueError(
                "window_s and window_stride_s must be > 0 and window_power >= 0, not "
                f"{self.window_s}, {self.window_stride_s}, {self.window_power}"
            )
        for name in ("window_share", "window_uniform"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], not {getattr(self, name)}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @property
    def eval_task(self) -> TaskConfig:
        """The task of the evaluations: the training task in :attr:`eval_physics`, if set."""
        if self.eval_physics is None:
            return self.task
        return dataclasses.replace(self.task, physics=self.eval_physics)

    @staticmethod
    def from_dict(data: dict[str, Any]) -> TrainConfig:
        """Inverse of :meth:`to_dict` (as read back from JSON)."""
        try:
            agent = dict(data["agent"])
            agent["hidden_dims"] = tuple(agent["hidden_dims"])
            rest = {k: v for k, v in data.items() if k not in ("task", "agent")}
            task = dict(data["task"])
            task["forearm_dofs"] = tuple(task.get("forearm_dofs", TaskConfig.forearm_dofs))
            return TrainConfig(task=TaskConfig(**task), agent=SACConfig(**agent), **rest)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a training configuration ({exc})") from None


DROQ_PAPER = TrainConfig(
    preset="droq-paper",
    task=TaskConfig(),
    agent=SACConfig(
        hidden_dims=(256, 256, 256),
        num_qs=2,
        critic_dropout=0.01,
        critic_layer_norm=True,
        discount=0.8,
    ),
)

# What learns a piece in the least wall-clock time here (benchmarks/bench_train.py): one hand
# when the song needs one, the fast physics preset, a compact goal (fingertip-to-target vectors
# and 2 goal rows instead of 11 x 89 bits), 2 x 256 networks and batches of 128, blocks of 8
# updates run on the second core while the first one steps the environment. Its evaluations,
# which choose the policy kept, are on the faithful physics, where pieces are judged.
FAST = TrainConfig(
    preset="fast",
    task=TaskConfig(
        hands="song",
        physics="fast",
        goal_frames_observed=2,
        finger_target_frames=3,
    ),
    agent=dataclasses.replace(DROQ_PAPER.agent, hidden_dims=(256, 256), batch_size=128),
    seed_steps=2000,
    steps_per_iteration=8,
    pipeline=True,
    eval_interval=5000,
    eval_physics="faithful",
    checkpoint_interval=20_000,
)

PRESETS: dict[str, TrainConfig] = {
    "droq-paper": DROQ_PAPER,
    # The same math as droq-paper, run in blocks of 10 steps with updates on the second core.
    "droq-paper-pipelined": dataclasses.replace(
        DROQ_PAPER, preset="droq-paper-pipelined", steps_per_iteration=10, pipeline=True
    ),
    # Plain SAC with the original code's defaults, on the paper's task.
    "sac": TrainConfig(preset="sac", task=TaskConfig(), agent=SACConfig()),
    # REDQ (Chen et al. 2021): 10 critics, min over 2 drawn at random, 20 updates per step.
    "redq": TrainConfig(
        preset="redq",
        task=TaskConfig(),
        agent=SACConfig(num_qs=10, num_min_qs=2, discount=0.8),
        updates_per_step=20,
    ),
    "fast": FAST,
    # Fast, with 2 x 128 networks: updates cost about half as much.
    "fast-small": dataclasses.replace(
        FAST, preset="fast-small", agent=dataclasses.replace(FAST.agent, hidden_dims=(128, 128))
    ),
    # Fast, with a higher update-to-data ratio.
    "fast-utd2": dataclasses.replace(FAST, preset="fast-utd2", updates_per_step=2),
    # A correction on top of the inverse-kinematics planner, in the environment the planner
    # declares (TaskConfig.residual).
    "residual": dataclasses.replace(
        FAST,
        preset="residual",
        task=dataclasses.replace(FAST.task, residual=True, residual_scale=0.3),
        seed_steps=1000,
    ),
    # The residual made to start as the planner and stay near it: a zero-initialised mean head
    # (the first policy plays exactly the planner); a small state-independent initial std,
    # exp(-2.3) = 0.1 before tanh (0.03 in action units at scale 0.3), capped at exp(-1.5) =
    # 0.22 (Adam otherwise inflates it to ~0.5 within 1000 updates); seed steps that sample
    # this actor instead of uniform noise; a penalty on the residual's size; a lower actor
    # learning rate; and evaluations every 2000 steps, so that run_dir/best keeps the best
    # policy. On c-major-chords and d-major-scale-right it rises above the planner within
    # minutes and stays there (benchmarks/bench_train.py), where `residual` oscillates around
    # the planner's F1 and ends below it.
    "residual-anchored": dataclasses.replace(
        FAST,
        preset="residual-anchored",
        task=dataclasses.replace(FAST.task, residual=True, residual_scale=0.3),
        agent=dataclasses.replace(
            FAST.agent,
            zero_mean_init=True,
            init_log_std=-2.3,
            log_std_max=-1.5,
            target_entropy_per_dim=-1.0,
            init_temperature=0.1,
            actor_lr=1e-4,
            residual_penalty=0.5,
        ),
        seed_steps=1000,
        seed_policy="actor",
        eval_interval=2000,
    ),
}

# Practise the hard parts: residual-anchored, with three training episodes in four being
# 4-second windows started mid-piece from the planner's states, drawn more often where the
# policy loses F1 (TrainConfig.windows); evaluation stays the whole piece.
PRESETS["residual-windows"] = dataclasses.replace(
    PRESETS["residual-anchored"], preset="residual-windows", windows=True
)

#: The preset of ``pianist train`` and ``pianist sweep --task train`` that practises one piece
#: (:mod:`pianist.agents.practice`): a correction per step learned by replaying the piece with
#: the refiner's look-ahead, not a soft actor-critic agent (it has no :class:`TrainConfig`).
PRACTICE_PRESET = "practice"

#: The preset ``pianist train`` and ``pianist sweep --task train`` use unless told: the best
#: measured per wall-clock minute on real pieces (docs/notes/2026-12-07-training-history.md:
#: practice took four real pieces from 0.739 to 0.829 mean F1 in 8 minutes;
#: ``residual-anchored``, the best agent, moved K545 by 0.01 in 10). ``droq-paper``, the
#: paper's recipe, needs millions of steps.
DEFAULT_PRESET = PRACTICE_PRESET


def get_preset(name: str, **overrides: Any) -> TrainConfig:
    """The preset ``name`` with top-level fields replaced by ``overrides``."""
    if name == PRACTICE_PRESET:
        raise ValueError(
            "practice is not a soft actor-critic preset: run it with `pianist train SONG "
            "--preset practice` or pianist.agents.practice.practise"
        )
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    try:
        return dataclasses.replace(PRESETS[name], **overrides)
    except TypeError as exc:
        raise ValueError(f"bad override for preset {name!r}: {exc}") from None
