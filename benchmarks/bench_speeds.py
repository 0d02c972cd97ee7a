"""How fast each controller kind plays, measured: the one source of the speeds that
``pianist play --help`` and the README quote.

Each kind plays the openings (``--seconds``, default 20 s) of a few pieces in each physics
preset, one episode each, planning included (the episode's wall time, as ``metrics.json``
records it); the median real-time factor per kind and preset is written to
``src/pianist/control/speeds.json`` (with ``--write``), which
:func:`pianist.control.registry.controller_help` and the README's speed table read, and to
``--json`` with every episode. Run it on an otherwise idle machine:

    python benchmarks/bench_speeds.py --write

Then ``python benchmarks/bench_speeds.py --readme`` rewrites the README's table from the file
(tests/test_readme.py checks that they agree).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from datetime import date
from pathlib import Path
from typing import Any

from pianist.control.registry import parse_controller, speeds_table
from pianist.eval.session import play
from pianist.files import write_json_atomic
from pianist.music import load_song

from arguments import preset_list, song_list  # isort: skip  (beside this script)

#: The kinds measured, as --controller strings, and the seconds of each opening they play
#: (the slow ones shorter).
KINDS = {
    "planner": None,
    "refine": None,
    "search": None,
    "mpc": 2.0,
    "mpc:tenth": 2.0,
    "generalist": None,
}
ROOT = Path(__file__).resolve().parent.parent
SPEEDS = ROOT / "src" / "pianist" / "control" / "speeds.json"
README = ROOT / "README.md"
DEFAULT_SONGS = "bach-chorale-bwv66-6,mozart-sonata-k545-allegro,chopin-mazurka-op6-no2"


def measure(kind: str, song: str, seconds: float, physics: str) -> dict:
    from pianist.eval.session import excerpt_of

    piece = excerpt_of(load_song(song), 0.0, seconds)
    result = play(piece, parse_controller(kind).build(), physics=physics, seed=0)
    m = result.metrics
    return {
        "kind": kind,
        "song": song,
        "physics": physics,
        "seconds": m["seconds"],
        "wall_s": m["wall_seconds"],
        "realtime_factor": m["realtime_factor"],
        "f1": m["f1"],
    }


def _median(rows: list[dict], kind: str, physics: str) -> float:
    return statistics.median(
        r["realtime_factor"] for r in rows if r["kind"] == kind and r["physics"] == physics
    )


def rewrite_readme(speeds: dict) -> None:
    text = README.read_text()
    start, end = "<!-- speeds: benchmarks/bench_speeds.py -->", "<!-- /speeds -->"
    head, _, rest = text.partition(start)
    _, _, tail = rest.partition(end)
    if not rest:
        raise SystemExit(f"README.md has no {start} ... {end} block")
    README.write_text(f"{head}{start}\n{speeds_table(speeds)}\n{end}{tail}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", default=DEFAULT_SONGS)
    parser.add_argument("--presets", default="faithful,fast")
    parser.add_argument("--seconds", type=float, default=20.0, help="opening played (s)")
    parser.add_argument("--kinds", default=",".join(KINDS), help="controller strings")
    parser.add_argument("--write", action="store_true", help=f"write {SPEEDS.name}")
    parser.add_argument("--readme", action="store_true", help="rewrite README's speed table")
    parser.add_argument("--json", default=None, help="also write every episode here")
    args = parser.parse_args()
    if args.readme and not args.write:
        rewrite_readme(json.loads(SPEEDS.read_text()))
        return
    songs = song_list(parser, args.songs, None)
    presets = preset_list(parser, args.presets)
    kinds = args.kinds.split(",")
    for kind in kinds:
        try:
            parse_controller(kind)
        except ValueError as exc:
            parser.error(str(exc))
    rows = []
    started = time.perf_counter()
    for kind in kinds:
        seconds = KINDS.get(kind) or args.seconds
        for physics in presets:
            for song in songs:
                row = measure(kind, song, seconds, physics)
                rows.append(row)
                print(
                    f"{kind:12s} {physics:9s} {song:32s} {row['seconds']:5.1f} s "
                    f"{row['realtime_factor']:7.3f}x  F1 {row['f1']:.3f}",
                    flush=True,
                )
    shorter = ", ".join(f"{k} {v:g} s" for k, v in KINDS.items() if v and k in kinds)
    speeds: dict[str, Any] = {
        "date": date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "what": (
            f"median over the first {args.seconds:g} s ({shorter}) of {', '.join(songs)}; "
            "one episode each, planning included"
        ),
        "kinds": {
            kind: {physics: _median(rows, kind, physics) for physics in presets} for kind in kinds
        },
    }
    print(f"\n{'controller':12s} " + " ".join(f"{p:>9s}" for p in presets))
    for kind, row in speeds["kinds"].items():
        print(f"{kind:12s} " + " ".join(f"{row[p]:9.3f}" for p in presets))
    print(f"({time.perf_counter() - started:.0f} s)")
    if args.write:
        write_json_atomic(speeds, SPEEDS)
        rewrite_readme(speeds)
    if args.json:
        write_json_atomic({"speeds": speeds, "episodes": rows}, Path(args.json))


if __name__ == "__main__":
    main()
