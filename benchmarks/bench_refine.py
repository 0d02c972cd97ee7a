"""Refinement by looking ahead: the F1 it adds to the planner, against the wall-clock it costs.

For every song asked for and every physics preset, one episode of the IK planner alone and one
of :class:`pianist.control.refine.Refiner` around it (same seed), both in the environment the
CLI uses for them. Per song: the two F1s (and precision, recall), the gain, each one's real-time
factor (simulated seconds per wall-clock second) and the share of steps where the refiner
played a perturbed action; in the JSON also the F1 each kind of error costs
(``f1_lost_*``, :func:`pianist.eval.f1_lost_by_kind`), and its means, printed at the end.
Both controllers are deterministic given the seed.

Run: ``python benchmarks/bench_refine.py [--songs a,b | --suite open-etude-12]
[--presets fast,faithful] [--refine candidates=8,horizon_steps=4] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from typing import Any

import numpy as np

from pianist.control.planner import IKPlanner
from pianist.control.refine import Refiner
from pianist.control.registry import parse_controller
from pianist.control.specs import RefineSpec
from pianist.eval.session import play

from arguments import preset_list, song_list  # isort: skip  (beside this script)


def _episode(song: str, controller, physics: str) -> dict:
    start = time.perf_counter()
    result = play(song, controller, physics=physics, seed=0)
    wall = time.perf_counter() - start
    m = result.metrics
    out = {k: m[k] for k in ("precision", "recall", "f1")}
    out.update({k: v for k, v in m.items() if k.startswith("f1_lost_")})  # pianist.eval.f1_lost
    out["rtf"] = m["realtime_factor"]
    out["wall_s"] = wall
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", default=None)
    parser.add_argument("--suite", default="open-etude-12")
    parser.add_argument("--presets", default="fast")
    parser.add_argument("--refine", default="", help="Refiner options, e.g. candidates=16")
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    songs = song_list(parser, args.songs, args.suite)
    preset_list(parser, args.presets)
    try:
        options = parse_controller(f"refine:{args.refine}" if args.refine else "refine")
    except ValueError as exc:
        parser.error(" ".join(str(exc).split()))
    assert isinstance(options, RefineSpec)
    results: dict = {"options": dataclasses.asdict(options), "songs": {}}
    print(
        f"{'song':36s} {'preset':8s} {'F1':>6s} {'+ref':>6s} {'gain':>6s} {'R':>6s} "
        f"{'+ref':>6s} {'rtf':>6s} {'+ref':>6s} {'refined':>7s}"
    )
    for preset in args.presets.split(","):
        gains = []
        for song in songs:
            base = _episode(song, IKPlanner(), preset)
            refiner = Refiner(options=options)
            refined = _episode(song, refiner, preset)
            refined["refined_share"] = refiner.stats()["refined_share"]
            gain = refined["f1"] - base["f1"]
            gains.append((base["f1"], refined["f1"]))
            results["songs"].setdefault(song, {})[preset] = {"planner": base, "refine": refined}
            print(
                f"{song:36s} {preset:8s} {base['f1']:6.3f} {refined['f1']:6.3f} {gain:+6.3f} "
                f"{base['recall']:6.3f} {refined['recall']:6.3f} {base['rtf']:6.2f} "
                f"{refined['rtf']:6.3f} {refined['refined_share']:7.2f}",
                flush=True,
            )
        f1 = np.array(gains)
        summary: dict[str, Any] = {
            "planner_f1": float(f1[:, 0].mean()),
            "refine_f1": float(f1[:, 1].mean()),
        }
        for who in ("planner", "refine"):
            runs = [results["songs"][song][preset][who] for song in songs]
            summary[f"{who}_f1_lost"] = {
                k: float(np.mean([r[k] for r in runs])) for k in runs[0] if k.startswith("f1_lost_")
            }
        results.setdefault("mean", {})[preset] = summary
        print(f"{'mean':36s} {preset:8s} {summary['planner_f1']:6.3f} {summary['refine_f1']:6.3f}")
        for who in ("planner", "refine"):
            lost = ", ".join(f"{k[8:]} {v:.3f}" for k, v in summary[f"{who}_f1_lost"].items())
            print(f"  F1 lost by the {who} (each kind alone put right): {lost}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
