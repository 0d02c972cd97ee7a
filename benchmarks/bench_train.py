"""Training speed and learning against wall-clock time, per preset.

Three modes:

- ``speed``: median ms per update (one update per jitted call, and blocks of
  ``steps_per_iteration * updates_per_step`` updates in one ``lax.scan`` call) and environment
  steps/s of each preset's task (observation features included, random actions), with the
  presets' real observation and action sizes.
- ``learn``: train one preset on a song for a wall-clock budget (``--minutes``), evaluating
  every ``--eval-interval`` steps; the run directory keeps the log. Run several in the
  background and compare them with ``report``.
- ``report``: F1 against wall-clock time from run directories (and, for residual runs, the
  planner's own F1 on the same task), steps/s and updates/s.

JAX is limited to one thread per computation (XLA_FLAGS below): on this shared 2-core machine
the pipelined presets use one core for the physics and one for the updates.

Examples::

    python benchmarks/bench_train.py speed --presets droq-paper fast --json speed.json
    nohup python benchmarks/bench_train.py learn --preset fast --minutes 30 --out runs/fast &
    python benchmarks/bench_train.py report runs/fast runs/droq-paper --json learn.json
"""

from __future__ import annotations

import os

os.environ.setdefault(
    "XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from pianist.agents import PRESETS, get_preset  # noqa: E402


def speed(presets: list[str], song: str, repeats: int) -> list[dict]:
    import jax

    from pianist.agents.envs import Featurizer, make_agent_env
    from pianist.agents.replay import Batch
    from pianist.agents.sac import SAC

    rows = []
    for name in presets:
        cfg = get_preset(name)
        env = make_agent_env(song, cfg.task)
        features = Featurizer(env, cfg.task)
        D, A, B = features.obs_dim, features.action_dim, cfg.agent.batch_size
        rng = np.random.default_rng(0)
        # Environment steps/s with features (and the planner for residual tasks).
        rates = []
        for r in range(repeats):
            obs, _ = env.reset(seed=r)
            features.reset(env, r)
            features(obs)
            start, n, done = time.perf_counter(), 0, False
            while not done:
                a = rng.uniform(-1, 1, A).astype(np.float32)
                obs, _, term, trunc, _ = env.step(features.env_action(a))
                features(obs)
                n += 1
                done = term or trunc
            rates.append(n / (time.perf_counter() - start))
        agent = SAC(D, A, cfg.agent)
        row = {"preset": name, "obs_dim": D, "action_dim": A, "env_steps_per_s": np.median(rates)}
        block = cfg.steps_per_iteration * cfg.updates_per_step
        for label, K in (("ms_per_update_single", 1), ("ms_per_update_block", block)):
            state = agent.init(0)
            batch = Batch(
                rng.standard_normal((K, B, D), dtype=np.float32),
                rng.uniform(-1, 1, (K, B, A)).astype(np.float32),
                rng.standard_normal((K, B), dtype=np.float32),
                np.ones((K, B), np.float32),
                rng.standard_normal((K, B, D), dtype=np.float32),
            )
            state, _ = agent.update_many(state, batch)
            jax.block_until_ready(state)
            times = []
            for _ in range(max(3, repeats * 3)):
                start = time.perf_counter()
                state, _ = agent.update_many(state, batch)
                jax.block_until_ready(state)
                times.append((time.perf_counter() - start) / K * 1e3)
            row[label] = float(np.median(times))
        row["block"] = block
        rows.append(row)
        print(
            f"{name:22s} obs {D:5d} act {A:3d}  env {row['env_steps_per_s']:7.0f} steps/s  "
            f"update {row['ms_per_update_single']:6.1f} ms (1/call)  "
            f"{row['ms_per_update_block']:6.1f} ms ({block}/call)",
            flush=True,
        )
    return rows


def learn(
    preset: str,
    song: str,
    minutes: float,
    out: str,
    eval_interval: int | None,
    seed: int,
    residual_scale: float | None = None,
) -> None:
    from pianist.agents.training import train

    cfg = get_preset(preset, seed=seed)
    if eval_interval:
        cfg = dataclasses.replace(cfg, eval_interval=eval_interval)
    if residual_scale is not None:
        task = dataclasses.replace(cfg.task, residual_scale=residual_scale)
        cfg = dataclasses.replace(cfg, task=task, preset=f"{preset}-scale{residual_scale:g}")
    resume = (Path(out) / "checkpoints" / "latest.json").exists()
    result = train(
        None if resume else song,
        None if resume else cfg,
        10**9,
        out,
        resume=resume,
        progress=False,
        message=print,
        stop_after_s=minutes * 60,
    )
    print(f"{preset}: {result.step} steps, last eval {result.last_eval}, {result.wall_s:.0f} s")


def report(run_dirs: list[str], marks_min: list[float]) -> list[dict]:
    rows = []
    for run in run_dirs:
        config = json.loads((Path(run) / "config.json").read_text())
        lines = [json.loads(x) for x in (Path(run) / "log.jsonl").read_text().splitlines() if x]
        evals = [r for r in lines if r["kind"] == "eval"]
        train_rows = [r for r in lines if r["kind"] == "train"]
        last = train_rows[-1] if train_rows else {"step": 0, "updates": 0, "wall_s": 0}
        row = {
            "run": run,
            "preset": config["config"]["preset"],
            "song": config["song"],
            "steps": last["step"],
            "updates": last["updates"],
            "wall_s": last["wall_s"],
            "steps_per_s": last["step"] / last["wall_s"] if last["wall_s"] else 0.0,
            "updates_per_s": last["updates"] / last["wall_s"] if last["wall_s"] else 0.0,
            "best_f1": max((r["f1"] for r in evals), default=float("nan")),
            "curve": [(r["wall_s"], r["step"], r["f1"]) for r in evals],
        }
        for m in marks_min:
            before = [r["f1"] for r in evals if r["wall_s"] <= m * 60]
            row[f"best_f1_by_{m:g}min"] = max(before, default=float("nan"))
        if config["config"]["task"]["residual"]:
            row["planner_f1"] = planner_f1(config)
        rows.append(row)
    head = f"{'preset':22s} {'steps':>8s} {'upd':>8s} {'wall s':>7s} {'steps/s':>7s} {'upd/s':>6s}"
    head += "".join(f" {'F1@' + format(m, 'g') + 'm':>8s}" for m in marks_min) + "  best F1"
    print(head)
    for row in rows:
        line = (
            f"{row['preset']:22s} {row['steps']:8d} {row['updates']:8d} {row['wall_s']:7.0f} "
            f"{row['steps_per_s']:7.1f} {row['updates_per_s']:6.1f}"
        )
        line += "".join(f" {row[f'best_f1_by_{m:g}min']:8.3f}" for m in marks_min)
        line += f"  {row['best_f1']:.3f}"
        if "planner_f1" in row:
            line += f"  (planner alone {row['planner_f1']:.3f})"
        print(line)
        print(
            "   curve (wall s, step, F1): "
            + ", ".join(f"({w:.0f}, {s}, {f:.2f})" for w, s, f in row["curve"])
        )
    return rows


def planner_f1(config: dict) -> float:
    from pianist.agents.config import TrainConfig
    from pianist.agents.envs import make_agent_env
    from pianist.control.planner import IKPlanner
    from pianist.eval import run_episode

    cfg = TrainConfig.from_dict(config["config"])
    env = make_agent_env(config["song"], cfg.task)
    return float(run_episode(env, IKPlanner(), seed=cfg.seed).metrics()["f1"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    p = sub.add_parser("speed")
    p.add_argument("--presets", nargs="+", default=list(PRESETS))
    p.add_argument("--song", default="twinkle-twinkle")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--json")
    p = sub.add_parser("learn")
    p.add_argument("--preset", required=True, choices=list(PRESETS))
    p.add_argument("--song", default="twinkle-twinkle")
    p.add_argument("--minutes", type=float, default=30.0)
    p.add_argument("--out", required=True)
    p.add_argument("--eval-interval", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--residual-scale", type=float, default=None)
    p = sub.add_parser("report")
    p.add_argument("runs", nargs="+")
    p.add_argument("--marks", type=float, nargs="+", default=[5, 10, 20, 30])
    p.add_argument("--json")
    args = parser.parse_args()
    if args.mode == "speed":
        rows = speed(args.presets, args.song, args.repeats)
    elif args.mode == "learn":
        learn(
            args.preset,
            args.song,
            args.minutes,
            args.out,
            args.eval_interval,
            args.seed,
            args.residual_scale,
        )
        return
    else:
        rows = report(args.runs, args.marks)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
