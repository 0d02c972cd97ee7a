"""The whole hand against the straight wrist: the planner with and without reach poses.

For every song (default: the ``octaves`` suite, pieces at an octave's stretch) and physics
preset, one episode (seed 0, automatic fingering as ``pianist play``) of the default planner,
whose whole-piece plan may turn a hand's wrist (``PoseConfig.reach_poses``), and one of
the same planner with the wrist held straight (``reach_poses=()``):

- F1 of each, and their difference;
- ``turned``: the share of the due key-frames the default's plan plays with a wrist turned;
- the reach ceiling of the whole hand (``reach_ceiling_f1``: every pose of
  ``WHOLE_HAND_POSES``) and of the straight wrist (``reach_ceiling_straight_f1``), each the
  most any controller scores with that model of the hands (the same for both planners).

Run: ``python benchmarks/bench_reach.py [--suite octaves | --songs a,b]
[--presets faithful,fast] [--json out.json]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.eval.session import play

from arguments import preset_list, song_list, song_table  # isort: skip  (beside this script)

VARIANTS = {"whole hand": PlannerConfig(), "straight": PlannerConfig().with_fields(reach_poses=())}


def row(name: str, physics: str) -> dict[str, float]:
    """Both planners' F1 on one song and preset, the turned share and the two ceilings."""
    out: dict[str, float] = {}
    for label, config in VARIANTS.items():
        planner = IKPlanner(config)
        result = play(name, planner, physics=physics, seed=0)
        out[f"{label} f1"] = float(result.metrics["f1"])
        if label == "whole hand":
            due = planner.goal.keys
            turned = np.zeros(due.shape, dtype=bool)
            for hand, arrays in zip(planner.hands, planner.plan.hands, strict=True):
                local = planner.fingers - hand.finger_offset
                mine = due & (local >= 0) & (local < 5)
                turned |= mine & (arrays.pose_plan > 0)[:, None]
            out["turned share"] = float(turned.sum() / max(due.sum(), 1))
            out["ceiling f1"] = float(result.metrics["reach_ceiling_f1"])
            out["straight ceiling f1"] = float(result.metrics["reach_ceiling_straight_f1"])
    out["gain"] = out["whole hand f1"] - out["straight f1"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="octaves")
    parser.add_argument("--songs", default=None, help="comma-separated songs (instead of --suite)")
    parser.add_argument("--presets", default="faithful,fast")
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    names = song_list(parser, args.songs, args.suite)
    presets = preset_list(parser, args.presets)
    columns: tuple[str, ...] = ("whole hand f1", "straight f1", "gain", "turned share")
    columns += ("ceiling f1", "straight ceiling f1")
    settings = {"suite": None if args.songs else args.suite, "presets": presets}
    song_table(names, presets, row, columns, args.json, settings, width=19)


if __name__ == "__main__":
    main()
