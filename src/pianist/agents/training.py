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
"""

from __future__ import annotations

import json
import math
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pianist.agents import checkpoint as ckpt
from pianist.agents.config import TrainConfig, get_preset
from pianist.agents.envs import Featurizer, make_agent_env
from pianist.agents.policy import NumpyActor, PolicyController, read_run_config
from pianist.agents.replay import ReplayBuffer
from pianist.eval import run_episode
from pianist.files import write_json_atomic, write_text_atomic

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


def _episode_seed(seed: int, episode: int) -> int:
    return int(np.random.SeedSequence([seed, 7, episode]).generate_state(1)[0])


def train(
    song: str | None,
    preset: str | TrainConfig | None,
    steps: int,
    out_dir: str | Path,
    resume: bool = False,
    progress: bool = True,
    message: Callable[[str], None] | None = None,
    stop_after_s: float | None = None,
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
        stop_after_s: stop (after a checkpoint) once this much wall time has passed in this
            call; for time-budgeted benchmarks.
    """
    import jax

    out = Path(out_dir)
    say = message or (lambda _text: None)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, not {steps}")
    if resume:
        run = read_run_config(out)
        song = run["song"]
        config = TrainConfig.from_dict(run["config"])
        if preset is not None and isinstance(preset, str) and preset != config.preset:
            raise ValueError(f"{out} was trained with preset {config.preset!r}, not {preset!r}")
    else:
        if song is None or preset is None:
            raise ValueError("a new run needs a song and a preset")
        config = get_preset(preset) if isinstance(preset, str) else preset
        if (out / ckpt.CHECKPOINTS / ckpt.LATEST).exists():
            raise ValueError(f"{out} already holds a run: resume it or choose another directory")
        out.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(out / ckpt.BEST, ignore_errors=True)  # left by a run that never checkpointed
    env = make_agent_env(song, config.task)
    eval_env = make_agent_env(song, config.task)
    features = Featurizer(env, config.task)
    write_json_atomic(
        {
            "song": song,
            "steps": steps,
            "config": config.to_dict(),
            "env_options": config.task.env_options(tuple(_hands_of(env))),
            "obs_dim": features.obs_dim,
            "action_dim": features.action_dim,
        },
        out / "config.json",
    )

    from pianist.agents.sac import actor_weights, make_agent

    A, D, c = features.action_dim, features.obs_dim, config.agent
    agent = make_agent(D, A, c)
    state = agent.init(config.seed)
    replay = ReplayBuffer(D, A, config.replay_capacity)
    explore_rng = np.random.default_rng([config.seed, 1])
    sample_rng = np.random.default_rng([config.seed, 2])
    counters = {
        "step": 0,
        "episode": 0,
        "updates": 0,
        "wall_s": 0.0,
        "last_eval": -1,
        "last_checkpoint": 0,
    }
    last_eval: dict[str, float] = {}
    best_eval = ckpt.best_evaluation(out) if resume else None
    resumed_from = None
    log_path = out / "log.jsonl"
    if resume:
        checkpoint = ckpt.latest_checkpoint(out)
        saved = ckpt.load_state(checkpoint)
        leaves, treedef = jax.tree_util.tree_flatten(state)
        leaves = ckpt.load_agent_leaves(checkpoint, [np.asarray(x) for x in leaves])
        state = jax.tree_util.tree_unflatten(treedef, [jax.numpy.asarray(x) for x in leaves])
        replay.load_arrays(ckpt.load_replay_arrays(checkpoint))
        explore_rng.bit_generator.state = saved["explore_rng"]
        sample_rng.bit_generator.state = saved["sample_rng"]
        counters.update(saved["counters"])
        last_eval = saved.get("last_eval", {})
        resumed_from = counters["step"]
        _truncate_log(log_path, resumed_from)
        say(f"resumed {out} from step {resumed_from} (checkpoint {checkpoint.name})")
    elif log_path.exists():
        log_path.unlink()

    actor = NumpyActor(actor_weights(state.actor), c.activation, c.log_std_min, c.log_std_max)
    log = log_path.open("a")
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, initial=counters["step"], unit="step", dynamic_ncols=True)

    def write(row: dict[str, Any]) -> None:
        log.write(json.dumps(row) + "\n")
        log.flush()

    def evaluate() -> dict[str, float]:
        controller = PolicyController.from_actor(config, actor)
        metrics = run_episode(eval_env, controller, seed=config.seed).metrics()
        row = {k: float(metrics[k]) for k in EVAL_KEYS}
        counters["last_eval"] = counters["step"]
        entry = {
            "kind": "eval",
            "step": counters["step"],
            "updates": counters["updates"],
            "wall_s": round(counters["wall_s"] + time.perf_counter() - t0, 3),
            **row,
        }
        nonlocal best_eval
        if best_eval is None or row["f1"] > best_eval["f1"]:
            best_eval = entry
            ckpt.save_best(out, counters["step"], actor.weights, entry)
        write(entry)
        return row

    def save(mid_episode: bool) -> None:
        leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(state)]
        counters["wall_s"] += time.perf_counter() - t0
        ckpt.save_checkpoint(
            out,
            counters["step"],
            leaves,
            actor.weights,
            replay.state_arrays(),
            {
                "explore_rng": explore_rng.bit_generator.state,
                "sample_rng": sample_rng.bit_generator.state,
                "counters": counters,
                "last_eval": last_eval,
                "mid_episode": mid_episode,
            },
        )
        counters["last_checkpoint"] = counters["step"]

    t0 = time.perf_counter()
    call_start = t0
    x = _start_episode(env, features, replay, config.seed, counters["episode"])
    episode_return, metrics = 0.0, None
    rate_mark = (counters["step"], t0)
    done = False
    try:
        while counters["step"] < steps:
            step = counters["step"]
            n = min(config.steps_per_iteration, env.num_steps - env.step_index, steps - step)
            train_now = step >= config.seed_steps and replay.transitions > 0
            k = n * config.updates_per_step
            if train_now and config.pipeline:
                batches = replay.sample(sample_rng, c.batch_size, k)
                state, metrics = agent.update_many(state, batches)  # runs while we step
            for _ in range(n):
                if counters["step"] < config.seed_steps and config.seed_policy == "uniform":
                    a = explore_rng.uniform(-1.0, 1.0, A).astype(np.float32)
                else:
                    a = actor.sample(x, explore_rng).astype(np.float32)
                obs, reward, terminated, truncated, _ = env.step(features.env_action(a))
                x = features(obs)
                replay.add(a, reward, 0.0 if terminated else 1.0, x)
                episode_return += reward
                counters["step"] += 1
                done = terminated or truncated
                if done:
                    break
            if train_now and not config.pipeline:
                batches = replay.sample(sample_rng, c.batch_size, k)
                state, metrics = agent.update_many(state, batches)
            if train_now:
                counters["updates"] += k
                actor = NumpyActor(
                    actor_weights(state.actor), c.activation, c.log_std_min, c.log_std_max
                )
            step = counters["step"]
            if bar is not None:
                bar.update(step - bar.n)
            if step // config.eval_interval > max(counters["last_eval"], 0) // config.eval_interval:
                last_eval = evaluate()
                if bar is not None:
                    bar.set_postfix(f1=f"{last_eval['f1']:.3f}", refresh=False)
            if step - rate_mark[0] >= 1000:
                now = time.perf_counter()
                row = {
                    "kind": "train",
                    "step": step,
                    "updates": counters["updates"],
                    "wall_s": round(counters["wall_s"] + now - t0, 3),
                    "steps_per_s": (step - rate_mark[0]) / (now - rate_mark[1]),
                }
                if metrics is not None:
                    row.update({k: float(v) for k, v in jax.device_get(metrics).items()})
                write(row)
                if bar is not None:
                    bar.set_postfix(
                        sps=f"{row['steps_per_s']:.0f}", f1=last_eval.get("f1", math.nan)
                    )
                rate_mark = (step, now)
            if done:
                write(
                    {
                        "kind": "episode",
                        "step": step,
                        "episode": counters["episode"],
                        "return": episode_return,
                    }
                )
                counters["episode"] += 1
                episode_return, done = 0.0, False
                out_of_time = (
                    stop_after_s is not None and time.perf_counter() - call_start >= stop_after_s
                )
                if out_of_time or step - counters["last_checkpoint"] >= config.checkpoint_interval:
                    save(mid_episode=False)
                    t0 = time.perf_counter()
                    if out_of_time:
                        break
                if step < steps:
                    x = _start_episode(env, features, replay, config.seed, counters["episode"])
        if counters["last_eval"] != counters["step"]:
            last_eval = evaluate()
        if counters["last_checkpoint"] != counters["step"] or counters["step"] == 0:
            save(mid_episode=env.step_index not in (0, env.num_steps))
    finally:
        if bar is not None:
            bar.close()
        log.close()
    return TrainResult(
        counters["step"], last_eval, resumed_from, counters["wall_s"], out, best_eval
    )


def _start_episode(env, features: Featurizer, replay: ReplayBuffer, seed: int, episode: int):
    s = _episode_seed(seed, episode)
    obs, _ = env.reset(seed=s)
    features.reset(env, s)
    x = features(obs)
    replay.start_episode(x)
    return x


def _hands_of(env) -> list[str]:
    return [h.side for h in env.scene.hands]


def _truncate_log(path: Path, step: int) -> None:
    """Drop log rows written after the checkpoint a run resumes from."""
    if not path.exists():
        return
    kept = []
    for line in path.read_text().splitlines():
        try:
            if json.loads(line)["step"] <= step:
                kept.append(line)
        except (json.JSONDecodeError, KeyError, TypeError):
            continue  # a line cut by the crash
    write_text_atomic("\n".join(kept) + "\n" if kept else "", path)
