"""The inverse-kinematics planner: F1, precision, recall and speed per song and physics preset.

For every song asked for (default: every built-in song), on the faithful and the fast preset,
one episode of :class:`pianist.control.planner.IKPlanner` in the environment the CLI uses for
it (the benchmark's defaults plus the forearm height slide it declares, ``IKPlanner.env_options``):

- precision, recall, F1 and sustain F1 (the planner is deterministic: one episode suffices);
- rtf: simulated seconds per wall-clock second, planner included (its reset too: the plans
  made and rehearsed anew for every repeat, as for a first play), median over ``--repeats``;
- plan: the planner's share of the wall-clock time (its ``act`` calls against the whole loop);
- plan s/min: the seconds the whole-piece plans take to make, per minute of music (every
  candidate plan made and chosen by its playable key-frames, no episode rehearsed; the
  model's posture samples, made once per model, excluded), median over ``--repeats``;
- with ``--compare-tape``: the same cold start with the rehearsal's steps simulated again in
  the performance (``replay_tape=False``), timed in turns with the default, its median
  real-time factor and the speed-up the tape gives (the F1 must be the same: checked);
- dF1: F1 on fast minus F1 on faithful, to check that the fast preset keeps results;
- in the JSON, ``f1_lost_*``: the F1 each kind of error costs, were it alone put right
  (:func:`pianist.eval.f1_lost_by_kind`: the plan's left-out keys and shifts, notes never
  sounding, late notes, drop-outs, false keys), and their means per preset printed at the end;
- with ``--noisy N``: the mean F1 over N more episodes with Gaussian noise (std 0.005) on the
  planner's actions. One episode's F1 is a chaotic function of the actions (contacts), so
  differences of ~0.01 between two planner versions are only real if the noisy means agree;
- with ``--initial-buffer S``: the same song after S seconds of silence (the original's
  ``initial_buffer_time``), scored over the song's own steps (``song_f1``): what the cold
  start costs, since the debug songs make a note due in the first step while the hands are
  still at home. The benchmark's own numbers are the ones without it.

Run: ``python benchmarks/bench_planner.py [--songs a,b | --suite open-etude-12]
[--presets faithful,fast] [--repeats 3] [--noisy 5] [--initial-buffer 0.5] [--compare-tape]
[--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import cast

import numpy as np

from pianist.control import NoisyController
from pianist.control.planner import IKPlanner, PlannerConfig, forget_plans
from pianist.env import PianoEnv
from pianist.eval import f1_lost_by_kind, run_episode
from pianist.eval.session import make_env
from pianist.music import list_songs

from arguments import preset_list, song_list  # isort: skip  (beside this script)

PRESETS = ("faithful", "fast")
#: The F1 each kind of error costs, in the JSON per song and preset (pianist.eval.f1_lost).
F1_LOST = tuple(
    f"f1_lost_{k}" for k in ("plan_left_out", "plan_in_shift", "never", "late", "dropout", "false")
)
NOISE_STD = 0.005


class _TimedPlanner(IKPlanner):
    """The planner, timing its own ``act`` calls."""

    def reset(self, env, seed=None) -> None:
        self.act_seconds = 0.0
        super().reset(env, seed)

    def act(self, observation=None) -> np.ndarray:
        start = time.perf_counter()
        action = super().act(observation)
        self.act_seconds += time.perf_counter() - start
        return action


def noisy_f1(song: str, physics: str, episodes: int, buffer_s: float = 0.0) -> tuple[float, float]:
    """Mean and standard deviation of F1 over ``episodes`` noisy episodes (after a lead-in of
    ``buffer_s``: the F1 of the song's own steps)."""
    noisy = NoisyController(IKPlanner(), NOISE_STD)
    env = make_env(song, noisy, physics=physics, initial_buffer_s=buffer_s)
    key = "song_f1" if cast(PianoEnv, env.unwrapped).config.lead_in_steps else "f1"
    f1 = [run_episode(env, noisy, seed=i).metrics()[key] for i in range(episodes)]
    return float(np.mean(f1)), float(np.std(f1))


def lead_in_f1(song: str, physics: str, buffer_s: float) -> float:
    """F1 of the song's own steps in one episode after ``buffer_s`` seconds of silence."""
    planner = IKPlanner()
    env = make_env(song, planner, physics=physics, initial_buffer_s=buffer_s)
    return run_episode(env, planner, seed=0).metrics()["song_f1"]


def plan_seconds_per_minute(song: str, physics: str, repeats: int) -> float:
    """Median seconds the whole-piece plans take to make (every candidate, chosen by the
    key-frames each leaves playable, none rehearsed) per minute of the song's music."""
    config = PlannerConfig().with_fields(choose_plan="playable")
    warm = IKPlanner(config)
    env = make_env(song, warm, physics=physics)
    env.reset(seed=0)
    warm.reset(env, seed=0)  # the posture samples, cached per model, are not the plan's
    times = []
    for _ in range(repeats):
        forget_plans()
        planner = IKPlanner(config)
        env.reset(seed=0)
        start = time.perf_counter()
        planner.reset(env, seed=0)
        times.append(time.perf_counter() - start)
    minutes = planner.goal.num_frames * planner.dt / 60.0
    return float(np.median(times)) / minutes


def _timed_episode(song: str, physics: str, config: PlannerConfig) -> tuple[dict, float, float]:
    """One cold-start episode (plans made and rehearsed anew): its metrics with the F1 lost
    by kind, its real-time factor and the planner's share of the wall time."""
    planner = _TimedPlanner(config)
    env = make_env(song, planner, physics=physics)
    forget_plans()
    start = time.perf_counter()
    episode = run_episode(env, planner, seed=0)
    wall = time.perf_counter() - start
    metrics = episode.metrics()
    metrics.update(f1_lost_by_kind(episode.active_keys, episode.goal_keys, planner.plan_arrays()))
    return metrics, metrics["seconds"] / wall, planner.act_seconds / wall


def bench_song(song: str, physics: str, repeats: int, compare_tape: bool = False) -> dict:
    rates, shares, untaped = [], [], []
    metrics: dict = {}
    for _ in range(repeats):
        metrics, rate, share = _timed_episode(song, physics, PlannerConfig())
        rates.append(rate)
        shares.append(share)
        if compare_tape:  # in turns, so that the machine's load weighs on both alike
            other, rate, _ = _timed_episode(
                song, physics, PlannerConfig().with_fields(replay_tape=False)
            )
            if other["f1"] != metrics["f1"]:
                raise AssertionError(
                    f"{song} {physics}: F1 {metrics['f1']} with the tape, {other['f1']} without"
                )
            untaped.append(rate)
    result = {
        "precision": metrics["precision"],
        "recall": metrics["recall"],
        "f1": metrics["f1"],
        "sustain_f1": metrics["sustain_f1"],
        "seconds": metrics["seconds"],
        "realtime_factor": float(np.median(rates)),
        "planner_share": float(np.median(shares)),
        **{k: v for k, v in metrics.items() if k.startswith("f1_lost_")},
    }
    if compare_tape:
        result["realtime_factor_no_tape"] = float(np.median(untaped))
        result["tape_speedup"] = result["realtime_factor"] / result["realtime_factor_no_tape"]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", default=",".join(list_songs()))
    parser.add_argument("--suite", default=None, help="all songs of a suite, e.g. open-etude-12")
    parser.add_argument("--presets", default=",".join(PRESETS))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--noisy", type=int, default=0, help="episodes of the noisy mean F1")
    parser.add_argument(
        "--initial-buffer", type=float, default=0.0, help="also score after S s of silence"
    )
    parser.add_argument(
        "--compare-tape",
        action="store_true",
        help="also time the performance simulated again (replay_tape=False)",
    )
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error(f"--repeats must be at least 1, not {args.repeats}")
    songs = song_list(parser, None if args.suite else args.songs, args.suite)
    presets = preset_list(parser, args.presets)

    results: dict[str, dict[str, dict[str, float]]] = {}
    header = (
        f"{'song':34s} {'preset':9s} {'P':>6s} {'R':>6s} {'F1':>6s} {'rtf':>6s} {'plan':>5s}"
        f" {'plan s/min':>10s}"
    )
    if args.compare_tape:
        header += f" {'rtf untaped':>11s} {'speed-up':>8s}"
    if args.noisy:
        header += f" {'noisy F1':>14s}"
    buffer = args.initial_buffer
    if buffer:
        header += f" {'lead-in F1':>10s}" + (f" {'noisy':>14s}" if args.noisy else "")
    print(header)
    for song in songs:
        results[song] = {}
        for physics in presets:
            r = bench_song(song, physics, args.repeats, args.compare_tape)
            r["plan_seconds_per_minute"] = plan_seconds_per_minute(song, physics, args.repeats)
            line = (
                f"{song:34s} {physics:9s} {r['precision']:6.3f} {r['recall']:6.3f} "
                f"{r['f1']:6.3f} {r['realtime_factor']:6.1f} {r['planner_share']:5.2f}"
                f" {r['plan_seconds_per_minute']:10.2f}"
            )
            if args.compare_tape:
                line += f" {r['realtime_factor_no_tape']:11.1f} {r['tape_speedup']:8.2f}"
            if args.noisy:
                r["noisy_f1_mean"], r["noisy_f1_std"] = noisy_f1(song, physics, args.noisy)
                line += f" {r['noisy_f1_mean']:7.3f}+-{r['noisy_f1_std']:.3f}"
            if buffer:
                r["initial_buffer_s"] = buffer
                r["lead_in_song_f1"] = lead_in_f1(song, physics, buffer)
                line += f" {r['lead_in_song_f1']:10.3f}"
                if args.noisy:
                    mean, std = noisy_f1(song, physics, args.noisy, buffer)
                    r["lead_in_noisy_song_f1_mean"], r["lead_in_noisy_song_f1_std"] = mean, std
                    line += f" {mean:7.3f}+-{std:.3f}"
            results[song][physics] = r
            print(line, flush=True)
    if set(PRESETS) <= set(presets):
        print(f"\n{'song':34s} {'dF1 (fast - faithful)':>22s}")
        for song, by_preset in results.items():
            print(f"{song:34s} {by_preset['fast']['f1'] - by_preset['faithful']['f1']:+22.3f}")
    for p in presets:
        print(f"mean F1 {p}: {np.mean([r[p]['f1'] for r in results.values()]):.3f}")
        rtf = [r[p]["realtime_factor"] for r in results.values()]
        print(f"median real-time factor {p}: {np.median(rtf):.1f} (slowest {min(rtf):.1f})")
        per_minute = [r[p]["plan_seconds_per_minute"] for r in results.values()]
        print(
            f"whole-piece plans {p}: median {np.median(per_minute):.2f} s per minute of music "
            f"(slowest {max(per_minute):.2f})"
        )
        if args.compare_tape:
            untaped = np.median([r[p]["realtime_factor_no_tape"] for r in results.values()])
            speedup = np.median([r[p]["tape_speedup"] for r in results.values()])
            print(f"  without the tape: {untaped:.1f}; median speed-up {speedup:.2f}x")
        if args.noisy:
            noisy = np.mean([r[p]["noisy_f1_mean"] for r in results.values()])
            print(f"mean noisy F1 {p}: {noisy:.3f}")
        lost = {k: np.mean([r[p][k] for r in results.values()]) for k in F1_LOST}
        print(
            f"mean F1 lost {p} (each kind alone put right): "
            + ", ".join(f"{k} {v:.3f}" for k, v in lost.items())
        )
        if buffer:
            lead = np.mean([r[p]["lead_in_song_f1"] for r in results.values()])
            print(f"mean F1 {p} after a {buffer:g} s lead-in (song steps): {lead:.3f}")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=2)


if __name__ == "__main__":
    main()
