"""Environment speed: control steps/s of PianoEnv against raw physics, and of the batched path.

For a two-hand built-in song driven by random actions, per physics preset:

- env: median control steps/s of ``PianoEnv.step`` over full episodes;
- physics: median control steps/s of bare ``mj_step(nstep=substeps)`` on the same model with
  the same controls (no observation, reward or events);
- overhead: env step time / physics time (1.0 would be no cost outside MuJoCo);
- batched: total control steps/s of ``PianoVectorEnv`` with N environments on all cores.

Speed-ups are against the original RoboPianist's ~210 control steps/s on this kind of machine
(facts page, section 7). Run: ``python benchmarks/bench_env.py [--repeats 5] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import mujoco
import numpy as np

from pianist.env import PianoEnv
from pianist.env.vector import PianoVectorEnv

ORIGINAL_STEPS_PER_S = 210.0


def bench_single(song: str, physics: str, repeats: int) -> dict[str, float]:
    env = PianoEnv(song, physics=physics)
    rng = np.random.default_rng(0)
    shape = env.action_space.shape
    assert shape is not None  # a Box
    actions = rng.uniform(-1, 1, (env.num_steps, shape[0]))
    ctrl = env._ctrl_low + (actions[:, :-1] + 1) * env._ctrl_half
    raw = mujoco.MjData(env.model)
    env_rates, physics_rates = [], []
    for _ in range(repeats):
        # Interleave the two measurements so that machine noise hits both alike.
        env.reset(seed=0)
        start = time.perf_counter()
        for action in actions:
            env.step(action)
        env_rates.append(len(actions) / (time.perf_counter() - start))

        mujoco.mj_resetData(env.model, raw)
        start = time.perf_counter()
        for c in ctrl:
            raw.ctrl[:] = c
            mujoco.mj_step(env.model, raw, nstep=env.config.substeps)
        physics_rates.append(len(ctrl) / (time.perf_counter() - start))
    env_rate, physics_rate = float(np.median(env_rates)), float(np.median(physics_rates))
    return {
        "env_steps_per_s": env_rate,
        "physics_control_steps_per_s": physics_rate,
        "physics_steps_per_s": physics_rate * env.config.substeps,
        "overhead_ratio": physics_rate / env_rate,
        "speedup_vs_original": env_rate / ORIGINAL_STEPS_PER_S,
    }


def bench_vector(song: str, physics: str, num_envs: int, repeats: int, steps: int) -> float:
    venv = PianoVectorEnv(song, num_envs, physics=physics)
    rng = np.random.default_rng(0)
    venv.reset(seed=0)
    rates = []
    for _ in range(repeats):
        shape = venv.action_space.shape
        assert shape is not None  # a Box
        actions = rng.uniform(-1, 1, (steps, *shape))
        start = time.perf_counter()
        for action in actions:
            venv.step(action)
        rates.append(steps * num_envs / (time.perf_counter() - start))
    venv.close()
    return float(np.median(rates))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--song", default="c-major-scale-both")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--num-envs", type=int, nargs="+", default=[2, 4, 8])
    parser.add_argument("--vector-steps", type=int, default=100)
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args()

    results: dict[str, Any] = {"song": args.song, "original_steps_per_s": ORIGINAL_STEPS_PER_S}
    print(f"song {args.song}, random actions, median of {args.repeats} runs")
    header = (
        f"{'preset':9s} {'env st/s':>9s} {'physics st/s':>13s} {'overhead':>9s} {'vs orig':>8s}"
    )
    print(header)
    for physics in ("faithful", "fast"):
        r = bench_single(args.song, physics, args.repeats)
        results[physics] = r
        print(
            f"{physics:9s} {r['env_steps_per_s']:9.0f} {r['physics_control_steps_per_s']:13.0f}"
            f" {r['overhead_ratio']:9.2f} {r['speedup_vs_original']:7.1f}x"
        )
    print(f"\n{'preset':9s} {'N':>3s} {'batched st/s':>13s} {'vs orig':>8s}")
    for physics in ("faithful", "fast"):
        results[physics]["batched"] = {}
        for n in args.num_envs:
            rate = bench_vector(args.song, physics, n, args.repeats, args.vector_steps)
            results[physics]["batched"][n] = rate
            print(f"{physics:9s} {n:3d} {rate:13.0f} {rate / ORIGINAL_STEPS_PER_S:7.1f}x")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()
