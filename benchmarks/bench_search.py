"""Controllers side by side on a suite: F1, recall and real-time factor per song and preset.

Made for the segment search (:mod:`pianist.control.search`): what choosing the planner's
execution settings per second of music adds, over the planner and over the refiner, against
the wall-clock it costs. Any ``--controller`` spec of ``pianist play`` works (``planner``,
``search``, ``refine``, ``search:refine``, ...). One deterministic episode per song,
controller and preset (seed 0), in the environment the CLI builds for the controller; the
episodes run in ``--workers`` processes (one per core: the real-time factors are then those
of one core each, with the other core busy).

Run: ``python benchmarks/bench_search.py --controllers planner search [--suite open-etude-12
| --songs a,b] [--presets fast,faithful] [--workers 2] [--json out.json]`` (specs are
space-separated: a spec may hold commas, e.g. ``search:segment_steps=10,overlap_steps=5``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import time

import numpy as np

from pianist.music import list_songs


def _episode(job: tuple[str, str, str]) -> tuple[str, str, str, dict]:
    song, spec, preset = job
    from pianist.control import make_controller
    from pianist.eval.session import play

    start = time.perf_counter()
    result = play(song, make_controller(spec), physics=preset, seed=0)
    m = result.metrics
    out = {k: m[k] for k in ("precision", "recall", "f1", "realtime_factor")}
    out["wall_s"] = time.perf_counter() - start
    out.update({k: v for k, v in m.items() if k.startswith("search_share_")})
    return song, spec, preset, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--controllers", nargs="+", default=["planner", "search"], help="specs, space-separated"
    )
    parser.add_argument("--songs", default=None)
    parser.add_argument("--suite", default="open-etude-12")
    parser.add_argument("--presets", default="fast")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    songs = args.songs.split(",") if args.songs else list_songs(args.suite)
    specs = args.controllers
    presets = args.presets.split(",")
    jobs = [(song, spec, preset) for preset in presets for song in songs for spec in specs]
    results: dict = {"controllers": specs, "presets": presets, "songs": {}, "mean": {}}
    started = time.perf_counter()
    # Spawned workers: each imports MuJoCo afresh (no state forked from this process).
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        for song, spec, preset, out in pool.imap_unordered(_episode, jobs):
            results["songs"].setdefault(song, {}).setdefault(preset, {})[spec] = out
            print(
                f"{song:36s} {preset:8s} {spec:16s} F1 {out['f1']:.3f} R {out['recall']:.3f} "
                f"rtf {out['realtime_factor']:6.2f}",
                flush=True,
            )
    results["wall_s"] = time.perf_counter() - started
    print(f"\n{'mean over ' + str(len(songs)) + ' songs':36s} {'preset':8s}", end="")
    print("".join(f" {spec:>16s}" for spec in specs), " (F1 / median rtf)")
    for preset in presets:
        row = {}
        for spec in specs:
            runs = [results["songs"][s][preset][spec] for s in songs]
            row[spec] = {
                "f1": float(np.mean([r["f1"] for r in runs])),
                "recall": float(np.mean([r["recall"] for r in runs])),
                "min_f1": float(np.min([r["f1"] for r in runs])),
                "median_rtf": float(np.median([r["realtime_factor"] for r in runs])),
            }
        results["mean"][preset] = row
        cells = "".join(
            f" {row[s]['f1']:9.3f} / {row[s]['median_rtf']:4.2f}".rjust(17) for s in specs
        )
        print(f"{'':36s} {preset:8s}{cells}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
