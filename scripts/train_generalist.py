"""Train the generalist shipped with the package (``--controller generalist``), from nothing.

1. The corpora, each built once (skipped when its folder exists): the chorales
   (``scripts/build_chorale_corpus.py``; needs ``pip install music21``): the Bach chorales
   of the music21 corpus (``--chorales N``: the first N; 0, all of them) in 4-measure
   segments, the two of ``open-etude-12`` held out; and ``--etudes N`` generated etudes
   (``scripts/build_etude_corpus.py``: stride basses, Alberti basses, arpeggios, runs,
   dance rhythms, leaps; 0: none).
2. The fingertip policy (:mod:`pianist.agents.fingertip.training`): the planner plays every
   segment once (fast physics) and its per-hand decisions are recorded; an MLP is fitted to
   them; then ``--rounds`` rounds of DAgger, each on the next share of the segments (the
   songs are played ``--workers`` at a time).
3. The policy is written to ``--out`` (default: the package's ``agents/data/generalist``).

Needs the ``rl`` extra (JAX). Run from the repository root:

    python scripts/train_generalist.py [--chorales 0] [--etudes 400] [--rounds 4] [--workers 2]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from pianist.agents.fingertip import save_policy
from pianist.agents.fingertip.training import FitConfig, train
from pianist.agents.generalist import GENERALIST_DIR

ROOT = Path(__file__).resolve().parents[1]


def log(line: str) -> None:
    print(line, flush=True)  # noqa: T201


def _build(folder: Path, script: str, options: list[str]) -> None:
    """Build a corpus folder with one of the corpus scripts, unless it exists."""
    if not folder.is_dir():
        command = [sys.executable, str(ROOT / "scripts" / script), "--out", str(folder)]
        subprocess.run([*command, *options], check=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=ROOT / "corpus")
    parser.add_argument("--chorales", type=int, default=0, help="the first N chorales; 0: all")
    parser.add_argument("--etudes", type=int, default=400, help="generated etudes; 0: none")
    parser.add_argument("--hidden", type=int, nargs="+", default=[256, 256])
    parser.add_argument("--steps", type=int, default=6000)
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--fingering",
        choices=["plan", "song"],
        default="plan",
        help="the fingering the policy reads: the planner's plan for this robot, or the song's",
    )
    parser.add_argument(
        "--forearm",
        choices=["plan", "policy"],
        default=None,
        help="where the policy's forearms go in the DAgger rounds: along the plan's path (the "
        "default with the plan's fingering, as it plays) or to its own slide targets",
    )
    parser.add_argument("--out", type=Path, default=GENERALIST_DIR)
    args = parser.parse_args()

    corpus = args.work / f"chorales-{args.chorales or 'all'}"
    limit = ["--limit", str(args.chorales)] if args.chorales else []
    _build(corpus, "build_chorale_corpus.py", limit)
    songs = sorted(str(path) for path in corpus.glob("*.txt"))
    corpora = [corpus.name]
    if args.etudes:
        etudes = args.work / f"etudes-{args.etudes}"
        _build(etudes, "build_etude_corpus.py", ["--count", str(args.etudes)])
        songs += sorted(str(path) for path in etudes.glob("*.txt"))
        corpora.append(etudes.name)
    config = FitConfig(hidden_dims=tuple(args.hidden), steps=args.steps)
    policy = train(songs, args.rounds, config, args.workers, log, args.fingering, args.forearm)
    policy.info["trained_by"] = "scripts/train_generalist.py " + " ".join(sys.argv[1:])
    policy.info["corpus"] = "+".join(corpora)
    save_policy(policy, args.out)
    log(f"wrote {args.out} in {policy.info['minutes']} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
