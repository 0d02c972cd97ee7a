"""Train the generalist shipped with the package (``--controller generalist``), from nothing.

1. The chorale corpus (``scripts/build_chorale_corpus.py``; needs ``pip install music21``):
   the Bach chorales of the music21 corpus (``--chorales N``: the first N; 0, all of them) in
   4-measure segments, the two of ``open-etude-12`` held out.
2. A demonstration dataset of the IK planner playing every segment once (fast physics), in
   Minari format (``pianist dataset build``).
3. Behaviour cloning on it, then ``--rounds`` rounds of DAgger: each round the policy plays
   ``--per-round`` of the segments (taken in turn), the planner labels every state it visits,
   and the policy is trained again on everything (:func:`pianist.agents.bc.dagger`; the
   songs are played ``--workers`` at a time).
4. The policy is written to ``--out`` (default: the package's ``agents/data/generalist``).

Steps 1 and 2 are skipped when their output exists (a rerun resumes). Needs the ``data``
and ``rl`` extras (Minari, JAX). Run from the repository root:

    python scripts/train_generalist.py [--chorales 0] [--rounds 2] [--per-round 220]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from pianist.agents import bc
from pianist.agents.generalist import GENERALIST_DIR
from pianist.data.build import BuildSettings, build_dataset
from pianist.data.minari_io import dataset_dir, dataset_setup, load_dataset

ROOT = Path(__file__).resolve().parents[1]


def log(line: str) -> None:
    print(line, flush=True)  # noqa: T201


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=ROOT / "corpus")
    parser.add_argument("--chorales", type=int, default=0, help="the first N chorales; 0: all")
    parser.add_argument("--hidden", type=int, nargs="+", default=[256, 256])
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--input-noise", type=float, default=0.1)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--per-round", type=int, default=220)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=GENERALIST_DIR)
    args = parser.parse_args()
    start = time.perf_counter()

    name = f"chorales-{args.chorales or 'all'}"
    corpus = args.work / name
    if not corpus.is_dir():
        script = ROOT / "scripts" / "build_chorale_corpus.py"
        command = [sys.executable, str(script), "--out", str(corpus)]
        limit = ["--limit", str(args.chorales)] if args.chorales else []
        subprocess.run([*command, *limit], check=True)
    dataset_id = f"pianist/{name}-planner-v0"
    root = args.work / "datasets"
    if not (dataset_dir(dataset_id, root) / "data").is_dir():
        settings = BuildSettings(controller="planner", physics="fast")
        build_dataset(
            [str(corpus)],
            episodes=1,
            settings=settings,
            dataset_id=dataset_id,
            root=root,
            workers=args.workers,
            log=log,
        )
    dataset = load_dataset(dataset_id, root)
    options, songs = dataset_setup(dataset)
    data = bc.demonstrations(bc.minari_episodes(dataset))
    log(f"{dataset_id}: {len(songs)} songs, {len(data.x)} steps, {data.features.dim} features")

    config = bc.BCConfig(
        hidden_dims=tuple(args.hidden), steps=args.steps, input_noise=args.input_noise
    )
    policy, trainer = bc.train_bc(data, config, options, log)
    history = []
    for r in range(args.rounds):
        first = (r * args.per_round) % len(songs)
        chosen = [songs[(first + i) % len(songs)] for i in range(min(args.per_round, len(songs)))]
        policy, rows = bc.dagger(
            data, chosen, 1, config, options, log, (policy, trainer), workers=args.workers
        )
        f1 = list(rows[0]["f1"].values())
        history.append({"round": r + 1, "songs": len(chosen), "mean_f1": float(np.mean(f1))})
        log(
            f"round {r + 1}: the policy before it played its {len(chosen)} songs at "
            f"mean F1 {np.mean(f1):.3f}; {len(data.x)} steps of data now"
        )
    extra = {
        "trained_by": "scripts/train_generalist.py " + " ".join(sys.argv[1:]),
        "dataset": dataset_id,
        "songs": len(songs),
        "config": bc.config_dict(config),
        "dagger": history,
        "minutes": round((time.perf_counter() - start) / 60, 1),
    }
    bc.save_policy(policy, args.out, extra)
    log(f"wrote {args.out} in {extra['minutes']} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
