"""Build a corpus of generated etudes (:mod:`pianist.music.etudes`) for training the generalist.

Etude ``i`` is ``generate_etude(seed=i)`` (its key, progression, tempo and each hand's figure
chosen by the seed), fingered automatically and written as a PIG file ``etude-<i>-<right>-
<left>.txt``, with a ``provenance.json``. Etudes the fingerer cannot make playable are left
out and listed. Deterministic: the same arguments give the same files. The folder ``--out``
is replaced whole.

Usage:
    python scripts/build_etude_corpus.py [--out corpus/etudes-400] [--count 400]
        [--measures 4]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pianist.files import atomic_dir
from pianist.music import assign_fingering, check_playability, write_pig
from pianist.music.etudes import generate_etude


def build(out_dir: Path, count: int, measures: int) -> dict:
    """Write the corpus to ``out_dir`` (whole or not at all); returns its provenance record."""
    pieces, skipped = [], []
    with atomic_dir(out_dir) as tmp:
        for seed in range(count):
            song = assign_fingering(generate_etude(seed, measures))
            problems = check_playability(song)
            if problems:
                skipped.append({"name": song.name, "reason": "; ".join(problems)})
                continue
            write_pig(song, tmp / f"{song.name}.txt")
            pieces.append(
                {
                    "name": song.name,
                    "file": f"{song.name}.txt",
                    "seed": seed,
                    "measures": measures,
                    "duration_s": round(song.duration_s, 3),
                    "notes": song.num_notes,
                }
            )
        record = {
            "suite": "etudes",
            "description": (
                f"{count} generated etudes of {measures} measures (pianist.music.etudes, "
                "seeds 0..count-1), fingered automatically"
            ),
            "pieces": pieces,
            "skipped": skipped,
        }
        (tmp / "provenance.json").write_text(json.dumps(record, indent=1) + "\n")
    return record


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="default corpus/etudes-COUNT")
    parser.add_argument("--count", type=int, default=400)
    parser.add_argument("--measures", type=int, default=4)
    args = parser.parse_args()
    if args.count < 1 or args.measures < 1:
        parser.error("--count and --measures must be >= 1")
    out = args.out or Path("corpus") / f"etudes-{args.count}"
    record = build(out, args.count, args.measures)
    seconds = sum(p["duration_s"] for p in record["pieces"])
    print(  # noqa: T201
        f"{len(record['pieces'])} etudes ({seconds / 60:.1f} min of music), "
        f"{len(record['skipped'])} left out, in {out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
