"""How much of each piece the hands can play: the reach ceiling, the plan, and the playing.

For every song (``pianist.control.planner.coverage``; one reset of the default planner per song):

- the **ceiling**: the recall and F1 of a player that presses, at every frame, every due key
  some placement of the two hands, each in its best pose of ``WHOLE_HAND_POSES``, lets a
  finger press, and nothing else: every frame on its own (no travel time), by the fingers'
  sampled reach widened by the planner's ``playable_tolerance_m``, scored per step as the
  metrics score; and beside it the same with the wrists straight (``straight F1``);
- the **plan**: the shares left out (no finger sent), in a shift (the hand's fingers lifted
  while it travels) and playable, and the plan's F1 (a player that sounds exactly the
  playable key-frames: what the plan leaves to execution);
- with ``--play``, one episode of the planner (seed 0): its recall and F1;
- with ``--practice JSON`` (``bench_practice.py``'s output), the practised recall and F1;
- with ``--what-if``, the straight-wrist ceiling for hands that could do more: the thumb on
  a black key (given its white-key reach there), the wrist turned and flexed
  (``WHAT_IF_WRIST``, rad) at the frames where that reaches more, and both.
- with ``--plan-variants``, the plan's F1 (its bound: no controller that follows it can
  pass it) for the default's whole-piece plan and for that plan with one thing changed
  (``PLAN_VARIANTS``: moves that take no time or a quicker slide, a looser reach model,
  closer forearms, cheaper moves, no cost at the edge of a finger's reach, the other
  whole-piece plans), each made at a reset with no episode played.

The ceiling bounds every controller with these hands' reach in those poses: a controller can
pass the plan's playable share (the reach model is a little conservative) but not, by more
than the tolerance, the ceiling.

Run: ``python benchmarks/bench_coverage.py [--suite open-etude-12 | --songs a,b]
[--physics fast] [--play] [--practice practice.json] [--what-if] [--plan-variants]
[--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import os
from dataclasses import replace

import numpy as np

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.planner.coverage import (
    ceiling_scores,
    plan_coverage,
    plan_f1,
    plan_key_classes,
    planner_ceiling,
)
from pianist.control.planner.hand_plan import HandPlanCosts
from pianist.control.planner.hand_split import HandReach
from pianist.eval.session import make_env, play
from pianist.music import load_song

from arguments import song_list  # isort: skip  (beside this script)

#: WRJ2 (towards the little finger) and WRJ1 (flexion), rad: the hand's span thumb to little
#: finger on white keys grows from 0.129 m to 0.160 m (an octave is 0.1645 m).
WHAT_IF_WRIST = (-0.3, 0.2)

#: The plan the default plays on every open-etude-12 piece (its rehearsal chooses it), made
#: alone: no rehearsal, so no episode is played.
_PIECE_F1 = PlannerConfig().with_fields(best_candidates=("piece-f1",))
_COSTS = HandPlanCosts()

#: Plans whose F1 ``--plan-variants`` reports: the default's, and it with one thing changed.
PLAN_VARIANTS: dict[str, PlannerConfig] = {
    "piece-f1 (the default's)": _PIECE_F1,
    "moves take no time": _PIECE_F1.with_fields(
        hand_plan=replace(_COSTS, slide_acceleration_m_s2=1e6)
    ),
    "slide 4x as quick (80 m/s^2)": _PIECE_F1.with_fields(
        hand_plan=replace(_COSTS, slide_acceleration_m_s2=80.0)
    ),
    "reach_margin 0.15 (0.3)": _PIECE_F1.with_fields(reach_margin=0.15),
    "forearm_separation_m 0.15 (0.17)": _PIECE_F1.with_fields(forearm_separation_m=0.15),
    "step_f1_move_scale 1 (4)": _PIECE_F1.with_fields(
        hand_plan=replace(_COSTS, step_f1_move_scale=1.0)
    ),
    "edge_cost 0 (0.25)": _PIECE_F1.with_fields(hand_plan=replace(_COSTS, edge_cost=0.0)),
    "split (both hands together)": _PIECE_F1.with_fields(hand_planning="split"),
    "piece (key-frames, not step F1)": _PIECE_F1.with_fields(best_candidates=("piece",)),
}


def coverage_row(name: str, physics: str, played: bool) -> dict:
    """The coverage of one song's default plan (and, with ``played``, one episode's scores)."""
    song = load_song(name, fingering="auto")
    coverage = plan_coverage(_reset(song, physics))
    row = {
        **coverage.to_dict(),
        "left_out_share": coverage.share("left_out"),
        "in_shift_share": coverage.share("in_shift"),
        "playable_share": coverage.share("playable"),
    }
    if played:
        metrics = play(song, IKPlanner(), physics=physics, seed=0).metrics
        row["played_recall"], row["played_f1"] = metrics["recall"], metrics["f1"]
    return row


def _reset(song, physics: str, config: PlannerConfig | None = None) -> IKPlanner:
    planner = IKPlanner(config)
    env = make_env(song, planner, physics=physics)
    env.reset(seed=0)
    planner.reset(env, seed=0)
    return planner


def _thumb_on_black(hand: HandReach) -> HandReach:
    full = hand.full_reach.copy()
    full[0, 1] = full[0, 0]  # the thumb reaches a black key where it reaches a white one
    return HandReach(full, full, hand.root_y, hand.slide_range)


def what_if_row(name: str, physics: str) -> dict:
    """The ceiling's recall and F1 for these hands and for hands that could do more."""
    song = load_song(name, fingering="auto")
    planners = {
        "straight": _reset(song, physics),
        "turned": _reset(song, physics, PlannerConfig().with_fields(wrist_pose=WHAT_IF_WRIST)),
    }
    keys = planners["straight"].goal.keys

    def lost(label: str, thumb: bool) -> np.ndarray:
        return planner_ceiling(planners[label], _thumb_on_black if thumb else None)

    cases = {
        "these_hands": lost("straight", False),
        "thumb_on_black": lost("straight", True),
        "wrist_turned": np.minimum(lost("straight", False), lost("turned", False)),
        "both": np.minimum(lost("straight", True), lost("turned", True)),
    }
    row = {}
    for case, frames in cases.items():
        row[f"{case}_recall"], row[f"{case}_f1"] = ceiling_scores(keys, frames)
    return row


def plan_variant_row(name: str, physics: str) -> dict:
    """Each of :data:`PLAN_VARIANTS`' plan F1 and the shares of the due key-frames it leaves
    out and lifts for shifts, for one song."""
    song = load_song(name, fingering="auto")
    row = {}
    for label, config in PLAN_VARIANTS.items():
        planner = _reset(song, physics, config)
        # The key classes alone: the ceiling (plan_coverage's) does not change with the plan.
        left_out, in_shift = plan_key_classes(planner)
        due = max(int(planner.goal.keys.sum()), 1)
        row[label] = {
            "plan_f1": plan_f1(planner),
            "left_out_share": float(left_out.sum()) / due,
            "in_shift_share": float(in_shift.sum()) / due,
        }
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="open-etude-12")
    parser.add_argument("--songs", default=None, help="comma-separated songs (instead of --suite)")
    parser.add_argument("--physics", default="fast", choices=("fast", "faithful"))
    parser.add_argument("--play", action="store_true", help="also play each piece once")
    parser.add_argument("--practice", default=None, help="bench_practice.py JSON to show beside")
    parser.add_argument(
        "--what-if", action="store_true", help="also the ceiling for more able hands"
    )
    parser.add_argument(
        "--plan-variants", action="store_true", help="also the plan F1 of other plans"
    )
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()

    names = song_list(parser, args.songs, args.suite)
    practised = {}
    if args.practice and not os.path.isfile(args.practice):
        parser.error(f"--practice {args.practice}: no such file")
    if args.practice:
        with open(args.practice) as f:
            practised = json.load(f)["songs"]
    header = (
        f"{'song':40s} {'due':>5s} {'ceiling R':>9s} {'ceiling F1':>10s} {'straight F1':>11s} "
        f"{'left out':>8s} "
        f"{'in shift':>8s} {'playable':>8s} {'plan F1':>7s}"
    )
    if args.play:
        header += f" {'played R':>8s} {'played F1':>9s}"
    if practised:
        header += f" {'practised R':>11s} {'practised F1':>12s}"
    print(header)
    rows: dict[str, dict] = {}
    for name in names:
        row = coverage_row(name, args.physics, args.play)
        if name in practised:
            best = practised[name]
            row["practised_recall"], row["practised_f1"] = best["best_recall"], best["best_f1"]
        rows[name] = row
        line = (
            f"{name[:40]:40s} {row['due']:5d} {row['ceiling_recall']:9.3f} "
            f"{row['ceiling_f1']:10.3f} {row['straight_ceiling_f1']:11.3f} "
            f"{row['left_out_share']:8.3f} "
            f"{row['in_shift_share']:8.3f} {row['playable_share']:8.3f} {row['plan_f1']:7.3f}"
        )
        if args.play:
            line += f" {row['played_recall']:8.3f} {row['played_f1']:9.3f}"
        if "practised_recall" in row:
            line += f" {row['practised_recall']:11.3f} {row['practised_f1']:12.3f}"
        print(line, flush=True)
    if args.what_if:
        cases = ("these_hands", "thumb_on_black", "wrist_turned", "both")
        print("\nceiling F1 (recall) for more able hands")
        print(f"{'song':40s} " + " ".join(f"{c:>16s}" for c in cases))
        for name in names:
            extra = what_if_row(name, args.physics)
            rows[name]["what_if"] = extra
            cells = " ".join(f"{extra[c + '_f1']:7.3f} ({extra[c + '_recall']:.3f})" for c in cases)
            print(f"{name[:40]:40s} {cells}", flush=True)
        for c in cases:
            for m in ("recall", "f1"):
                key = f"{c}_{m}"
                rows_mean = float(np.mean([r["what_if"][key] for r in rows.values()]))
                print(f"mean {key}: {rows_mean:.3f}")
    if args.plan_variants:
        labels = list(PLAN_VARIANTS)
        print("\nplan F1 (left out, in shift) of each plan")
        for name in names:
            variants = plan_variant_row(name, args.physics)
            rows[name]["plan_variants"] = variants
            cells = " ".join(f"{variants[label]['plan_f1']:.3f}" for label in labels)
            print(f"{name[:40]:40s} {cells}", flush=True)
        print(f"{'plan':40s} {'plan F1':>7s} {'left out':>8s} {'in shift':>8s}")
        for label in labels:
            means = [
                float(np.mean([r["plan_variants"][label][k] for r in rows.values()]))
                for k in ("plan_f1", "left_out_share", "in_shift_share")
            ]
            print(f"{label:40s} {means[0]:7.3f} {means[1]:8.3f} {means[2]:8.3f}")
    keys = [k for k, v in next(iter(rows.values())).items() if isinstance(v, float)]
    mean = {k: float(np.mean([r[k] for r in rows.values() if k in r])) for k in keys}
    totals = {
        k: int(sum(r[k] for r in rows.values()))
        for k in ("due", "left_out", "in_shift", "out_of_reach", "playable", "ceiling_lost")
    }
    print("mean: " + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))
    print("totals: " + ", ".join(f"{k} {v}" for k, v in totals.items()))
    if args.json:
        settings = {"suite": None if args.songs else args.suite, "physics": args.physics}
        with open(args.json, "w") as f:
            json.dump(
                {"settings": settings, "mean": mean, "totals": totals, "songs": rows}, f, indent=1
            )


if __name__ == "__main__":
    main()
