"""Predictive-sampling MPC: F1 and real-time factor per song, against the IK planner.

For each song (built-in debug songs, optionally cut to their first ``--seconds``) and each
controller, one seeded episode with ``pianist.eval.run_episode``:

- f1 / precision / recall: the episode's key metrics (facts page, section 5);
- rtf: simulated seconds / wall seconds of the whole episode (environment included);
  the paper ran its MPC at 0.1 (one tenth of real time);
- plan_rtf: simulated seconds / seconds spent planning (MPC only);
- ms/step: planning wall time per control step (MPC only).

Controllers: ``--mpc SPEC`` (repeatable; a ``pianist.control.mpc.make_mpc`` spec such as
``paper``, ``tenth`` or ``paper,num_samples=20,iterations=3``) on the paper's scene, and
``--planner``: the IK planner, on the scene it declares (``IKPlanner.env_options``: one more
forearm slide, tz).

Run: ``python benchmarks/bench_mpc.py --mpc paper --planner [--songs twinkle-twinkle ...]
[--seconds 4] [--json out.json]``. Machine noise matters: the rollouts share 2 cores.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pianist.control import make_controller
from pianist.control.mpc import make_mpc
from pianist.eval.session import play
from pianist.music import load_song
from pianist.music.transforms import window

DEFAULT_SONGS = ("twinkle-twinkle", "c-major-scale-right", "c-major-chords")


def run_one(song_name: str, seconds: float | None, controller_name: str, physics: str, seed: int):
    song = load_song(song_name)
    if seconds is not None:
        song = window(song, 0.0, seconds)
    # The planner declares an extra forearm height slide (tz); the MPC plays the paper's scene.
    controller = make_controller("planner") if controller_name == "planner" else None
    controller = controller or make_mpc(controller_name)
    result = play(song, controller, physics=physics, seed=seed)
    metrics = result.metrics
    wall = metrics["wall_seconds"]
    row = {
        "song": song_name,
        "seconds": metrics["seconds"],
        "controller": controller_name,
        "physics": physics,
        "f1": metrics["f1"],
        "precision": metrics["precision"],
        "recall": metrics["recall"],
        "wall_s": wall,
        "rtf": metrics["seconds"] / wall,
    }
    if "mpc_realtime_factor" in metrics:
        row["plan_rtf"] = metrics["mpc_realtime_factor"]
        row["ms_per_step"] = metrics["mpc_ms_per_step"]
        row["rollout_steps_per_s"] = metrics["mpc_rollout_steps_per_s"]
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", nargs="+", default=list(DEFAULT_SONGS))
    parser.add_argument("--seconds", type=float, default=None, help="cut songs to this length")
    parser.add_argument("--mpc", action="append", default=None, help="make_mpc spec; repeatable")
    parser.add_argument("--planner", action="store_true", help="also run the IK planner")
    parser.add_argument("--physics", default="faithful", choices=["faithful", "fast"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="write the rows to this JSON file")
    args = parser.parse_args()

    controllers = list(args.mpc or ["paper"]) + (["planner"] if args.planner else [])
    rows = []
    header = (
        f"{'song':22s} {'controller':44s} {'sec':>5s} {'F1':>6s} {'prec':>6s} {'rec':>6s} "
        f"{'rtf':>6s} {'plan_rtf':>8s} {'ms/step':>8s}"
    )
    print(header)
    for song in args.songs:
        for name in controllers:
            row = run_one(song, args.seconds, name, args.physics, args.seed)
            rows.append(row)
            nan = float("nan")
            print(
                f"{song:22s} {name[:44]:44s} {row['seconds']:5.2f} {row['f1']:6.3f} "
                f"{row['precision']:6.3f} {row['recall']:6.3f} {row['rtf']:6.3f} "
                f"{row.get('plan_rtf', nan):8.3f} {row.get('ms_per_step', nan):8.1f}"
            )
            sys.stdout.flush()
    for name in controllers:
        mine = [r for r in rows if r["controller"] == name]
        f1 = sum(r["f1"] for r in mine) / len(mine)
        sim = sum(r["seconds"] for r in mine)
        wall = sum(r["wall_s"] for r in mine)
        print(f"mean F1 {f1:.3f}  overall rtf {sim / wall:.3f}  {name}")
    if args.json:
        from pianist.files import write_json_atomic

        write_json_atomic({"rows": rows, "args": vars(args)}, Path(args.json))


if __name__ == "__main__":
    main()
