"""The generalist: F1 on held-out pieces, and how it scales with training songs and model size.

``eval``: one policy (default: the shipped generalist; a fingertip policy folder or a
behaviour-cloning one) plays every song of the held-out suites once (seed 0, fast physics
or ``--physics faithful``) in NumPy; per song F1, precision, recall and the real-time factor
(simulated seconds per wall-clock second), and the mean per suite. A fingertip policy's
forearms follow the plan's path, or with ``--forearm policy`` its own slide targets.

``fingertip-scaling``: the same experiment for the fingertip policy (the shipped design,
:mod:`pianist.agents.fingertip.training`): for each N and network size, a policy trained on
the first N songs of a fixed shuffle of the corpus folders (the expert's recordings, a fit,
``--rounds`` of DAgger), scored on the held-out suite.

``scaling``: the paper's multi-song BC experiment (joint angles), extended with DAgger. For
each number of training songs N (the first N songs of a planner demonstration dataset) and
each hidden size, a policy is trained by behaviour cloning (``--steps`` Adam steps), then
``--dagger-rounds`` rounds of DAgger on the same N songs, and scored on the held-out suite;
also on its own training songs (up to 8 of them). The paper's figure is printed beside: BC
distilled from its RL specialists, <= ~0.15 zero-shot on etude-12.

Run:
    python benchmarks/bench_generalist.py eval [--policy DIR] [--suites open-etude-12,debug] \
        [--forearm plan|policy] [--physics fast|faithful]
    python benchmarks/bench_generalist.py fingertip-scaling \
        --corpus corpus/chorales-all corpus/etudes-400 [--sizes 8,64,256] \
        [--hidden 256x256,512x512] [--rounds 1] [--fingering plan|song]
    python benchmarks/bench_generalist.py scaling --dataset pianist/chorales-planner-v0 \
        [--root DIR] [--sizes 1,8,32,128] [--hidden 256,512] [--dagger-rounds 2]
Both print a table and, with ``--json FILE``, write it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from pianist.agents.bc import (
    BCConfig,
    BCPolicy,
    dagger,
    demonstrations,
    load_policy,
    play_song_episode,
    train_bc,
)
from pianist.agents.generalist import GENERALIST_DIR
from pianist.env.multi_song import MultiSongEnv
from pianist.music import list_songs

#: The paper's multi-song BC, zero-shot on etude-12 (facts page, section 6).
PAPER_BC_ETUDE12 = "<= ~0.15"


def evaluate_fingertip(
    policy: Any, songs: list[str], forearm: Any = None, physics: str = "fast"
) -> dict[str, dict[str, float]]:
    """Each song played once (seed 0) by a fingertip policy (or its folder); ``forearm``:
    where its forearms go (None: the controller's default, the plan's path)."""
    from pianist.agents.fingertip import FingertipController
    from pianist.eval.session import play

    rows: dict[str, dict[str, float]] = {}
    for song in songs:
        controller = FingertipController(policy, forearm=forearm)
        m = play(song, controller, physics=physics, seed=0).metrics
        rows[song] = {
            "f1": m["f1"],
            "precision": m["precision"],
            "recall": m["recall"],
            "rtf": m["realtime_factor"],
        }
    return rows


def evaluate(policy: BCPolicy, songs: list[str], seed: int = 0) -> dict[str, dict[str, float]]:
    """Each song played once by ``policy``: F1, precision, recall, real-time factor."""
    env = MultiSongEnv(songs, **policy.env_options)
    policy.features.check(env.observation_space)
    rows: dict[str, dict[str, float]] = {}
    try:
        for index, song in enumerate(songs):
            row = play_song_episode(policy, env, index, seed)
            rows[song] = {k: v for k, v in row.items() if k != "song"}
    finally:
        env.close()
    return rows


def _mean(rows: dict[str, dict[str, float]], key: str = "f1") -> float:
    return float(np.mean([row[key] for row in rows.values()]))


def cmd_eval(args: argparse.Namespace) -> dict[str, Any]:
    from pianist.agents import fingertip

    policy: Any
    if (args.policy / fingertip.controller.CONFIG_FILE).is_file():
        policy = fingertip.load_policy(args.policy)

        def play_all(policy: Any, songs: list[str]) -> dict[str, dict[str, float]]:
            return evaluate_fingertip(policy, songs, args.forearm, args.physics)

        forearm = fingertip.FingertipController(policy, forearm=args.forearm).forearm
    else:
        policy = load_policy(args.policy)
        play_all = evaluate
        forearm = None
    result: dict[str, Any] = {
        "policy": str(args.policy),
        "info": policy.info,
        "forearm": forearm,
        "physics": args.physics if forearm else "fast",
        "suites": {},
    }
    print(f"{'suite':18s} {'song':40s} {'F1':>6s} {'P':>6s} {'R':>6s} {'rtf':>6s}")
    for suite in args.suites.split(","):
        rows = play_all(policy, list_songs(suite))
        for song, row in rows.items():
            print(
                f"{suite:18s} {song:40s} {row['f1']:6.3f} {row['precision']:6.3f} "
                f"{row['recall']:6.3f} {row['rtf']:6.1f}"
            )
        mean = {k: _mean(rows, k) for k in ("f1", "precision", "recall", "rtf")}
        print(
            f"{suite:18s} {'mean':40s} {mean['f1']:6.3f} {mean['precision']:6.3f} "
            f"{mean['recall']:6.3f} {mean['rtf']:6.1f}"
        )
        result["suites"][suite] = {"songs": rows, "mean": mean}
    return result


def cmd_fingertip_scaling(args: argparse.Namespace) -> dict[str, Any]:
    from pianist.agents.fingertip.training import FitConfig, train

    songs = sorted(str(p) for folder in args.corpus for p in Path(folder).glob("*.txt"))
    # The first N of a fixed shuffle, so that every N draws from every corpus given.
    songs = [songs[i] for i in np.random.default_rng(0).permutation(len(songs))]
    held_out = list_songs(args.held_out)
    result: dict[str, Any] = {
        "corpus": [str(c) for c in args.corpus],
        "held_out": args.held_out,
        "rounds": args.rounds,
        "fingering": args.fingering,
        "paper_bc_etude12": PAPER_BC_ETUDE12,
        "rows": [],
    }
    print(f"{'songs':>5s} {'hidden':>8s} {'train F1':>8s} {'held-out F1':>11s} {'minutes':>7s}")
    for size in [int(s) for s in args.sizes.split(",")]:
        if size > len(songs):
            raise SystemExit(f"the corpus has {len(songs)} songs, not {size}")
        for hidden in args.hidden.split(","):
            dims = tuple(int(h) for h in hidden.split("x"))
            start = time.perf_counter()
            config = FitConfig(hidden_dims=dims, seed=args.seed)
            policy = train(songs[:size], args.rounds, config, 2, fingering=args.fingering)
            own = evaluate_fingertip(policy, songs[: min(size, 8)])
            test = evaluate_fingertip(policy, held_out)
            row = {
                "songs": size,
                "hidden": list(dims),
                "train_f1": _mean(own),
                "held_out_f1": _mean(test),
                "held_out": {k: v["f1"] for k, v in test.items()},
                "history": policy.info["history"],
                "minutes": (time.perf_counter() - start) / 60,
            }
            result["rows"].append(row)
            print(
                f"{size:5d} {hidden:>8s} {row['train_f1']:8.3f} {row['held_out_f1']:11.3f} "
                f"{row['minutes']:7.1f}",
                flush=True,
            )
    return result


def cmd_scaling(args: argparse.Namespace) -> dict[str, Any]:
    from pianist.data.minari_io import dataset_setup, load_dataset

    dataset = load_dataset(args.dataset, Path(args.root) if args.root else None)
    options, songs = dataset_setup(dataset)
    held_out = list_songs(args.held_out)
    sizes = [int(s) for s in args.sizes.split(",")]
    hidden = [int(h) for h in args.hidden.split(",")]
    result: dict[str, Any] = {
        "dataset": args.dataset,
        "held_out": args.held_out,
        "steps": args.steps,
        "dagger_rounds": args.dagger_rounds,
        "paper_bc_etude12": PAPER_BC_ETUDE12,
        "rows": [],
    }
    print(
        f"{'songs':>5s} {'hidden':>6s} {'steps':>6s} {'train F1':>8s} "
        f"{'held-out F1':>11s} {'minutes':>7s}   (paper's BC on etude-12: {PAPER_BC_ETUDE12})"
    )
    for size in sizes:
        if size > len(songs):
            raise SystemExit(f"the dataset has {len(songs)} songs, not {size}")
        # One episode per song, in the dataset's song order: the first `size` episodes.
        episodes = dataset.iterate_episodes(episode_indices=list(range(size)))
        data_all = demonstrations((dict(e.observations), np.asarray(e.actions)) for e in episodes)
        for width in hidden:
            start = time.perf_counter()
            data = type(data_all)(data_all.features, data_all.x.copy(), data_all.y.copy())
            config = BCConfig(hidden_dims=(width, width), steps=args.steps, seed=args.seed)
            trained = train_bc(data, config, options)
            policy, _ = dagger(
                data, songs[:size], args.dagger_rounds, config, options, trained=trained
            )
            own = evaluate(policy, songs[: min(size, 8)])
            test = evaluate(policy, held_out)
            row = {
                "songs": size,
                "hidden": width,
                "demo_steps": int(len(data_all.x)),
                "train_f1": _mean(own),
                "held_out_f1": _mean(test),
                "held_out": {k: v["f1"] for k, v in test.items()},
                "minutes": (time.perf_counter() - start) / 60,
            }
            result["rows"].append(row)
            print(
                f"{size:5d} {width:6d} {row['demo_steps']:6d} {row['train_f1']:8.3f} "
                f"{row['held_out_f1']:11.3f} {row['minutes']:7.1f}",
                flush=True,
            )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    ev = sub.add_parser("eval", help="score one policy on held-out suites")
    ev.add_argument("--policy", type=Path, default=GENERALIST_DIR)
    ev.add_argument("--suites", default="open-etude-12,debug,robopianist-debug")
    ev.add_argument(
        "--forearm",
        choices=["plan", "policy"],
        default=None,
        help="a fingertip policy's forearms: along the plan's path (its default) or its own",
    )
    ev.add_argument("--physics", choices=["fast", "faithful"], default="fast")
    fs = sub.add_parser("fingertip-scaling", help="the fingertip policy against training songs")
    fs.add_argument("--corpus", required=True, nargs="+", help="folders of training songs (.txt)")
    fs.add_argument("--sizes", default="8,64,256")
    fs.add_argument("--hidden", default="256x256", help="network sizes, e.g. 256x256,512x512")
    fs.add_argument("--rounds", type=int, default=1)
    fs.add_argument("--held-out", default="open-etude-12")
    fs.add_argument("--seed", type=int, default=0)
    fs.add_argument("--fingering", choices=["plan", "song"], default="plan")
    sc = sub.add_parser("scaling", help="held-out F1 against training songs and model size")
    sc.add_argument("--dataset", required=True, help="a planner demonstration dataset id")
    sc.add_argument("--root", default=None, help="where datasets are stored")
    sc.add_argument("--sizes", default="1,8,32,128")
    sc.add_argument("--hidden", default="256")
    sc.add_argument("--steps", type=int, default=6000)
    sc.add_argument("--dagger-rounds", type=int, default=2)
    sc.add_argument("--held-out", default="open-etude-12")
    sc.add_argument("--seed", type=int, default=0)
    for p in (ev, fs, sc):
        p.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args()
    commands = {
        "eval": cmd_eval,
        "fingertip-scaling": cmd_fingertip_scaling,
        "scaling": cmd_scaling,
    }
    result = commands[args.command](args)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
