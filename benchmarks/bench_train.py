"""Training speed and learning against wall-clock time, per preset.

Three modes:

- ``speed``: median ms per update (one update per jitted call, and blocks of
  ``steps_per_iteration * updates_per_step`` updates in one ``lax.scan`` call) and environment
  steps/s of each preset's task (observation features included, random actions), with the
  presets' real observation and action sizes.
- ``learn``: train one preset on a song for a wall-clock budget (``--minutes``), evaluating
  every ``--eval-interval`` steps; the run directory keeps the log. Run several in the
  background and compare them with ``report``.
- ``report``: F1 against wall-clock time from run directories (the last evaluation by each
  mark, and the best one kept by then in ``run/best``; a practice run's passes, from
  ``pianist train SONG``, beside them), steps/s and updates/s; then the
  planner (residual runs), the final policy and the best kept policy evaluated again: one
  deterministic episode each, and the mean F1 over ``--episodes`` episodes with Gaussian
  action noise of std ``--noise`` (a single episode's F1 is chaotic: see ``NoisyController``).

Residual runs: ``learn`` copies the planner's source into the run (``planner_snapshot.py``)
and trains on that copy, and writes the planner's F1 on the run's task (``planner.json``);
``report`` evaluates the run on that copy (the baseline in the same code state) and again on
the planner as it is now, with the run's residual on top.

JAX is limited to one thread per computation (XLA_FLAGS below): on this shared 2-core machine
the pipelined presets use one core for the physics and one for the updates.

Examples::

    python benchmarks/bench_train.py speed --presets droq-paper fast --json speed.json
    nohup python benchmarks/bench_train.py learn --preset fast --minutes 30 --out runs/fast &
    nohup taskset -c 1 python benchmarks/bench_train.py learn --preset residual-anchored \
        --song c-major-chords --minutes 30 --out runs/anchored-chords &
    python benchmarks/bench_train.py report runs/fast runs/droq-paper --json learn.json \
        --plot curves.png

Practising the hard parts (windows) against whole-piece episodes, one core each::

    nohup taskset -c 0 python benchmarks/bench_train.py learn --preset residual-anchored \
        --song mozart-sonata-k545-allegro --minutes 10 --out runs/k545-anchored &
    nohup taskset -c 1 python benchmarks/bench_train.py learn --preset residual-windows \
        --song mozart-sonata-k545-allegro --minutes 10 --out runs/k545-windows &
    python benchmarks/bench_train.py report runs/k545-anchored runs/k545-windows --marks 5 10

Twinkle from scratch in 10 minutes on both cores, trained on the fast physics and scored on
the faithful one as well (``--eval-physics``)::

    python benchmarks/bench_train.py learn --preset fast-small --song twinkle-twinkle \
        --minutes 10 --eval-interval 2000 --out runs/twinkle-s0
    python benchmarks/bench_train.py report runs/twinkle-s0 --marks 5 10 --episodes 5 \
        --eval-physics faithful --json twinkle.json
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
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from pianist.agents import PRESETS, get_preset  # noqa: E402
from pianist.control import NoisyController  # noqa: E402


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


PLANNER_SNAPSHOT = "planner_snapshot"  # a copy of the planner package (older runs: a .py)


def use_planner(run: str | Path | None) -> None:
    """Make ``pianist.control.planner`` the copy kept in ``run`` (None: the package's own).

    The planner changes while runs go on; a residual run keeps the planner source it trained
    on, so its baseline and its policy are evaluated on that planner, in this process.
    """
    import importlib
    import importlib.util
    import sys

    import pianist.control

    name = "pianist.control.planner"
    for loaded in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
        sys.modules.pop(loaded)
    if run is None:
        module = importlib.import_module(name)
    else:
        folder = Path(run) / PLANNER_SNAPSHOT
        if folder.is_dir():  # the package: its modules load from the copy too
            spec = importlib.util.spec_from_file_location(
                name, folder / "__init__.py", submodule_search_locations=[str(folder)]
            )
        else:  # a run snapshotted when the planner was one module
            spec = importlib.util.spec_from_file_location(name, folder.with_suffix(".py"))
        if spec is None or spec.loader is None:
            raise SystemExit(f"no planner snapshot in {run}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    pianist.control.planner = module


def snapshot_planner(run: str | Path) -> None:
    """Copy the planner's current source into ``run`` and use that copy from now on."""
    import importlib.util
    import shutil

    found = importlib.util.find_spec("pianist.control.planner")
    assert found is not None and found.origin is not None  # the package is installed
    package = Path(found.origin).parent
    Path(run).mkdir(parents=True, exist_ok=True)
    target = Path(run) / PLANNER_SNAPSHOT
    shutil.rmtree(target, ignore_errors=True)
    shutil.copytree(package, target, ignore=shutil.ignore_patterns("__pycache__"))
    use_planner(run)


def learn(
    preset: str,
    song: str,
    minutes: float,
    out: str,
    eval_interval: int | None,
    seed: int,
    residual_scale: float | None = None,
    eval_physics: str | None = None,
) -> None:
    from pianist.agents.training import train

    cfg = get_preset(preset, seed=seed)
    if eval_physics:
        cfg = dataclasses.replace(cfg, eval_physics=eval_physics)  # type: ignore[arg-type]
    if eval_interval:
        cfg = dataclasses.replace(cfg, eval_interval=eval_interval)
    if residual_scale is not None:
        task = dataclasses.replace(cfg.task, residual_scale=residual_scale)
        cfg = dataclasses.replace(cfg, task=task, preset=f"{preset}-scale{residual_scale:g}")
    resume = (Path(out) / "checkpoints" / "latest.json").exists()
    if cfg.task.residual:
        if resume:
            use_planner(out)
        else:
            snapshot_planner(out)
    if cfg.task.residual and not resume:
        # The planner's own F1 on the same task, in the code this process runs (the planner
        # may change while runs go on): the baseline the residual must beat.
        Path(out).mkdir(parents=True, exist_ok=True)
        baseline = {"song": song, "planner_f1": planner_f1({"song": song, "config": cfg.to_dict()})}
        (Path(out) / "planner.json").write_text(json.dumps(baseline) + "\n")
        print(f"planner alone: F1 {baseline['planner_f1']:.3f}", flush=True)
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


def report(
    run_dirs: list[str],
    marks_min: list[float],
    noise: float,
    episodes: int,
    eval_physics: str | None = None,
) -> list[dict]:
    rows = []
    for run in run_dirs:
        config = json.loads((Path(run) / "config.json").read_text())
        lines = [json.loads(x) for x in (Path(run) / "log.jsonl").read_text().splitlines() if x]
        if config.get("kind") == "practice":
            rows.append(practice_row(run, config, lines, marks_min, noise, episodes))
            continue
        evals = [r for r in lines if r["kind"] == "eval"]
        train_rows = [r for r in lines if r["kind"] == "train"]
        last = train_rows[-1] if train_rows else {"step": 0, "updates": 0, "wall_s": 0}
        row = {
            "run": run,
            "preset": config["config"]["preset"],
            "song": config["song"],
            "seed": config["config"].get("seed"),
            # The physics of the log's evaluations (the curve and the best kept).
            "curve_physics": config["config"].get("eval_physics")
            or config["config"]["task"]["physics"],
            "steps": last["step"],
            "updates": last["updates"],
            "wall_s": last["wall_s"],
            "steps_per_s": last["step"] / last["wall_s"] if last["wall_s"] else 0.0,
            "updates_per_s": last["updates"] / last["wall_s"] if last["wall_s"] else 0.0,
            "best_f1": max((r["f1"] for r in evals), default=float("nan")),
            "final_f1": evals[-1]["f1"] if evals else float("nan"),
            "curve": [(r["wall_s"], r["step"], r["f1"]) for r in evals],
        }
        for m in marks_min:
            # Marks the run did not reach (within 5 %) have no value.
            reached = bool(evals) and evals[-1]["wall_s"] >= 0.95 * m * 60
            before = [r["f1"] for r in evals if r["wall_s"] <= m * 60] if reached else []
            # The policy of the last evaluation by then, and the best one kept by then.
            row[f"f1_at_{m:g}min"] = before[-1] if before else float("nan")
            row[f"best_f1_by_{m:g}min"] = max(before, default=float("nan"))
        if config["config"]["task"]["residual"]:
            baseline = Path(run) / "planner.json"
            if baseline.exists():
                row["planner_f1_at_start"] = json.loads(baseline.read_text())["planner_f1"]
            kept = Path(run) / PLANNER_SNAPSHOT
            snapshot = kept.exists() or kept.with_suffix(".py").exists()
            use_planner(run if snapshot else None)
            row["planner_snapshot"] = snapshot
            row["planner_f1"] = planner_f1(config)  # the run's planner, measured again
            row.update(evaluate_policies(run, config, noise, episodes, ""))
            if snapshot:  # and the planner as it is now, with the run's residual on top
                use_planner(None)
                row["planner_f1_now"] = planner_f1(config)
                row.update(evaluate_policies(run, config, noise, episodes, "now_"))
        elif episodes > 0:
            row.update(evaluate_policies(run, config, noise, episodes, ""))
        if eval_physics:
            # The same policies in another physics preset (trained on fast, scored on
            # faithful): the rest of the task unchanged.
            prefix = f"{eval_physics}_"
            row.update(evaluate_policies(run, config, noise, episodes, prefix, eval_physics))
        rows.append(row)
    head = f"{'song':20s} {'preset':18s} {'steps':>6s} {'upd':>6s} {'wall s':>6s} {'steps/s':>7s}"
    head += f" {'upd/s':>5s}" + "".join(f" {'F1@' + format(m, 'g') + 'm':>7s}" for m in marks_min)
    head += f" {'final':>6s} {'best':>6s}"
    print(head)
    for row in rows:
        line = (
            f"{row['song']:20s} {row['preset']:18s} {row['steps']:6d} {row['updates']:6d} "
            f"{row['wall_s']:6.0f} {row['steps_per_s']:7.1f} {row['updates_per_s']:5.1f}"
        )
        line += "".join(f" {row[f'f1_at_{m:g}min']:7.3f}" for m in marks_min)
        line += f" {row['final_f1']:6.3f} {row['best_f1']:6.3f}"
        print(line)
        marks = ", ".join(f"{m:g} min {row[f'best_f1_by_{m:g}min']:.3f}" for m in marks_min)
        print(f"   best kept by: {marks} (evaluated on {row['curve_physics']} physics)")
        if "planner_f1" in row:
            start = row.get("planner_f1_at_start", float("nan"))
            print(f"   planner alone: {start:.3f} at the start, {row['planner_f1']:.3f} again")
        own = "the run's planner" if "planner_f1" in row else "the run's physics"
        labels = [("", own), ("now_", "today's planner")]
        if eval_physics:
            labels.append((f"{eval_physics}_", f"the {eval_physics} physics"))
        for prefix, label in labels:
            if f"{prefix}det_final_f1" not in row:
                continue
            names = [n for n in ("planner", "final", "best") if f"{prefix}det_{n}_f1" in row]
            det = ", ".join(f"{n} {row[f'{prefix}det_{n}_f1']:.3f}" for n in names)
            print(f"   on {label}: F1 {det}")
            if f"{prefix}noisy_final_f1" in row:
                noisy = ", ".join(f"{n} {row[f'{prefix}noisy_{n}_f1']:.3f}" for n in names)
                print(f"      under action noise {noise:g}, mean of {episodes} episodes: {noisy}")
        print(
            "   curve (wall s, step, F1): "
            + ", ".join(f"({w:.0f}, {s}, {f:.2f})" for w, s, f in row["curve"])
        )
    return rows


def practice_row(
    run: str, config: dict, passes: list[dict], marks_min: list[float], noise: float, episodes: int
) -> dict:
    """A practice run's row (``pianist train SONG``, no network) in the shape of the others:
    its passes as the curve (wall seconds, environment steps simulated so far on both
    workers, look-aheads included, and the pass's F1, which is its table's: the physics is
    deterministic), the best table kept by each mark, and the planner and the best table
    evaluated again in the physics it was practised in (a table plays no other). "updates"
    counts the passes."""
    from pianist.agents.practice import CorrectedPlanner
    from pianist.control.planner import IKPlanner
    from pianist.eval import run_episode
    from pianist.eval.session import make_env

    steps_so_far = np.cumsum([int(r.get("env_steps", 0)) for r in passes])
    curve = [(r["seconds"], int(n), r["f1"]) for r, n in zip(passes, steps_so_far, strict=True)]
    best_by = np.maximum.accumulate([f for _, _, f in curve])
    wall, steps = curve[-1][0], curve[-1][1]
    row: dict = {
        "run": run,
        "preset": "practice",
        "song": config["song"],
        "seed": config.get("seed"),
        "steps": steps,
        "updates": len(passes) - 1,
        "wall_s": wall,
        "steps_per_s": steps / wall if wall else 0.0,
        "updates_per_s": (len(passes) - 1) / wall if wall else 0.0,
        "best_f1": float(best_by[-1]),
        "final_f1": float(best_by[-1]),  # what the run keeps and plays: its best table
        "curve": curve,
        "trained_physics": config["physics"],
        "curve_physics": config["physics"],
    }
    for m in marks_min:
        reached = wall >= 0.95 * m * 60
        before = [b for (w, _, _), b in zip(curve, best_by, strict=True) if w <= m * 60]
        value = float(before[-1]) if reached and before else float("nan")
        row[f"f1_at_{m:g}min"] = row[f"best_f1_by_{m:g}min"] = value
    practised = CorrectedPlanner.load(run)
    env = make_env(config["song"], practised)
    for name, controller in (("planner", IKPlanner()), ("best", practised)):
        row[f"det_{name}_f1"] = run_episode(env, controller, seed=0).metrics()["f1"]
        if episodes > 0:
            noisy = NoisyController(controller, noise)
            f1 = [run_episode(env, noisy, seed=i).metrics()["f1"] for i in range(episodes)]
            row[f"noisy_{name}_f1"] = float(np.mean(f1))
            row[f"noisy_{name}_f1_all"] = [float(x) for x in f1]
    row["det_final_f1"] = row["det_best_f1"]
    row["planner_f1_at_start"] = curve[0][2]  # pass 0: the planner alone, its plan chosen
    row["planner_f1"] = row["det_planner_f1"]
    if episodes > 0:
        row["noisy_final_f1"] = row["noisy_best_f1"]
    return row


def planner_f1(config: dict) -> float:
    from pianist.agents.config import TrainConfig
    from pianist.agents.envs import make_agent_env
    from pianist.control.planner import IKPlanner
    from pianist.eval import run_episode

    cfg = TrainConfig.from_dict(config["config"])
    env = make_agent_env(config["song"], cfg.task)
    return float(run_episode(env, IKPlanner(), seed=cfg.seed).metrics()["f1"])


def evaluate_policies(
    run: str,
    config: dict,
    sigma: float,
    episodes: int,
    prefix: str,
    physics: str | None = None,
) -> dict[str, float]:
    """F1 of one deterministic episode and mean F1 over ``episodes`` noisy ones (skipped if
    0) of the planner (residual runs), the run's final policy and its best kept policy
    (``run/best``), in the run's environment (or in another ``physics`` preset), with
    whichever planner module is in use."""
    from pianist.agents import PolicyController
    from pianist.control.planner import IKPlanner
    from pianist.eval import run_episode

    # The run's own physics unless told: a fast preset's run evaluates on the faithful one
    # during training, and its controllers would default to that.
    physics = physics or config["config"]["task"]["physics"]
    final = PolicyController(run, physics=physics)
    env = final.make_env(config["song"])
    controllers: dict[str, Any] = {"final": final}
    if (Path(run) / "best").is_dir():
        controllers["best"] = PolicyController(Path(run) / "best", physics=physics)
    if config["config"]["task"]["residual"]:
        controllers["planner"] = IKPlanner()
    out: dict = {}
    for name, controller in controllers.items():
        seed = final.config.seed
        out[f"{prefix}det_{name}_f1"] = run_episode(env, controller, seed=seed).metrics()["f1"]
        if episodes > 0:
            noisy = NoisyController(controller, sigma)
            f1 = [run_episode(env, noisy, seed=i).metrics()["f1"] for i in range(episodes)]
            out[f"{prefix}noisy_{name}_f1"] = float(np.mean(f1))
            out[f"{prefix}noisy_{name}_f1_all"] = [float(x) for x in f1]
    return out


def plot_curves(rows: list[dict], path: str) -> None:
    """F1 against wall-clock minutes, one line per run (preset and song), the planner's F1 as a
    dashed line of the same colour for residual and practice runs; written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for i, row in enumerate(rows):
        colour = f"C{i % 10}"
        minutes = [w / 60 for w, _, _ in row["curve"]]
        f1 = [f for _, _, f in row["curve"]]
        ax.plot(
            minutes,
            f1,
            marker="o",
            ms=3,
            color=colour,
            label=f"{row['preset']} ({row['song']}, seed {row['seed']})",
        )
        if "planner_f1" in row:
            ax.axhline(row["planner_f1"], color=colour, ls="--", lw=1, alpha=0.7)
    ax.set_xlabel("wall-clock time (min)")
    ax.set_ylabel("F1 (one deterministic evaluation episode)")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Learning curves (dashed: the planner alone, under residual and practice runs)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


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
    p.add_argument(
        "--eval-physics",
        choices=("faithful", "fast"),
        help="the physics of the run's evaluations, which choose its best policy "
        "(default: the preset's)",
    )
    p = sub.add_parser("report")
    p.add_argument("runs", nargs="+")
    p.add_argument("--marks", type=float, nargs="+", default=[5, 10, 20, 30])
    p.add_argument("--noise", type=float, default=0.005, help="action noise of the robust F1")
    p.add_argument("--episodes", type=int, default=10, help="noisy episodes (0: skip)")
    p.add_argument("--json")
    p.add_argument("--plot", help="also plot F1 against wall-clock time to this PNG")
    p.add_argument(
        "--eval-physics",
        choices=("faithful", "fast"),
        help="also evaluate the final and best policies in this physics preset",
    )
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
            args.eval_physics,
        )
        return
    else:
        rows = report(args.runs, args.marks, args.noise, args.episodes, args.eval_physics)
        if args.plot:
            plot_curves(rows, args.plot)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
