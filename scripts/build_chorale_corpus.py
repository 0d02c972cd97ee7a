"""Build the chorale training corpus for the generalist from the music21 corpus.

Every four-part Bach chorale of the music21 corpus except the two in ``open-etude-12``
(BWV 66.6 and BWV 269, held out for testing), cut into fixed segments of ``--measures``
measures, converted as ``scripts/build_open_library.py`` converts its chorales (quarter = 72,
soprano right, bass left, inner voices to either hand, every note fingered automatically) and
written as PIG files (``<chorale>-m<first>.txt``) with a ``provenance.json``. Segments the
fingerer cannot make playable are left out and listed. ``--transpose -5,7`` adds each
segment shifted by those semitones too (``...-m1-t+7``; hands kept, fingered again).

Deterministic: the same music21 corpus and arguments give the same files. music21 is needed
only here (``pip install music21``). The files go to ``--out`` (default: ``corpus/chorales``
under the working folder), which is replaced whole.

Usage:
    python scripts/build_chorale_corpus.py [--out DIR] [--measures 4] [--limit N]
        [--transpose -5,7]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from build_open_library import CHORALE_NOTE, Piece, _convert  # noqa: E402

from pianist.files import atomic_dir  # noqa: E402
from pianist.music import (  # noqa: E402
    Song,
    assign_fingering,
    check_playability,
    strip_fingering,
    write_pig,
)
from pianist.music.transforms import transpose  # noqa: E402

#: Chorales of open-etude-12: never in the training corpus.
HELD_OUT = ("bach/bwv66.6", "bach/bwv269")


def chorale_paths() -> list[str]:
    """Corpus paths ("bach/bwvN.M") of the four-part chorales, in the corpus's order."""
    from music21 import corpus

    paths = []
    for path in corpus.getComposer("bach"):
        name = "bach/" + Path(str(path)).stem
        if name.startswith("bach/bwv") and "." in name and name not in HELD_OUT:
            paths.append(name)
    return paths


def segments(corpus_path: str, measures: int) -> list[tuple[int, int]]:
    """(first, last) measure numbers of each whole segment of ``measures`` measures."""
    from music21 import corpus

    score = corpus.parse(corpus_path)
    if len(score.parts) != 4:
        return []
    numbers = sorted({m.number for m in score.parts[0].getElementsByClass("Measure")})
    numbers = [n for n in numbers if n >= 1]  # a pickup measure 0 is left out
    return [
        (numbers[i], numbers[i + measures - 1])
        for i in range(0, len(numbers) - measures + 1, measures)
    ]


def _variants(song: Song, info: dict, shifts: list[int]) -> list[tuple[Song, dict, str]]:
    """The segment and each playable transposition of it: (song, info, reason left out)."""
    out = [(song, info, "")]
    for shift in shifts:
        name = f"{info['name']}-t{shift:+d}"
        moved = assign_fingering(strip_fingering(transpose(song, shift), keep_hands=True))
        moved = Song(moved.notes, name=name)
        problems = check_playability(moved)
        entry = {**info, "name": name, "file": f"{name}.txt", "transposed": shift}
        out.append((moved, entry, "; ".join(problems)))
    return out


def build(out_dir: Path, measures: int, limit: int | None, shifts: list[int]) -> dict:
    """Write the corpus to ``out_dir`` (whole or not at all); returns its provenance record."""
    import music21

    pieces, skipped = [], []
    with atomic_dir(out_dir) as tmp:
        for corpus_path in chorale_paths()[:limit]:
            stem = corpus_path.split("/")[1].replace(".", "-")
            for first, last in segments(corpus_path, measures):
                name = f"bach-chorale-{stem}-m{first}"
                piece = Piece(
                    name,
                    corpus_path,
                    f"Chorale {stem}, measures {first}-{last}",
                    "Johann Sebastian Bach",
                    "1685-1750",
                    first,
                    last,
                    right_parts=(0,),
                    quarter_bpm=72.0,
                    free_parts=(1, 2),
                    note=CHORALE_NOTE,
                )
                try:
                    song, info = _convert(piece)
                except (SystemExit, ValueError, KeyError) as exc:
                    skipped.append({"name": name, "reason": str(exc)})
                    continue
                if info["problems"]:
                    skipped.append({"name": name, "reason": "; ".join(info["problems"])})
                    continue
                for variant, entry, problem in _variants(song, info, shifts):
                    if problem:
                        skipped.append({"name": entry["name"], "reason": problem})
                        continue
                    write_pig(variant, tmp / entry["file"])
                    pieces.append(entry)
                    print(f"{entry['name']:44s} {entry['duration_s']:5.1f} s")  # noqa: T201
        record = {
            "suite": "chorales",
            "description": (
                f"Bach chorales of the music21 corpus in {measures}-measure segments, "
                f"on the keyboard; held out: {', '.join(HELD_OUT)}"
            ),
            "built_with": f"music21 {music21.__version__}",
            "pieces": pieces,
            "skipped": skipped,
        }
        (tmp / "provenance.json").write_text(json.dumps(record, indent=1) + "\n")
    return record


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("corpus/chorales"))
    parser.add_argument("--measures", type=int, default=4)
    parser.add_argument("--limit", type=int, default=None, help="use the first N chorales")
    parser.add_argument("--transpose", default="", help="semitone shifts added, e.g. -5,7")
    args = parser.parse_args()
    if args.measures < 1:
        parser.error("--measures must be >= 1")
    shifts = [int(x) for x in args.transpose.split(",") if x.strip()]
    record = build(args.out, args.measures, args.limit, shifts)
    seconds = sum(p["duration_s"] for p in record["pieces"])
    print(  # noqa: T201
        f"{len(record['pieces'])} segments ({seconds / 60:.1f} min of music), "
        f"{len(record['skipped'])} left out, in {args.out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
