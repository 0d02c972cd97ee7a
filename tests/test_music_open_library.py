"""The shipped open song library (open-etude-12)."""

from __future__ import annotations

from importlib import resources

import pytest

from pianist.music import (
    OPEN_SUITE,
    SUITES,
    check_playability,
    get_song,
    list_songs,
    load_song,
    open_song_info,
    song_description,
    song_stats,
)
from pianist.music.open_library import provenance

NAMES = list_songs(OPEN_SUITE)


def test_suite_lists_twelve_pieces_and_debug_songs_stay_the_default() -> None:
    assert OPEN_SUITE in SUITES
    assert len(NAMES) == 12 and len(set(NAMES)) == 12
    assert not set(NAMES) & set(list_songs())
    assert list_songs("debug") == list_songs()
    with pytest.raises(ValueError, match="unknown suite"):
        list_songs("nope")


@pytest.mark.parametrize("name", NAMES)
def test_piece_is_playable_material(name: str) -> None:
    song = load_song(name)
    assert song == get_song(name) and song.name == name
    assert song.has_full_fingering
    assert song.hands == {"left", "right"}
    assert song.duration_s >= 20.0
    assert song.notes[0].onset_s < 2.0  # the segment starts at (or a rest before) its first note
    info = open_song_info(name)
    for key in ("title", "composer", "composer_dates", "source", "source_licence", "licence"):
        assert info[key]
    segment = info["segment"]
    # The last note ends at the segment's end, or earlier when the segment ends in a rest.
    assert song.duration_s <= segment["end_s"] - segment["start_s"] + 1e-3
    assert info["notes"] == song.num_notes
    # The recorded problems are exactly what the checker finds in the shipped file.
    assert info["problems"] == check_playability(song)
    assert song_description(name).endswith(f"({OPEN_SUITE})")
    assert song_stats(song).max_polyphony >= 2


def test_most_pieces_have_no_playability_problem() -> None:
    clean = [name for name in NAMES if not open_song_info(name)["problems"]]
    assert len(clean) >= 10


def test_provenance_and_size() -> None:
    record = provenance()
    assert record["suite"] == OPEN_SUITE and "music21" in record["built_with"]
    folder = resources.files("pianist.music") / "data" / "open"
    total = sum(entry.stat().st_size for entry in resources.as_file(folder).__enter__().iterdir())
    assert total < 1_000_000
