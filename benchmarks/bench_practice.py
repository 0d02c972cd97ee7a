"""Practice (``pianist train SONG --preset practice``): F1 against wall-clock time per piece.

For every song: :func:`pianist.agents.practice.practise` with a wall-clock budget, on the
physics asked for (faithful by default, the one the issue scores on), with ``--workers``
processes. Per song it records the planner's F1 (pass 0), the best F1 after 1, 5 and 10
minutes and at the end, every pass (F1 against seconds), and how robust the learned table is:
the mean F1 over ``--noise-episodes`` episodes with Gaussian action noise (std
``--noise-std``) of the planner alone and of the planner with the table. Beside them: the
recall of the best pass against the share of due key-frames the planner's plan leaves
playable by its own reach model (practice changes how the plan is played, not the plan; a
recall above the share is keys sounded beyond what the model grants the fingers), and the
environment steps the passes simulated per wall-clock second (the piece's and the
look-aheads', all workers). The practised table
replays its best pass exactly (deterministic physics), so its F1 needs no separate
evaluation; the noisy episodes show how much of the gain survives a perturbed trajectory.

Run: ``python benchmarks/bench_practice.py --songs a,b [--minutes 10] [--physics faithful]
[--workers 2] [--json out.json] [--plot out.png]``. The songs run one after the other (each
uses all the workers).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from pianist.agents.practice import CorrectedPlanner, PracticeConfig, practise
from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner.coverage import playable_mask
from pianist.eval.session import make_env, play
from pianist.music import load_song


class _Noisy:
    """A controller with Gaussian noise added to its actions (clipped to [-1, 1])."""

    def __init__(self, inner, std: float, seed: int) -> None:
        self.inner, self.std = inner, std
        self.rng = np.random.default_rng(seed)

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def act(self, observation):
        action = self.inner.act(observation)
        noise = self.rng.normal(0.0, self.std, action.shape)
        return np.clip(action + noise, -1.0, 1.0).astype(np.float32)


def _plan_ceiling(song, physics: str, hand_planning: str) -> float:
    """The share of the piece's due key-frames that the practised plan leaves playable (a
    finger given, within its modelled reach from the planned hand position, not during a
    shift). Practice corrects how the plan is played, not the plan."""
    planner = IKPlanner(PlannerConfig().with_fields(hand_planning=hand_planning))
    env = make_env(song, planner, physics=physics)
    env.reset(seed=0)
    planner.reset(env, seed=0)
    playable = int(playable_mask(planner).sum())
    return playable / max(int(planner.goal.keys.sum()), 1)


def _env_steps_per_s(history: list[dict]) -> float:
    """Environment steps simulated per wall-clock second over the passes after the first
    (the planner's own pass simulates only the piece)."""
    passes = [row for row in history if row["pass"] > 0]
    if not passes:
        return 0.0
    seconds = passes[-1]["seconds"] - history[0]["seconds"]
    return sum(row.get("env_steps", 0) for row in passes) / max(seconds, 1e-9)


def _best_by(history: list[dict], seconds: float) -> float:
    return max(row["f1"] for row in history if row["seconds"] <= seconds or row["pass"] == 0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", required=True, help="comma-separated song names or files")
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--physics", default="faithful")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--noise-std", type=float, default=0.005)
    parser.add_argument("--noise-episodes", type=int, default=3)
    parser.add_argument("--json", default=None)
    parser.add_argument("--plot", default=None)
    args = parser.parse_args()

    config = PracticeConfig(passes=10_000, physics=args.physics, workers=args.workers)
    results: dict[str, dict] = {}
    print(
        f"{'song':40s} {'planner':>8s} {'1 min':>7s} {'5 min':>7s} {'10 min':>7s} "
        f"{'end':>7s} {'passes':>6s} {'noisy planner':>13s} {'noisy practised':>15s} "
        f"{'recall':>6s} {'playable':>8s} {'steps/s':>7s}"
    )
    for name in args.songs.split(","):
        song = load_song(name, fingering="auto")
        start = time.perf_counter()
        result = practise(song, config, stop_after_s=60.0 * args.minutes)
        wall = time.perf_counter() - start
        history = result.history
        noisy: dict[str, list[float]] = {"planner": [], "practised": []}
        for seed in range(args.noise_episodes):
            for label, table in (("planner", None), ("practised", result.table)):
                controller = (
                    IKPlanner()
                    if table is None
                    else CorrectedPlanner(table, hand_planning=result.hand_planning)
                )
                played = play(song, _Noisy(controller, args.noise_std, seed), physics=args.physics)
                noisy[label].append(played.metrics["f1"])
        row = {
            "planner_f1": history[0]["f1"],
            "best_f1_by_s": {str(s): _best_by(history, s) for s in (60, 300, 600)},
            "best_f1": result.f1,
            "best_pass": result.pass_index,
            "passes": history[-1]["pass"],
            "wall_s": wall,
            "noisy_planner_f1": float(np.mean(noisy["planner"])),
            "noisy_practised_f1": float(np.mean(noisy["practised"])),
            "best_recall": next(r for r in history if r["pass"] == result.pass_index)["recall"],
            "plan_playable_share": _plan_ceiling(song, args.physics, result.hand_planning),
            "hand_planning": result.hand_planning,
            "env_steps_per_s": _env_steps_per_s(history),
            "history": history,
        }
        results[name] = row
        by = row["best_f1_by_s"]
        print(
            f"{name:40s} {row['planner_f1']:8.3f} {by['60']:7.3f} {by['300']:7.3f} "
            f"{by['600']:7.3f} {result.f1:7.3f} {row['passes']:6d} "
            f"{row['noisy_planner_f1']:13.3f} {row['noisy_practised_f1']:15.3f} "
            f"{row['best_recall']:6.3f} {row['plan_playable_share']:8.3f} "
            f"{row['env_steps_per_s']:7.0f}",
            flush=True,
        )
    mean = {
        key: float(np.mean([r[key] for r in results.values()]))
        for key in (
            "planner_f1",
            "best_f1",
            "noisy_planner_f1",
            "noisy_practised_f1",
            "plan_playable_share",
            "env_steps_per_s",
        )
    }
    print("mean: " + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))
    settings = {
        "minutes": args.minutes,
        "physics": args.physics,
        "workers": args.workers,
        "noise_std": args.noise_std,
        "noise_episodes": args.noise_episodes,
        "config": config.to_dict(),
    }
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"settings": settings, "mean": mean, "songs": results}, f, indent=1)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        # Twenty colours, then the line style changes: every curve tells from the others.
        colours = plt.get_cmap("tab20").colors  # type: ignore[attr-defined]
        for i, (name, row) in enumerate(results.items()):
            h = row["history"]
            seconds = [r["seconds"] / 60 for r in h]
            best = np.maximum.accumulate([r["f1"] for r in h])
            style = ("-", "--", ":")[(i // len(colours)) % 3]
            colour = colours[i % len(colours)]
            ax.step(seconds, best, where="post", label=name, color=colour, linestyle=style)
        ax.set_xlabel("wall-clock minutes")
        ax.set_ylabel("best F1 so far")
        ax.set_title(f"practice, {args.physics} physics, {args.workers} workers")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)


if __name__ == "__main__":
    main()
