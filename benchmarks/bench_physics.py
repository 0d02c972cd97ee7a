"""Effect of each fast-preset option on raw physics speed, cumulatively from the faithful preset.

Two-hand scene, random controls held for 10 substeps (one control step), bare ``mj_step``.
Every configuration is measured in each round (interleaved) and the median over rounds is
reported with its ratio to the faithful preset measured in the same rounds.

Run: ``python benchmarks/bench_physics.py [--rounds 5] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from typing import Any

import mujoco
import numpy as np

from pianist.sim.scene import FAITHFUL, SceneOptions, build_scene

STEPS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("faithful", {}),
    ("+ sleeping islands", {"sleep": True}),
    ("+ no hand frictionloss", {"hand_frictionloss": False}),
    ("+ fingertip contacts only", {"fingertip_contacts_only": True}),
    ("+ 20 iterations (= fast)", {"iterations": 20, "ls_iterations": 10}),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--control-steps", type=int, default=150)
    parser.add_argument("--json")
    args = parser.parse_args()

    models, preset = [], FAITHFUL
    for label, change in STEPS:
        preset = dataclasses.replace(preset, name=label, **change)
        models.append((label, build_scene(SceneOptions(physics=preset)).model))
    rng = np.random.default_rng(0)
    low, high = models[0][1].actuator_ctrlrange.T
    controls = rng.uniform(low, high, (args.control_steps, len(low)))
    rates: dict[str, list[float]] = {label: [] for label, _ in models}
    for _ in range(args.rounds):
        for label, model in models:
            data = mujoco.MjData(model)
            start = time.perf_counter()
            for c in controls:
                data.ctrl[:] = c
                mujoco.mj_step(model, data, nstep=10)
            rates[label].append(10 * len(controls) / (time.perf_counter() - start))
    base = np.median(rates["faithful"])
    print(f"{'configuration':28s} {'physics steps/s':>16s} {'vs faithful':>12s}")
    results = {}
    for label, _ in models:
        rate = float(np.median(rates[label]))
        results[label] = rate
        print(f"{label:28s} {rate:16.0f} {rate / base:11.2f}x")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
