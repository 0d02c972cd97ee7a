"""Song transforms: stretch, transpose, trim_silence, window."""

from __future__ import annotations

import pytest

from pianist.music import Note, OutOfRangeError, Song
from pianist.music.transforms import delay, stretch, transpose, trim_silence, window


def _song() -> Song:
    return Song(
        (
            Note(60, 1.0, 2.0, 70, finger=0),
            Note(64, 1.5, 3.0, finger=2),
            Note(48, 2.0, 4.0, finger=9),
        ),
        sustain=[(0.5, 1.5), (2.5, 5.0)],
        name="t",
    )


def _times(song: Song) -> list[tuple[int, float, float]]:
    return [(n.pitch, round(n.onset_s, 9), round(n.offset_s, 9)) for n in song.notes]


def test_stretch() -> None:
    song = stretch(_song(), 2.0)
    assert _times(song) == [(60, 2.0, 4.0), (64, 3.0, 6.0), (48, 4.0, 8.0)]
    assert song.sustain == ((1.0, 3.0), (5.0, 10.0))
    assert song.notes[0].finger == 0 and song.notes[0].velocity == 70 and song.name == "t"
    assert _times(stretch(_song(), 0.5))[0] == (60, 0.5, 1.0)
    for bad in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError):
            stretch(_song(), bad)


def test_stretch_leaves_input_alone() -> None:
    original = _song()
    stretch(original, 3.0)
    assert original == _song()


def test_transpose() -> None:
    up = transpose(_song(), 12)
    assert [n.pitch for n in up.notes] == [72, 76, 60]
    assert [n.finger for n in up.notes] == [0, 2, 9]
    assert [n.pitch for n in transpose(_song(), -2).notes] == [58, 62, 46]


def test_transpose_out_of_range() -> None:
    with pytest.raises(OutOfRangeError, match=r"\+49.*2 note.*109..113"):
        transpose(_song(), 49)  # 60+49=109 and 64+49=113 leave the piano; 48+49=97 stays
    dropped = transpose(_song(), 49, out_of_range="drop")
    assert [n.pitch for n in dropped.notes] == [97]
    with pytest.raises(OutOfRangeError):
        transpose(_song(), -28)  # 48 - 28 = 20 < 21
    with pytest.raises(ValueError):
        transpose(_song(), 1, out_of_range="wrap")  # type: ignore[arg-type]


def test_trim_silence() -> None:
    song = trim_silence(_song())
    assert _times(song) == [(60, 0.0, 1.0), (64, 0.5, 2.0), (48, 1.0, 3.0)]
    # (0.5, 1.5) -> clipped to start at the first onset; (2.5, 5.0) -> ends at the last offset.
    assert song.sustain == ((0.0, 0.5), (1.5, 3.0))
    assert song.duration_s == 3.0
    empty = Song((), sustain=[(1, 2)])
    assert trim_silence(empty) is empty


def test_window() -> None:
    song = window(_song(), 1.75, 2.5)
    assert _times(song) == [(60, 0.0, 0.25), (64, 0.0, 0.75), (48, 0.25, 0.75)]
    assert song.sustain == ()
    later = window(_song(), 2.75, 10.0)
    assert _times(later) == [(48, 0.0, 1.25), (64, 0.0, 0.25)]  # sorted by (onset, pitch)
    assert later.sustain == ((0.0, 2.25),)
    # A note ending exactly at the window start does not overlap it.
    assert [n.pitch for n in window(_song(), 2.0, 2.5).notes] == [48, 64]
    assert window(_song(), 10.0, 11.0).num_notes == 0
    for start, end in ((1.0, 1.0), (2.0, 1.0), (-1.0, 1.0), (0.0, float("nan"))):
        with pytest.raises(ValueError):
            window(_song(), start, end)


def test_delay_moves_every_note_and_pedal_later() -> None:
    song = Song((Note(60, 0.0, 0.5, finger=0), Note(64, 0.25, 1.0)), sustain=((0.0, 1.0),))
    later = delay(song, 0.5)
    assert [(n.pitch, n.onset_s, n.offset_s, n.finger) for n in later.notes] == [
        (60, 0.5, 1.0, 0),
        (64, 0.75, 1.5, None),
    ]
    assert later.sustain == ((0.5, 1.5),)
    assert later.duration_s == pytest.approx(song.duration_s + 0.5)
    assert delay(song, 0.0) is song
    for bad in (-0.1, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="delay"):
            delay(song, bad)
