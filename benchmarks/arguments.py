"""Arguments the benchmarks share, checked before anything runs: a typo at the end of a long
list must not cost the results before it (the scripts write their JSON only at the end)."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from typing import Any

PRESETS = ("faithful", "fast")


def song_list(parser: argparse.ArgumentParser, songs: str | None, suite: str | None) -> list[str]:
    """The comma-separated ``songs``, else ``suite``'s, each loaded once to check it; a bad
    one ends the script with ``parser.error`` (one line, exit status 2)."""
    from pianist.music import MusicError, list_songs, load_song

    try:
        names = songs.split(",") if songs else list_songs(suite)
        for name in names:
            load_song(name)
    except (MusicError, ValueError) as exc:
        parser.error(" ".join(str(exc).split()))
    return names


def preset_list(parser: argparse.ArgumentParser, presets: str) -> list[str]:
    """The comma-separated physics ``presets``, each one of :data:`PRESETS`."""
    names = presets.split(",")
    unknown = [name for name in names if name not in PRESETS]
    if unknown:
        parser.error(f"unknown physics preset(s) {unknown}; choose from {list(PRESETS)}")
    return names


def song_table(
    names: list[str],
    presets: list[str],
    row: Callable[[str, str], dict[str, float]],
    columns: tuple[str, ...],
    json_path: str | None,
    settings: dict[str, Any],
    width: int = 13,
) -> None:
    """Run ``row(song, preset)`` for every preset and song, print each row's ``columns`` as it
    comes and then each preset's means (NaN cells left out), and write everything (settings,
    means, rows) to ``json_path`` if given."""
    results: dict[str, dict[str, dict[str, float]]] = {preset: {} for preset in presets}
    print(f"{'song':32s} {'preset':8s} " + " ".join(f"{c:>{width}s}" for c in columns))
    for preset in presets:
        for name in names:
            values = results[preset][name] = row(name, preset)
            cells = " ".join(f"{values[c]:{width}.3f}" for c in columns)
            print(f"{name[:32]:32s} {preset:8s} {cells}", flush=True)
    means = {
        preset: {c: _mean([r[c] for r in rows.values()]) for c in columns}
        for preset, rows in results.items()
    }
    for preset, mean in means.items():
        print(f"{'mean':32s} {preset:8s} " + " ".join(f"{mean[c]:{width}.3f}" for c in columns))
    if json_path:
        with open(json_path, "w") as f:
            json.dump({"settings": settings, "mean": means, "songs": results}, f, indent=1)


def _mean(values: list[float]) -> float:
    """The mean of the values that are numbers (NaN when none is)."""
    kept = [v for v in values if not math.isnan(v)]
    return sum(kept) / len(kept) if kept else float("nan")
