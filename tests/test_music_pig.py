"""read_pig / write_pig: parsing, finger mapping, errors with line numbers, round trip."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pianist.music import Note, OutOfRangeError, PigFormatError, Song, read_pig, write_pig
from pianist.music.pig import index_to_pig_finger, pig_finger_to_index

SAMPLE = (
    "//Version: PianoFingering_v170101\n"
    "0\t0.000000\t0.500000\tC#4\t64\t80\t0\t1\n"
    "\n"
    "1\t0.250000\t1.000000\tBb2\t70\t80\t1\t-5\n"
    "// a comment in the middle\n"
    "2\t0.500000\t0.750000\tE4\t0\t80\t0\t3_2\n"
    "3 1.0 1.5 Db3 64 80 1 -2_-1\n"  # space separated also works
    "4\t1.5\t1.5\tC4\t64\t80\t0\t1\n"  # zero length: dropped
)


def _write(tmp_path: Path, text: str, name: str = "001-1_fingering.txt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_sample(tmp_path: Path) -> None:
    song = read_pig(_write(tmp_path, SAMPLE))
    assert song.name == "001-1_fingering"
    got = [(n.pitch, n.onset_s, n.offset_s, n.velocity, n.finger, n.hand) for n in song.notes]
    assert got == [
        (61, 0.0, 0.5, 64, 0, "right"),
        (46, 0.25, 1.0, 70, 9, "left"),
        (64, 0.5, 0.75, 1, 2, "right"),  # velocity 0 clipped to 1; "3_2" keeps 3
        (49, 1.0, 1.5, 64, 6, "left"),  # "-2_-1" keeps -2
    ]
    assert song.sustain == () and song.has_full_fingering


def test_finger_mapping() -> None:
    assert [pig_finger_to_index(str(f)) for f in (1, 2, 3, 4, 5)] == [0, 1, 2, 3, 4]
    assert [pig_finger_to_index(str(f)) for f in (-1, -2, -3, -4, -5)] == [5, 6, 7, 8, 9]
    assert pig_finger_to_index("0") is None
    assert [index_to_pig_finger(i) for i in range(10)] == [1, 2, 3, 4, 5, -1, -2, -3, -4, -5]


def test_unlabelled_finger_takes_hand_from_channel(tmp_path: Path) -> None:
    song = read_pig(_write(tmp_path, "0\t0\t1\tC3\t64\t80\t1\t0\n"))
    assert song.notes[0].finger is None and song.notes[0].hand == "left"


@pytest.mark.parametrize(
    ("row", "why"),
    [
        ("0\t0\t1\tC4\t64\t80\t0", "fields"),
        ("0\t0\t1\tC4\t64\t80\t0\t1\textra", "fields"),
        ("0\tzero\t1\tC4\t64\t80\t0\t1", "could not convert"),
        ("0\t1\t0.5\tC4\t64\t80\t0\t1", "bad times"),
        ("0\t-1\t0.5\tC4\t64\t80\t0\t1", "bad times"),
        ("0\t0\tnan\tC4\t64\t80\t0\t1", "bad times"),
        ("0\t0\t1\tH4\t64\t80\t0\t1", "pitch name"),
        ("0\t0\t1\tC4\t64\t80\t2\t1", "channel"),
        ("0\t0\t1\tC4\t64\t80\t0\t6", "finger"),
        ("0\t0\t1\tC4\t64\t80\t0\tx", "invalid literal"),
        ("0\t0\t1e5\tC4\t64\t80\t0\t1", "refusing an absurd length"),  # 2M goal frames
        ("0\t0\t1e300\tC4\t64\t80\t0\t1", "refusing an absurd length"),
    ],
)
def test_bad_rows_name_file_and_line(tmp_path: Path, row: str, why: str) -> None:
    path = _write(tmp_path, "//header\n0\t0\t1\tC4\t64\t80\t0\t1\n\n" + row + "\n")
    with pytest.raises(PigFormatError) as info:
        read_pig(path)
    message = str(info.value)
    assert f"{path}:4:" in message and why in message and "\n" not in message


def test_out_of_range(tmp_path: Path) -> None:
    path = _write(tmp_path, "0\t0\t1\tC4\t64\t80\t0\t1\n1\t0\t1\tC0\t64\t80\t1\t-1\n")
    with pytest.raises(OutOfRangeError, match="1 note"):
        read_pig(path)
    assert [n.pitch for n in read_pig(path, out_of_range="drop").notes] == [60]


@pytest.mark.parametrize("text", ["//only a header\n", "\n\n"])
def test_no_notes(tmp_path: Path, text: str) -> None:
    with pytest.raises(PigFormatError, match="no notes"):
        read_pig(_write(tmp_path, text))


def test_missing_empty_directory(tmp_path: Path) -> None:
    with pytest.raises(PigFormatError, match="not found"):
        read_pig(tmp_path / "missing.txt")
    with pytest.raises(PigFormatError, match="empty"):
        read_pig(_write(tmp_path, ""))
    with pytest.raises(PigFormatError, match="directory"):
        read_pig(tmp_path)
    binary = tmp_path / "bin.txt"
    binary.write_bytes(b"\xff\xfe\x00\x81" * 10)
    with pytest.raises(PigFormatError):
        read_pig(binary)


def test_round_trip(tmp_path: Path) -> None:
    song = Song(
        (
            Note(60, 0.0, 0.5, 64, finger=0),
            Note(61, 0.123456, 0.654321, 99, finger=2),
            Note(36, 0.5, 2.0, 50, finger=9),
            Note(47, 1.0, 1.25, 80, finger=5),
        ),
        name="rt",
    )
    path = tmp_path / "rt.txt"
    write_pig(song, path)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("//")
    assert lines[1].split("\t") == ["0", "0.000000", "0.500000", "C4", "64", "80", "0", "1"]
    back = read_pig(path)
    for a, b in zip(song.notes, back.notes, strict=True):
        assert (a.pitch, a.velocity, a.finger, a.hand) == (b.pitch, b.velocity, b.finger, b.hand)
        assert a.onset_s == pytest.approx(b.onset_s, abs=1e-6)
        assert a.offset_s == pytest.approx(b.offset_s, abs=1e-6)


def test_write_needs_fingers_and_creates_nothing(tmp_path: Path) -> None:
    song = Song((Note(60, 0, 1, finger=0), Note(62, 1, 2)), name="half")
    path = tmp_path / "half.txt"
    with pytest.raises(PigFormatError, match="note 1 .*no finger"):
        write_pig(song, path)
    assert os.listdir(tmp_path) == []
