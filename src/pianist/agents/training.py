"""The training loop: act, store, update in jitted blocks, evaluate, log, checkpoint, resume.

One iteration steps the environment ``n`` times (``steps_per_iteration``, cut at the end of
an episode) and runs ``n * updates_per_step`` updates as one jitted call. Without
``pipeline`` the environment steps come first and the updates follow (n = 1 is the paper's
alternation). With ``pipeline`` the updates are dispatched first (JAX runs them on its own
thread) and the steps use the actor from before them, so the physics and the networks run on
the two cores at once; the order of all random draws is the same either way, so a run is
reproducible.

Randomness: the JAX key lives in the agent state; exploration noise and replay sampling use
two NumPy generators; each training episode resets the environment with a seed derived from
the run seed and the episode number. Checkpoints are taken at episode ends (the environment
needs no saved state then), so a resumed run repeats exactly what the interrupted one did.

With ``TrainConfig.windows`` a share of the episodes start mid-piece and are truncated after a
few seconds (:mod:`pianist.agents.windows`): the window starts are recorded again when a run
resumes (the recording is deterministic), the windows' errors and the draws' generator are
in the checkpoint.

The loop (:func:`train`) reads top to bottom; everything it carries from one iteration to the
next is in a :class:`_Run`, and each part of an iteration is a function of its own.
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.agents import checkpoint as ckpt
from pianist.agents import rundir
from pianist.agents.config import TrainConfig, get_preset
from pianist.agents.envs import AgentEnv, Featurizer, make_agent_env
from pianist.agents.policy import NumpyActor, PolicyController
from pianist.agents.replay import ReplayBuffer
from pianist.agents.rundir import RunLog
from pianist.agents.windows import Windows, record_windows, start_window, step_f1
from pianist.eval import run_episode

if TYPE_CHECKING:
    from pianist.agents.sac import SAC, SACState

EVAL_KEYS = ("precision", "recall", "f1", "sustain_f1", "return")


@dataclass
class TrainResult:
    """What :func:`train` did: the final step, the last evaluation, where it resumed from, and
    the best evaluation (its policy is kept in ``run_dir/best``)."""

    step: int
    last_eval: dict[str, float]
    resumed_from: int | None
    wall_s: float
    run_dir: Path
    best_eval: dict[str, float] | None = None


@dataclass
class _Run:
    """A training run in progress: what it is set up with, and all that changes as it runs.

    The counters, the RNG states and ``last_eval`` are what a checkpoint's state.json keeps
    (:func:`_checkpoint`), next to the agent state and the replay buffer.
    """

    # Set up once.
    out: Path
    config: TrainConfig
    env: AgentEnv
    eval_env: AgentEnv
    features: Featurizer
    agent: SAC
    # The learner and what it learns from.
    state: SACState
    replay: ReplayBuffer
    explore_rng: np.random.Generator  # seed-step actions and exploration noise
    sample_rng: np.random.Generator  # replay batches
    actor: NumpyActor  # acts in NumPy: a copy of state.actor, refreshed after each update
    # Counters.
    step: int = 0  # environment steps
    episode: int = 0  # training episodes started before the current one
    updates: int = 0
    wall_s: float = 0.0  # training wall time up to ``clock``, over all calls of train()
    last_eval_step: int = -1
    last_checkpoint_step: int = 0
    # Evaluations.
    last_eval: dict[str, float] = field(default_factory=dict)
    best_eval: dict[str, Any] | None = None  # the log row of the best evaluation F1
    resumed_from: int | None = None
    # The current episode: the feature vector of its latest observation, its return so far.
    x: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    episode_return: float = 0.0
    # For the "train" log rows.
    metrics: dict[str, Any] | None = None  # losses of the latest block of updates (on device)
    clock: float = 0.0  # time.perf_counter() up to which wall_s counts
    rate_step: int = 0  # step and time of the previous "train" row
    rate_clock: float = 0.0
    # Windows (TrainConfig.windows): the window starts and their errors, the generator of
    # the draws, and the current episode's window (-1: the whole piece), first and end step
    # (where it is truncated), and its sounding and due keys per step.
    windows: Windows | None = None
    window_rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    episode_window: int = -1
    episode_start: int = 0
    episode_end: int = 0
    episode_keys: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def train(
    song: str | None,
    preset: str | TrainConfig | None,
    steps: int,
    out_dir: str | Path,
    resume: bool = False,
    progress: bool = True,
    message: Callable[[str], None] | None = None,
    stop_after_s: float | None = None,
    budget_from: float | None = None,
) -> TrainResult:
    """Train an agent on ``song`` for ``steps`` environment steps in total.

    Args:
        song: a built-in song name or a file (None when resuming: read from the run).
        preset: a preset name (:data:`pianist.agents.config.PRESETS`) or a TrainConfig
            (None when resuming).
        steps: total environment steps of the run (a resumed run continues up to it).
        out_dir: the run directory (config.json, log.jsonl, checkpoints/).
        resume: continue the run in ``out_dir`` from its newest checkpoint.
        progress: show a tqdm bar with steps/s and the latest F1.
        message: called with one-line notices (e.g. the step a run resumed from).
        stop_after_s: stop at the end of the episode in which this much wall time has passed
            in this call (after a checkpoint; a resumed run then goes on exactly as an
            uninterrupted one), without a last evaluation when the run has one:
            ``pianist train --minutes``.
        budget_from: the ``time.perf_counter()`` the budget counts from (default: when the
            training loop starts, after the setup; ``pianist train`` gives its own start, so
            that importing JAX and compiling count too).
    """
    from tqdm import tqdm

    out = Path(out_dir)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, not {steps}")
    song, config = _resumed_setup(out, preset) if resume else _new_setup(out, song, preset)
    run = _new_run(out, song, config, steps)
    if resume:
        checkpoint = _resume_run(run)
        if message is not None:
            message(f"resumed {out} from step {run.resumed_from} (checkpoint {checkpoint.name})")
    else:
        rundir.remove_log(out)  # of an earlier run here that never checkpointed

    env = run.env
    bar = tqdm(total=steps, initial=run.step, unit="step", dynamic_ncols=True, disable=not progress)
    with RunLog(out) as log, bar:
        run.clock = run.rate_clock = started = time.perf_counter()
        if budget_from is not None:
            started = budget_from
        run.rate_step = run.step
        _start_episode(run)
        out_of_time = False
        while run.step < steps:
            n = min(config.steps_per_iteration, run.episode_end - env.step_index, steps - run.step)
            learning = run.step >= config.seed_steps and run.replay.transitions > 0
            if learning and config.pipeline:
                _update(run, n)  # JAX runs it on its own thread while _collect steps
            done = _collect(run, n)  # with pipeline: with the actor from before _update
            if learning and not config.pipeline:
                _update(run, n)
            if learning:
                run.actor = _numpy_actor(run)
            bar.update(run.step - bar.n)
            if _eval_due(run):
                _evaluate(run, log)
                bar.set_postfix(f1=f"{run.last_eval['f1']:.3f}", refresh=False)
            if run.step - run.rate_step >= 1000:
                steps_per_s = _log_rate(run, log)
                bar.set_postfix(sps=f"{steps_per_s:.0f}", f1=run.last_eval.get("f1", math.nan))
            if done:
                _end_episode(run, log)
                out_of_time = (
                    stop_after_s is not None and time.perf_counter() - started >= stop_after_s
                )
                if out_of_time or _checkpoint_due(run):
                    _checkpoint(run, mid_episode=False)
                    if out_of_time:
                        break
                if run.step < steps:
                    _start_episode(run)
        if run.last_eval_step != run.step and not (out_of_time and run.last_eval):
            _evaluate(run, log)
        if run.last_checkpoint_step != run.step or run.step == 0:
            _checkpoint(run, mid_episode=env.step_index not in (run.episode_start, run.episode_end))
    return TrainResult(run.step, run.last_eval, run.resumed_from, run.wall_s, out, run.best_eval)


def _new_setup(
    out: Path, song: str | None, preset: str | TrainConfig | None
) -> tuple[str, TrainConfig]:
    """The song and configuration of a new run in ``out``, which must not hold a run already;
    makes the directory."""
    if song is None or preset is None:
        raise ValueError("a new run needs a song and a preset")
    config = get_preset(preset) if isinstance(preset, str) else preset
    if rundir.holds_run(out):
        raise ValueError(f"{out} already holds a run: resume it or choose another directory")
    out.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(rundir.best_dir(out), ignore_errors=True)  # left by a run that never checkpointed
    return song, config


def _resumed_setup(out: Path, preset: str | TrainConfig | None) -> tuple[str, TrainConfig]:
    """The song and configuration of the run in ``out``; ``preset``, if a name, must match."""
    run = rundir.read_run_config(out)
    config = TrainConfig.from_dict(run["config"])
    if preset is not None and isinstance(preset, str) and preset != config.preset:
        raise ValueError(f"{out} was trained with preset {config.preset!r}, not {preset!r}")
    return run["song"], config


def _new_run(out: Path, song: str, config: TrainConfig, steps: int) -> _Run:
    """Set up a run at step 0: environments, a fresh agent, an empty replay buffer, seeded
    RNGs; write config.json."""
    from pianist.agents.sac import make_agent

    env = make_agent_env(song, config.task)
    eval_env = make_agent_env(song, config.eval_task)
    features = Featurizer(env, config.task)
    rundir.write_run_config(
        out,
        {
            "song": song,
            "steps": steps,
            "config": config.to_dict(),
            "env_options": config.task.env_options(tuple(_hands_of(env))),
            "obs_dim": features.obs_dim,
            "action_dim": features.action_dim,
        },
    )
    agent = make_agent(features.obs_dim, features.action_dim, config.agent)
    state = agent.init(config.seed)
    windows, recording_s = None, 0.0
    if config.windows:  # on the training environment: each episode resets it anyway
        clock = time.perf_counter()
        dt = env.config.control_timestep_s
        windows, _ = record_windows(
            env,
            features,
            max(1, round(config.window_s / dt)),
            max(1, round(config.window_stride_s / dt)),
            config.seed,
        )
        recording_s = time.perf_counter() - clock  # training time (a resumed run: setup)
    return _Run(
        out=out,
        config=config,
        env=env,
        eval_env=eval_env,
        features=features,
        agent=agent,
        state=state,
        replay=ReplayBuffer(features.obs_dim, features.action_dim, config.replay_capacity),
        explore_rng=np.random.default_rng([config.seed, 1]),
        sample_rng=np.random.default_rng([config.seed, 2]),
        actor=_numpy_actor_of(state, config),
        wall_s=recording_s,
        windows=windows,
        window_rng=np.random.default_rng([config.seed, 3]),
    )


def _resume_run(run: _Run) -> Path:
    """Restore ``run`` from the newest checkpoint of its directory and drop the log rows
    written after that checkpoint; returns the checkpoint's folder."""
    import jax

    checkpoint = ckpt.latest_checkpoint(run.out)
    saved = ckpt.load_state(checkpoint)
    leaves, treedef = jax.tree_util.tree_flatten(run.state)
    leaves = ckpt.load_agent_leaves(checkpoint, [np.asarray(x) for x in leaves])
    run.state = jax.tree_util.tree_unflatten(treedef, [jax.numpy.asarray(x) for x in leaves])
    run.actor = _numpy_actor(run)
    run.replay.load_arrays(ckpt.load_replay_arrays(checkpoint))
    run.explore_rng.bit_generator.state = saved["explore_rng"]
    run.sample_rng.bit_generator.state = saved["sample_rng"]
    if run.windows is not None:
        run.windows.load_state(saved["windows"])
        run.window_rng.bit_generator.state = saved["windows"]["rng"]
    counters = {**_counters(run), **saved["counters"]}  # a counter missing: its start value
    run.step = int(counters["step"])
    run.episode = int(counters["episode"])
    run.updates = int(counters["updates"])
    run.wall_s = float(counters["wall_s"])
    run.last_eval_step = int(counters["last_eval"])
    run.last_checkpoint_step = int(counters["last_checkpoint"])
    run.last_eval = saved.get("last_eval", {})
    run.best_eval = ckpt.best_evaluation(run.out)
    run.resumed_from = run.step
    rundir.truncate_log(run.out, run.step)
    return checkpoint


def _counters(run: _Run) -> dict[str, Any]:
    """The counters as a checkpoint's state.json stores them (the names old runs used)."""
    return {
        "step": run.step,
        "episode": run.episode,
        "updates": run.updates,
        "wall_s": run.wall_s,
        "last_eval": run.last_eval_step,
        "last_checkpoint": run.last_checkpoint_step,
    }


def _start_episode(run: _Run) -> None:
    """Reset the environment for training episode ``run.episode`` (its own derived seed):
    at the start of the piece, or (``TrainConfig.windows``) at a window drawn for it."""
    config, env = run.config, run.env
    seed = _episode_seed(config.seed, run.episode)
    run.episode_window, run.episode_end = -1, env.num_steps
    if run.windows is not None and run.window_rng.random() < config.window_share:
        i = run.windows.draw(run.window_rng, config.window_power, config.window_uniform)
        obs = start_window(env, run.features, run.windows.starts[i], seed)
        run.episode_window, run.episode_end = i, int(run.windows.ends[i])
    else:
        obs, _ = env.reset(seed=seed)
        run.features.reset(env, seed)
    run.episode_start = env.step_index
    run.episode_keys = []
    run.x = run.features(obs)
    run.replay.start_episode(run.x)


def _episode_seed(seed: int, episode: int) -> int:
    return int(np.random.SeedSequence([seed, 7, episode]).generate_state(1)[0])


def _collect(run: _Run, n: int) -> bool:
    """Step the environment up to ``n`` times, storing each transition in the replay buffer;
    True if the episode ended (after fewer steps, then)."""
    config, features = run.config, run.features
    for _ in range(n):
        if run.step < config.seed_steps and config.seed_policy == "uniform":
            a = run.explore_rng.uniform(-1.0, 1.0, features.action_dim).astype(np.float32)
        else:
            a = run.actor.sample(run.x, run.explore_rng).astype(np.float32)
        obs, reward, terminated, truncated, info = run.env.step(features.env_action(a))
        run.x = features(obs)
        run.replay.add(a, reward, 0.0 if terminated else 1.0, run.x)
        run.episode_return += reward
        run.step += 1
        if run.windows is not None:
            run.episode_keys.append((info["active_keys"], info["goal_keys"]))
        if terminated or truncated or run.env.step_index >= run.episode_end:
            return True
    return False


def _update(run: _Run, n: int) -> None:
    """Run ``n * updates_per_step`` updates on batches sampled from the replay buffer, as one
    jitted call.

    JAX only dispatches the call: it runs on JAX's own thread until a result is read
    (:func:`_numpy_actor`, :func:`_log_rate`), which lets the pipeline step the environment
    meanwhile.
    """
    k = n * run.config.updates_per_step
    batches = run.replay.sample(run.sample_rng, run.config.agent.batch_size, k)
    run.state, run.metrics = run.agent.update_many(run.state, batches)
    run.updates += k


def _numpy_actor(run: _Run) -> NumpyActor:
    """The NumPy copy of the actor of ``run.state`` (waits for pending updates)."""
    return _numpy_actor_of(run.state, run.config)


def _numpy_actor_of(state: SACState, config: TrainConfig) -> NumpyActor:
    from pianist.agents.sac import actor_weights

    c = config.agent
    return NumpyActor(actor_weights(state.actor), c.activation, c.log_std_min, c.log_std_max)


def _wall_s(run: _Run) -> float:
    """Training wall time so far, over all calls of :func:`train` for this run."""
    return run.wall_s + time.perf_counter() - run.clock


def _evaluate(run: _Run, log: RunLog) -> None:
    """Play one deterministic episode with the current actor and log it; keep the actor as
    ``best/`` when its F1 is the best so far."""
    controller = PolicyController.from_actor(run.config, run.actor)
    episode = run_episode(run.eval_env, controller, seed=run.config.seed)
    metrics = episode.metrics()
    if run.windows is not None:
        run.windows.record_evaluation(step_f1(episode.active_keys, episode.goal_keys))
    row = {k: float(metrics[k]) for k in EVAL_KEYS}
    run.last_eval_step = run.step
    entry = {
        "kind": "eval",
        "step": run.step,
        "updates": run.updates,
        "wall_s": round(_wall_s(run), 3),
        **row,
    }
    if run.best_eval is None or row["f1"] > run.best_eval["f1"]:
        run.best_eval = entry
        ckpt.save_best(run.out, run.step, run.actor.weights, entry)
    log.write(entry)
    run.last_eval = row


def _eval_due(run: _Run) -> bool:
    """Whether the step count crossed a multiple of ``eval_interval`` since the last evaluation."""
    interval = run.config.eval_interval
    return run.step // interval > max(run.last_eval_step, 0) // interval


def _checkpoint_due(run: _Run) -> bool:
    """Whether ``checkpoint_interval`` steps have passed since the last checkpoint."""
    return run.step - run.last_checkpoint_step >= run.config.checkpoint_interval


def _log_rate(run: _Run, log: RunLog) -> float:
    """Log a "train" row: steps/s since the previous one and the latest losses; returns the
    steps/s."""
    import jax

    now = time.perf_counter()
    steps_per_s = (run.step - run.rate_step) / (now - run.rate_clock)
    row = {
        "kind": "train",
        "step": run.step,
        "updates": run.updates,
        "wall_s": round(run.wall_s + now - run.clock, 3),
        "steps_per_s": steps_per_s,
    }
    if run.metrics is not None:
        row.update({k: float(v) for k, v in jax.device_get(run.metrics).items()})
    log.write(row)
    run.rate_step, run.rate_clock = run.step, now
    return steps_per_s


def _end_episode(run: _Run, log: RunLog) -> None:
    """Log the finished training episode's return (with windows: its F1, and the window it
    played, whose error it updates) and count it."""
    row: dict[str, Any] = {
        "kind": "episode",
        "step": run.step,
        "episode": run.episode,
        "return": run.episode_return,
    }
    if run.windows is not None:
        active, due = (np.stack(x) for x in zip(*run.episode_keys, strict=True))
        f1 = step_f1(active, due)
        row["f1"] = float(f1.mean())
        if run.episode_window >= 0:
            row.update(window=run.episode_window, start_step=run.episode_start)
            run.windows.record_episode(run.episode_window, f1)
    log.write(row)
    run.episode += 1
    run.episode_return = 0.0


def _checkpoint(run: _Run, mid_episode: bool) -> None:
    """Save everything needed to resume at ``run.step`` (``mid_episode``: the environment was
    not at an episode boundary, so a resumed run starts a new episode there)."""
    import jax

    leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(run.state)]
    run.wall_s += time.perf_counter() - run.clock
    ckpt.save_checkpoint(
        run.out,
        run.step,
        leaves,
        run.actor.weights,
        run.replay.state_arrays(),
        {
            "explore_rng": run.explore_rng.bit_generator.state,
            "sample_rng": run.sample_rng.bit_generator.state,
            "counters": _counters(run),
            "last_eval": run.last_eval,
            "mid_episode": mid_episode,
            **(
                {"windows": {**run.windows.state(), "rng": run.window_rng.bit_generator.state}}
                if run.windows is not None
                else {}
            ),
        },
    )
    run.last_checkpoint_step = run.step
    run.clock = time.perf_counter()  # writing the checkpoint is not training time


def _hands_of(env: AgentEnv) -> list[str]:
    return [h.side for h in env.scene.hands]
