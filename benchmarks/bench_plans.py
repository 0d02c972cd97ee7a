"""The planner's candidate plans, each played, and the plan each way of choosing picks.

For every song and physics preset: each plan of :data:`pianist.control.planner.config.
PLAN_CANDIDATES` played once on its own (seed 0; the planner with ``hand_planning`` set to
it), with what its plan promises beside what it plays: the share of the due key-frames it
leaves playable and its plan F1 (:func:`pianist.control.planner.coverage.plan_f1`: a player sounding
exactly those key-frames). Then the choosers (:data:`CHOOSERS`): the default planner
(``choose_plan="rehearsal"``: the best rehearsed of ``best_candidates``), the same
rehearsing the three candidates it used to (``rehearsal-3``), and the chooser before
rehearsal (``choose_plan="playable"`` over frame, piece-song and piece: the first plan
within ``piece_plan_margin`` of the most playable key-frames), each timed from a cold start
(plans made and rehearsed anew): their F1, the plan each chose, and their real-time factors.

Run: ``python benchmarks/bench_plans.py [--suite open-etude-12 | --songs a,b]
[--presets fast,faithful] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from pianist.control.planner import IKPlanner, PlannerConfig, forget_plans
from pianist.control.planner.config import PLAN_CANDIDATES, PlanKind
from pianist.control.planner.coverage import plan_coverage
from pianist.eval import run_episode
from pianist.eval.session import make_env
from pianist.music import list_songs

#: The plan choosers compared, by label: the default; the default rehearsing the whole-piece
#: plan that counts key-frames too; the chooser before rehearsal, by playable key-frames.
CHOOSERS = {
    "rehearsal": PlannerConfig(),
    "rehearsal-3": PlannerConfig().with_fields(best_candidates=("frame", "piece", "piece-f1")),
    "playable": PlannerConfig().with_fields(
        choose_plan="playable", best_candidates=("frame", "piece-song", "piece")
    ),
}


def candidate_config(name: str) -> PlannerConfig:
    """The planner that plays only the candidate plan ``name`` (one candidate: no
    rehearsal)."""
    return PlannerConfig().with_fields(best_candidates=(name,))


def _played(song: str, physics: str, config: PlannerConfig) -> tuple[dict, IKPlanner]:
    """One cold-start episode: F1, wall seconds and real-time factor, and the planner."""
    forget_plans()
    planner = IKPlanner(config)
    env = make_env(song, planner, physics=physics)
    start = time.perf_counter()
    metrics = run_episode(env, planner, seed=0).metrics()
    wall = time.perf_counter() - start
    return {"f1": metrics["f1"], "realtime_factor": metrics["seconds"] / wall}, planner


def bench_song(song: str, physics: str) -> dict:
    row: dict = {"candidates": {}}
    for name in PLAN_CANDIDATES:
        played, planner = _played(song, physics, candidate_config(name))
        coverage = plan_coverage(planner)
        row["candidates"][name] = {
            "f1": played["f1"],
            "playable_share": coverage.share("playable"),
            "plan_f1": coverage.plan_f1,
        }
    for label, config in CHOOSERS.items():
        played, planner = _played(song, physics, config)
        row[label] = {**played, "chosen": _name(planner.plan_kind)}
    return row


def _name(kind: PlanKind) -> str:
    return next(name for name, known in PLAN_CANDIDATES.items() if known == kind)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="open-etude-12")
    parser.add_argument("--songs", default=None, help="comma-separated songs (instead of --suite)")
    parser.add_argument("--presets", default="fast,faithful")
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    songs = args.songs.split(",") if args.songs else list_songs(args.suite)
    names = list(PLAN_CANDIDATES)
    results: dict = {"settings": {"suite": None if args.songs else args.suite}, "songs": {}}
    print(
        f"{'song':34s} {'preset':8s} "
        + " ".join(f"{n:>10s}" for n in names)
        + "".join(f" {label:>16s}" for label in CHOOSERS)
        + f" {'rtf':>15s}"
    )
    for song in songs:
        results["songs"][song] = {}
        for physics in args.presets.split(","):
            row = bench_song(song, physics)
            results["songs"][song][physics] = row
            cells = " ".join(f"{row['candidates'][n]['f1']:10.3f}" for n in names)
            chosen = "".join(
                f" {row[label]['f1']:6.3f} {row[label]['chosen']:>9s}" for label in CHOOSERS
            )
            rtf = "/".join(f"{row[label]['realtime_factor']:4.1f}" for label in CHOOSERS)
            print(f"{song[:34]:34s} {physics:8s} {cells}{chosen} {rtf}", flush=True)
    for physics in args.presets.split(","):
        rows = [by[physics] for by in results["songs"].values()]
        mean = {
            **{f"{c}_f1": float(np.mean([r[c]["f1"] for r in rows])) for c in CHOOSERS},
            **{
                f"{c}_rtf_median": float(np.median([r[c]["realtime_factor"] for r in rows]))
                for c in CHOOSERS
            },
            **{
                f"{n}_{k}": float(np.mean([r["candidates"][n][k] for r in rows]))
                for n in names
                for k in ("f1", "plan_f1", "playable_share")
            },
        }
        results.setdefault("mean", {})[physics] = mean
        print(f"mean {physics}: " + ", ".join(f"{k} {v:.4f}" for k, v in mean.items()))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
