"""Calibrate the planner's pushed strikes: the velocity a push asks for against the one its
key sounds, and how late it sounds.

A note softer than ``StrikeConfig.push_below_velocity`` is pushed
(:mod:`pianist.control.planner.strikes`): its key is brought down along a planned descent at
the speed its velocity maps to, each step's push predicted with the simulator. This
script plays calibration songs whose notes alternate between a target velocity and 100 (a
song of one velocity is never pushed), for each target and physics preset, and reports for
the target's notes, white and black keys apart:

- ``velocity``: the median MIDI velocity they sounded (10th-90th percentiles in the JSON);
- ``late ms``: the median delay of a performed note's onset after the score's;
- ``f1``: the episode F1 over the songs (mean), and ``f1 plain``: the same songs played
  without pushes.

Run: ``python benchmarks/calibrate_strikes.py [--presets fast,faithful]
[--targets 30,45,60,75] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import tempfile
from typing import Any

import numpy as np

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.eval.session import play
from pianist.media.results import played_dynamics
from pianist.music import Song, load_song
from pianist.sim import constants as C

from arguments import preset_list  # isort: skip  (beside this script)

SONGS = ("c-major-scale-both", "d-major-scale-both", "c-major-chords")
LOUD = 100
PUSHED = PlannerConfig()  # the default pushes notes below velocity 80
PLAIN = PlannerConfig().with_fields(push_below_velocity=0)


def calibration_song(name: str, target: int) -> Song:
    """The debug song ``name``, its notes' velocities alternating ``target`` and 100."""
    song = load_song(name)
    notes = tuple(
        dataclasses.replace(note, velocity=target if i % 2 else LOUD)
        for i, note in enumerate(song.notes)
    )
    return dataclasses.replace(song, notes=notes)


def measure(target: int, physics: str) -> dict[str, Any]:
    """Every calibration song played with and without pushes: the target notes' velocities
    and delays by key colour, and both F1s."""
    velocity: dict[str, list[float]] = {"white": [], "black": []}
    late: dict[str, list[float]] = {"white": [], "black": []}
    f1s, plain = [], []
    for name in SONGS:
        song = calibration_song(name, target)
        result = play(song, IKPlanner(PUSHED), physics=physics, seed=0)
        f1s.append(float(result.metrics["f1"]))
        plain.append(float(play(song, IKPlanner(PLAIN), physics=physics, seed=0).metrics["f1"]))
        for performed, score in played_dynamics(result)[2]:
            if score.velocity != target:
                continue
            black = C.BLACK_KEY_MASK[performed.pitch - C.LOWEST_MIDI_PITCH]
            colour = "black" if black else "white"
            velocity[colour].append(performed.velocity)
            late[colour].append(1000.0 * (performed.onset_s - score.onset_s))
    out: dict[str, Any] = {
        "target": target,
        "f1": float(np.mean(f1s)),
        "f1_plain": float(np.mean(plain)),
    }
    for colour in ("white", "black"):
        v, d = np.array(velocity[colour]), np.array(late[colour])
        out[colour] = {
            "notes": int(v.size),
            "velocity": float(np.median(v)) if v.size else float("nan"),
            "velocity_p10_p90": [float(x) for x in np.percentile(v, [10, 90])] if v.size else [],
            "late_ms": float(np.median(d)) if d.size else float("nan"),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="fast,faithful")
    parser.add_argument("--targets", default="30,45,60,75")
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    presets = preset_list(parser, args.presets)
    try:
        targets = [int(x) for x in args.targets.split(",")]
    except ValueError:
        parser.error(f"--targets takes comma-separated MIDI velocities, not {args.targets!r}")
    if not all(1 <= t < PUSHED.strikes.push_below_velocity for t in targets):
        parser.error(f"--targets must be from 1 to {PUSHED.strikes.push_below_velocity - 1}")
    header = f"{'preset':9}{'target':>7}{'f1':>7}{'f1 plain':>9}"
    header += "".join(f"{c + ' vel':>11}{c + ' late ms':>15}" for c in ("white", "black"))
    print(header)
    rows = []
    for preset in presets:
        for target in targets:
            row = {"preset": preset, **measure(target, preset)}
            rows.append(row)
            line = f"{preset:9}{target:7d}{row['f1']:7.3f}{row['f1_plain']:9.3f}"
            for c in ("white", "black"):
                line += f"{row[c]['velocity']:11.1f}{row[c]['late_ms']:15.1f}"
            print(line, flush=True)
    if args.json:
        folder = os.path.dirname(os.path.abspath(args.json))
        with tempfile.NamedTemporaryFile("w", dir=folder, delete=False, suffix=".tmp") as f:
            below = PUSHED.strikes.push_below_velocity
            settings = {"songs": SONGS, "config": f"push_below_velocity={below}"}
            json.dump({**settings, "rows": rows}, f, indent=1)
        os.replace(f.name, args.json)


if __name__ == "__main__":
    main()
