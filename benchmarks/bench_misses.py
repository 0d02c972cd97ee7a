"""Where the planner's misses are: each missed key-frame by its cause, per finger.

For every song of the suite, one episode of the IK planner (seed 0) in the environment the CLI
uses for it. At every step, each key due then and not sounding is put in one class:

- left out: the plan gives it no finger that can press it (a chord wider than the hand);
- else by the named state of the finger the plan gives it (``FingerState``): ``lifted``,
  ``hovering`` (not lined up with its key), ``pressing`` or ``pushing`` (on it, not sounding
  it), ``restriking`` or ``travelling`` (the hand is shifting). A ``lifted`` miss is a key
  held across a shift of its hand when the frame is one of the shift's (``held_in_shift``).

The left-out key-frames in all, and per finger (thumb 0 to little finger 4, both hands
together) the planned key-frames due and missed by class; for ``hovering`` and ``pressing``
the median distance across the keys from the fingertip to the key.
``docs/notes/2026-12-07-planner-plans.md``
("Misses traced to their cause") reads it.

Run: ``python benchmarks/bench_misses.py [--suite open-etude-12] [--physics fast]
[--json out.json]``.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from pianist.control.planner import FingerState, IKPlanner
from pianist.eval.session import make_env
from pianist.music import list_songs

CLASSES = ("left_out", *(state.name.lower() for state in FingerState))


def misses(song: str, physics: str) -> dict:
    """Due and missed key-frames of one episode by class and finger, and the distances."""
    planner = IKPlanner()
    env = make_env(song, planner, physics=physics)
    observation, _ = env.reset(seed=0)
    planner.reset(env, seed=0)
    goal, data = planner.goal.keys, planner.handle.data
    due = np.zeros(5, dtype=int)  # planned key-frames, by the finger the plan gives them
    left_out = left_out_missed = 0
    missed = {name: np.zeros(5, dtype=int) for name in CLASSES[1:]}
    held_in_shift = 0
    across: dict[str, list[float]] = {"hovering": [], "pressing": []}
    for t in range(goal.shape[0]):
        observation, _, terminated, truncated, info = env.step(planner.act(observation))
        sounding = info["active_keys"]
        planned = np.zeros_like(goal[t])
        for hand, arrays, memory in zip(
            planner.hands, planner.plan.hands, planner.memories, strict=True
        ):
            for key in np.flatnonzero(goal[t] & ~arrays.skip[t]).tolist():
                finger = int(planner.fingers[t, key]) - hand.finger_offset
                if not 0 <= finger < 5:
                    continue  # the other hand's
                planned[key] = True
                due[finger] += 1
                if sounding[key]:
                    continue
                state = FingerState(int(memory.state[finger])).name.lower()
                missed[state][finger] += 1
                if state == "lifted" and arrays.free[t] and t > 0 and goal[t - 1, key]:
                    held_in_shift += 1
                if state in across:
                    tip = data.site_xpos[hand.sites[finger], 1]
                    across[state].append(abs(float(tip - planner.key_point[key, 1])))
        out = goal[t] & ~planned  # no hand's plan gives these a finger
        left_out += int(out.sum())
        left_out_missed += int((out & ~sounding).sum())
        if terminated or truncated:
            break
    return {
        "due": due.tolist(),
        "left_out": left_out,
        "left_out_missed": left_out_missed,
        "missed": {name: counts.tolist() for name, counts in missed.items()},
        "held_in_shift": held_in_shift,
        "across_m": across,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="open-etude-12")
    parser.add_argument("--physics", default="fast", choices=("fast", "faithful"))
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    songs = {song: misses(song, args.physics) for song in list_songs(args.suite)}
    due = np.sum([r["due"] for r in songs.values()], axis=0)
    missed = {c: np.sum([r["missed"][c] for r in songs.values()], axis=0) for c in CLASSES[1:]}
    left_out = sum(r["left_out"] for r in songs.values())
    left_out_missed = sum(r["left_out_missed"] for r in songs.values())
    total = left_out_missed + int(sum(int(m.sum()) for m in missed.values()))
    held = sum(r["held_in_shift"] for r in songs.values())
    print(
        f"{args.suite}, {args.physics}: {total} of {int(due.sum()) + left_out} due key-frames "
        f"missed; {left_out_missed} of the {left_out} the plan leaves out"
    )
    print(f"{'planned':12s} {'all':>6s} " + " ".join(f"{'finger ' + str(f):>9s}" for f in range(5)))
    print(f"{'due':12s} {int(due.sum()):6d} " + " ".join(f"{int(d):9d}" for d in due))
    for name in CLASSES[1:]:
        counts = missed[name]
        print(f"{name:12s} {int(counts.sum()):6d} " + " ".join(f"{int(c):9d}" for c in counts))
    print(f"lifted misses that are keys held across a shift of their hand: {held}")
    medians = {}
    for state in ("hovering", "pressing"):
        values = [v for r in songs.values() for v in r["across_m"][state]]
        medians[state] = float(np.median(values)) if values else None
        if values:
            print(f"{state}: median {1000 * np.median(values):.1f} mm across from the key")
    if args.json:
        summary = {
            "suite": args.suite,
            "physics": args.physics,
            "due": due.tolist(),
            "left_out": left_out,
            "left_out_missed": left_out_missed,
            "missed": {c: m.tolist() for c, m in missed.items()},
            "held_in_shift": held,
            "median_across_m": medians,
            "songs": {
                song: {k: v for k, v in r.items() if k != "across_m"} for song, r in songs.items()
            },
        }
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()
