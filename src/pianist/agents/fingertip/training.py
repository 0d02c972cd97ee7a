"""Training a fingertip policy: the planner's decisions recorded, behaviour cloning, DAgger.

1. :func:`record`: the expert (:func:`expert_config`: the default planner, whose plan
   fingers the piece for the robot, or the planner with the song's own fingering) plays
   every song once; each step gives every hand's features and the expert's decisions
   (:class:`~pianist.agents.fingertip.controller.ExpertRecorder`).
2. :func:`fit`: an MLP fitted to them by mean squared error on the tanh outputs (the modes
   as +-1 one-hot scores), with :class:`pianist.agents.bc.Trainer` (JAX).
3. :func:`train`: then ``rounds`` of DAgger. Each round the current policy plays a share of
   the songs with the expert in lock-step (:func:`record` with a policy): the states the
   policy reaches are labelled with what the expert would do there, and the policy is
   fitted again, from scratch, on everything so far.

Songs are played in ``workers`` local processes (spawned: the parent has JAX loaded).
"""

from __future__ import annotations

import multiprocessing
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pianist.agents.fingertip.controller import (
    PLAN_FINGERING_CONFIG,
    ExpertRecorder,
    Fingering,
    FingertipController,
    FingertipPolicy,
    Forearm,
    save_policy,
)
from pianist.control.planner import PlannerConfig

Log = Callable[[str], None]


def expert_config(fingering: Fingering = "plan") -> PlannerConfig:
    """The planner the policy learns from. The policy presses each key with the finger of
    the fingering it reads: for ``"plan"`` the default planner, whose own plan is that
    fingering (open-etude-12 0.777, fast); for ``"song"`` the planner's whole-piece hand
    plan with the song's fingering (0.690: a pianist's fingering spans more than this
    hand). The plan is chosen without rehearsal (:data:`PLAN_FINGERING_CONFIG`)."""
    if fingering == "plan":
        return PLAN_FINGERING_CONFIG
    return PlannerConfig().with_fields(hand_planning="piece", refinger=False, reach_poses=())


@dataclass(frozen=True)
class FitConfig:
    """How the network is built and fitted."""

    hidden_dims: tuple[int, ...] = (256, 256)
    steps: int = 6000
    """Adam steps of the first fit; each DAgger round fits ``round_steps`` more than the last
    (it has more data)."""
    round_steps: int = 2000
    input_noise: float = 0.1
    """Std of the noise on the standardised features of each minibatch."""
    batch_size: int = 512
    learning_rate: float = 1e-3
    activation: str = "gelu"
    seed: int = 0


@dataclass
class Recording:
    """Features (N, D), labels (N, :data:`OUTPUT_DIM`), and each song's F1 as played."""

    x: np.ndarray
    y: np.ndarray
    f1: dict[str, float]


def _play_one(
    args: tuple[str, str | None, str, Fingering, Forearm | None],
) -> tuple[np.ndarray, np.ndarray, float]:
    from pianist.eval.session import play

    song, policy_dir, physics, fingering, forearm = args
    expert = ExpertRecorder(expert_config(fingering), fingering)
    controller: Any = (
        expert
        if policy_dir is None
        else FingertipController(policy_dir, expert=expert, forearm=forearm)
    )
    result = play(song, controller, physics=physics, seed=0)
    return np.concatenate(expert.features), np.concatenate(expert.labels), result.metrics["f1"]


def record(
    songs: Sequence[str],
    policy: FingertipPolicy | None = None,
    workers: int = 2,
    physics: str = "fast",
    log: Log | None = None,
    fingering: Fingering = "plan",
    forearm: Forearm | None = None,
) -> Recording:
    """Play each song once (song names or files): the expert alone (``policy`` None), or the
    policy with the expert labelling its states; ``f1`` is the player's. ``fingering``: the
    one the policy reads (a policy's own ``info["fingering"]`` must agree); ``forearm``:
    where the policy's forearms go (:data:`~pianist.agents.fingertip.controller.Forearm`)."""
    if policy is not None and policy.info.get("fingering", "song") != fingering:
        raise ValueError(f"the policy reads the {policy.info.get('fingering', 'song')} fingering")
    with tempfile.TemporaryDirectory() as tmp:
        policy_dir = None
        if policy is not None:
            policy_dir = str(save_policy(policy, Path(tmp) / "policy"))
        jobs = [(str(song), policy_dir, physics, fingering, forearm) for song in songs]
        if workers <= 1:
            results = [_play_one(job) for job in jobs]
        else:
            spawn = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(workers, mp_context=spawn) as pool:
                results = list(pool.map(_play_one, jobs))
    f1 = {str(song): float(r[2]) for song, r in zip(songs, results, strict=True)}
    if log is not None:
        who = "expert" if policy is None else "policy"
        log(f"  {len(songs)} songs played by the {who}: mean F1 {np.mean(list(f1.values())):.3f}")
    return Recording(
        np.concatenate([r[0] for r in results]), np.concatenate([r[1] for r in results]), f1
    )


def fit(x: np.ndarray, y: np.ndarray, config: FitConfig, steps: int) -> FingertipPolicy:
    """A policy fitted to features ``x`` (N, D) and labels ``y`` (N, OUTPUT_DIM) in ``steps``
    Adam steps (JAX)."""
    from pianist.agents.bc import BCConfig, NumpyMLP, Trainer, standardiser

    bc_config = BCConfig(
        hidden_dims=config.hidden_dims,
        activation=config.activation,
        learning_rate=config.learning_rate,
        batch_size=config.batch_size,
        steps=steps,
        input_noise=config.input_noise,
        seed=config.seed,
    )
    mean, std = standardiser(x)
    trainer = Trainer(bc_config, x.shape[1], y.shape[1], mean, std)
    losses = trainer.fit(x, y, steps)
    net = NumpyMLP(trainer.layers(), mean, std, config.activation)
    return FingertipPolicy(net, {"samples": len(x), "final_loss": float(np.mean(losses[-100:]))})


def train(
    songs: Sequence[str],
    rounds: int = 2,
    config: FitConfig | None = None,
    workers: int = 2,
    log: Log | None = None,
    fingering: Fingering = "plan",
    forearm: Forearm | None = None,
) -> FingertipPolicy:
    """The expert's recordings of ``songs``, a fit, then ``rounds`` of DAgger, each on the
    next 1/``rounds`` of the songs (every song played once by the policy over the rounds).
    ``fingering``: the one the policy reads (:func:`expert_config`); ``forearm``: where the
    policy's forearms go in its DAgger rounds (None: as it will play)."""
    config = config or FitConfig()
    say = log or (lambda line: None)
    start = time.perf_counter()
    say(f"recording the expert on {len(songs)} songs")
    data = record(songs, None, workers, log=say, fingering=fingering)
    xs, ys = [data.x], [data.y]
    steps = config.steps
    policy = fit(data.x, data.y, config, steps)
    policy.info["fingering"] = fingering
    history: list[dict[str, Any]] = [{"expert_f1": float(np.mean(list(data.f1.values())))}]
    for r in range(rounds):
        share = list(songs[r::rounds])
        say(f"DAgger round {r + 1}/{rounds}: the policy plays {len(share)} songs")
        played = record(share, policy, workers, log=say, fingering=fingering, forearm=forearm)
        xs.append(played.x)
        ys.append(played.y)
        steps += config.round_steps
        policy = fit(np.concatenate(xs), np.concatenate(ys), config, steps)
        policy.info["fingering"] = fingering
        history.append(
            {
                "round": r + 1,
                "songs": len(share),
                "policy_f1_before": float(np.mean(list(played.f1.values()))),
            }
        )
    policy.info.update(
        {
            "songs": len(songs),
            "rounds": rounds,
            "dagger_forearm": forearm or ("plan" if fingering == "plan" else "policy"),
            "fit": {**asdict(config), "hidden_dims": list(config.hidden_dims)},
            "history": history,
            "minutes": round((time.perf_counter() - start) / 60, 1),
        }
    )
    return policy
