"""Arguments the benchmarks share, checked before anything runs: a typo at the end of a long
list must not cost the results before it (the scripts write their JSON only at the end)."""

from __future__ import annotations

import argparse

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
