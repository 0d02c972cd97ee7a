"""Automatic fingering: speed (notes/s) and quality (the planner's F1 with each fingering).

Speed: :func:`pianist.music.assign_fingering` on every open-etude-12 piece (fingers stripped,
hands kept) and on the same pieces with hands stripped too; median of ``--repeats`` runs.

Quality: the inverse-kinematics planner plays each piece with
- ``human``: the file's own fingering (debug songs only: the open library is auto-fingered),
- ``auto``: pianist's fingerer (hands kept, fingers re-estimated),
- ``pianoplayer``: the `pianoplayer` package's fingering (hands kept); notes it leaves
  unfingered are filled by pianist's fingerer with pianoplayer's fingers fixed, and the
  coverage is reported. Skipped with a note when pianoplayer is not installed.

Usage:
    python benchmarks/bench_fingering.py [--songs NAME ...] [--quality/--no-quality]
        [--seconds S] [--repeats N] [--json PATH]

Playing is slow (the planner runs at ~real time or below): ``--seconds`` crops each piece
for the quality table (default 10 s) and ``--songs`` picks pieces.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from pianist.music import (
    OPEN_SUITE,
    Note,
    Song,
    assign_fingering,
    list_songs,
    load_song,
    pitch_to_name,
    strip_fingering,
)

DEFAULT_QUALITY_SONGS = (
    "twinkle-twinkle",
    "c-major-scale-both",
    "c-major-chords",
    "bach-prelude-c-major-bwv846",
    "mozart-sonata-k545-allegro",
    "clara-schumann-polonaise-op1-no1",
)


def _crop(song: Song, seconds: float | None) -> Song:
    if seconds is None:
        return song
    notes = tuple(
        Note(n.pitch, n.onset_s, min(n.offset_s, seconds), n.velocity, n.finger, n.hand)
        for n in song.notes
        if n.onset_s < seconds - 0.05
    )
    return Song(notes, name=song.name)


def speed(repeats: int) -> list[dict]:
    rows = []
    for name in list_songs(OPEN_SUITE):
        song = load_song(name)
        for label, bare in (
            ("fingers", strip_fingering(song, keep_hands=True)),
            ("hands+fingers", strip_fingering(song)),
        ):
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                assign_fingering(bare)
                times.append(time.perf_counter() - start)
            median = statistics.median(times)
            rows.append(
                {
                    "song": name,
                    "estimated": label,
                    "notes": song.num_notes,
                    "median_s": median,
                    "notes_per_s": song.num_notes / median,
                }
            )
    return rows


def pianoplayer_fingering(song: Song) -> tuple[Song, float] | None:
    """(fingered song, fraction of notes pianoplayer fingered), or None if unavailable."""
    try:
        from pianoplayer.hand import Hand
        from pianoplayer.models import keypos_midi
        from pianoplayer.scorereader import reader_PIG
    except ImportError:
        return None
    import logging

    logging.getLogger("pianoplayer").setLevel(logging.ERROR)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "song.txt"
        # PIG rows with channel 0 = right, 1 = left and finger 0 (unlabelled).
        rows = [
            f"{i}\t{n.onset_s:.6f}\t{n.offset_s:.6f}\t{pitch_to_name(n.pitch)}\t{n.velocity}\t80"
            f"\t{0 if n.hand == 'right' else 1}\t0"
            for i, n in enumerate(song.notes)
        ]
        path.write_text("//Version: PianoFingering_v170101\n" + "\n".join(rows) + "\n")
        found: dict[tuple[str, int], list[tuple[float, int]]] = {}
        for channel, side in ((0, "right"), (1, "left")):
            noteseq = reader_PIG(str(path), channel)
            if not noteseq:
                continue
            for note in noteseq:
                # pianoplayer 3.0.2's PIG reader leaves every key position at 0 (its score
                # readers set it): without this every note gets the same finger.
                if not note.x:
                    note.x = keypos_midi(note)
            hand = Hand(side=side, noteseq=noteseq, size="M")
            hand.verbose = False
            hand.generate(1, 100000)
            for note in hand.noteseq:
                if note.fingering:
                    found.setdefault((side, int(note.pitch)), []).append(
                        (float(note.time), int(note.fingering))
                    )
    notes = []
    labelled = 0
    for n in song.notes:
        finger = None
        for onset, number in found.get((n.hand or "", n.pitch), []):
            if abs(onset - n.onset_s) < 0.06:  # pianoplayer staggers chord notes slightly
                finger = number - 1 if n.hand == "right" else number + 4
                break
        labelled += finger is not None
        notes.append(Note(n.pitch, n.onset_s, n.offset_s, n.velocity, finger, n.hand))
    filled = assign_fingering(Song(tuple(notes), song.sustain, song.name))
    return filled, labelled / max(1, len(song.notes))


def planner_f1(song: Song, physics: str) -> float:
    from pianist.control import make_controller
    from pianist.eval.session import play

    return float(play(song, make_controller("planner"), physics=physics).metrics["f1"])


def quality(names: list[str], seconds: float | None, physics: str) -> list[dict]:
    rows = []
    for name in names:
        original = _crop(load_song(name), seconds)
        variants: dict[str, Song] = {}
        if name in list_songs():  # debug songs carry human fingering
            variants["human"] = original
        bare = strip_fingering(original, keep_hands=True)
        variants["auto"] = assign_fingering(bare)
        coverage = None
        pp = pianoplayer_fingering(bare)
        if pp is not None:
            variants["pianoplayer"], coverage = pp
        for label, song in variants.items():
            start = time.perf_counter()
            f1 = planner_f1(song, physics)
            row = {
                "song": name,
                "fingering": label,
                "seconds": round(song.duration_s, 2),
                "f1": f1,
                "wall_s": time.perf_counter() - start,
            }
            if label == "pianoplayer":
                row["pianoplayer_coverage"] = coverage
            if label != "human" and "human" in variants:
                human = [n.finger for n in variants["human"].notes]
                row["agrees_with_human"] = sum(
                    a == b for a, b in zip(human, (n.finger for n in song.notes), strict=True)
                ) / len(human)
            rows.append(row)
            print(
                f"  {name:34s} {label:12s} F1 {f1:.3f}"
                + (f"  (pianoplayer fingered {coverage:.0%})" if label == "pianoplayer" else "")
                + (
                    f"  agrees with human {row['agrees_with_human']:.0%}"
                    if "agrees_with_human" in row
                    else ""
                ),
                flush=True,
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--songs", nargs="*", default=list(DEFAULT_QUALITY_SONGS))
    parser.add_argument("--quality", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--seconds", type=float, default=10.0, help="crop for the quality run")
    parser.add_argument("--physics", default="fast", choices=("fast", "faithful"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    rows = speed(args.repeats)
    print(f"{'song':34s} {'estimated':14s} {'notes':>5s} {'ms':>8s} {'notes/s':>8s}")
    for r in rows:
        print(
            f"{r['song']:34s} {r['estimated']:14s} {r['notes']:5d} "
            f"{1000 * r['median_s']:8.1f} {r['notes_per_s']:8.0f}"
        )
    for label in ("fingers", "hands+fingers"):
        picked = [r for r in rows if r["estimated"] == label]
        total = sum(r["notes"] for r in picked) / sum(r["median_s"] for r in picked)
        print(f"overall ({label} estimated): {total:.0f} notes/s")
    result = {"speed": rows}
    if args.quality:
        print(f"planner F1 ({args.physics} physics, first {args.seconds:g} s of each piece):")
        result["quality"] = quality(args.songs, args.seconds, args.physics)
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
