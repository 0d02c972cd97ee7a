"""Note and Song model: validation, derived hand, sorting, sustain merging, properties."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pianist.music import MusicError, Note, OutOfRangeError, Song
from pianist.music.pitch import name_to_pitch, pitch_to_name


def test_note_defaults_and_key() -> None:
    note = Note(60, 0.0, 0.5)
    assert note.velocity == 80
    assert note.finger is None and note.hand is None
    assert note.key == 39
    assert Note(21, 0, 1).key == 0 and Note(108, 0, 1).key == 87
    assert note.duration_s == pytest.approx(0.5)


@pytest.mark.parametrize(("finger", "hand"), [(0, "right"), (4, "right"), (5, "left"), (9, "left")])
def test_hand_derived_from_finger(finger: int, hand: str) -> None:
    assert Note(60, 0, 1, finger=finger).hand == hand
    assert Note(60, 0, 1, finger=finger, hand=hand).hand == hand


def test_hand_without_finger_is_kept() -> None:
    assert Note(60, 0, 1, hand="left").hand == "left"


@pytest.mark.parametrize("pitch", [20, 109, 0, 127])
def test_out_of_range_pitch(pitch: int) -> None:
    with pytest.raises(OutOfRangeError, match=str(pitch)):
        Note(pitch, 0, 1)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"onset_s": -0.1},
        {"offset_s": 0.0},
        {"onset_s": 1.0, "offset_s": 0.5},
        {"offset_s": float("inf")},
        {"onset_s": float("nan")},
        {"velocity": 0},
        {"velocity": 128},
        {"finger": 10},
        {"finger": -1},
        {"hand": "middle"},
        {"finger": 1, "hand": "left"},
        {"finger": 7, "hand": "right"},
        {"pitch": 60.0},
        {"pitch": True},
    ],
)
def test_invalid_notes(kwargs: dict) -> None:
    fields = {"pitch": 60, "onset_s": 0.0, "offset_s": 1.0} | kwargs
    with pytest.raises(MusicError):
        Note(**fields)


def test_numpy_scalars_normalised() -> None:
    note = Note(np.int64(60), np.float32(0.5), np.float64(1.0), velocity=np.int16(70))
    assert type(note.pitch) is int and type(note.onset_s) is float
    assert note == Note(60, 0.5, 1.0, 70)


def test_note_is_frozen() -> None:
    note = Note(60, 0, 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        note.pitch = 61  # type: ignore[misc]


def test_song_sorts_notes_by_onset_then_pitch() -> None:
    song = Song((Note(64, 1, 2), Note(62, 0, 1), Note(60, 0, 1)))
    assert [(n.onset_s, n.pitch) for n in song.notes] == [(0, 60), (0, 62), (1, 64)]
    assert isinstance(song.notes, tuple)


def test_song_sustain_sorted_and_merged() -> None:
    song = Song((Note(60, 0, 1),), sustain=[(3, 4), (0, 1), (0.5, 2), (2, 2.5), (5, 6)])
    assert song.sustain == ((0.0, 2.5), (3.0, 4.0), (5.0, 6.0))


@pytest.mark.parametrize("bad", [[(1, 1)], [(2, 1)], [(-1, 1)], [(0, float("nan"))], [(1,)]])
def test_song_bad_sustain(bad: list) -> None:
    with pytest.raises(MusicError):
        Song((), sustain=bad)


def test_song_rejects_non_notes() -> None:
    with pytest.raises(MusicError):
        Song(((60, 0, 1),))  # type: ignore[arg-type]


def test_song_properties() -> None:
    song = Song(
        (Note(60, 0, 1, finger=0), Note(48, 0.5, 2, finger=5), Note(64, 1, 1.5)),
        sustain=[(1, 3)],
        name="x",
    )
    assert song.duration_s == 3.0  # the pedal outlasts the notes
    assert song.num_notes == 3
    assert song.hands == {"right", "left"}
    assert song.fingering_coverage == pytest.approx(2 / 3)
    assert not song.has_full_fingering
    full = Song((Note(60, 0, 1, finger=0),))
    assert full.has_full_fingering and full.fingering_coverage == 1.0
    assert full.duration_s == 1.0


def test_empty_song() -> None:
    song = Song(())
    assert song.duration_s == 0.0 and song.num_notes == 0
    assert song.hands == frozenset() and song.fingering_coverage == 0.0
    assert not song.has_full_fingering


def test_song_equality() -> None:
    a = Song((Note(62, 0, 1), Note(60, 0, 1)), name="s")
    b = Song((Note(60, 0, 1), Note(62, 0, 1)), name="s")
    assert a == b


def test_pitch_names_round_trip() -> None:
    for pitch in range(128):
        assert name_to_pitch(pitch_to_name(pitch)) == pitch
    assert pitch_to_name(60) == "C4" and pitch_to_name(61) == "C#4" and pitch_to_name(21) == "A0"
    assert pitch_to_name(108) == "C8" and pitch_to_name(0) == "C-1"


@pytest.mark.parametrize(
    ("name", "pitch"),
    [
        ("C4", 60),
        ("Db4", 61),
        ("C#4", 61),
        ("Bb3", 58),
        ("B#3", 60),
        ("Cb4", 59),
        ("F##4", 67),
        ("Ebb4", 62),
        ("A0", 21),
        ("C8", 108),
        ("C-1", 0),
        ("G9", 127),
        ("c4", 60),
        (" E4 ", 64),
    ],
)
def test_name_to_pitch(name: str, pitch: int) -> None:
    assert name_to_pitch(name) == pitch


@pytest.mark.parametrize("name", ["H4", "C", "4", "C#", "Cx4", "C4.5", "G#9", "Cb-1", ""])
def test_bad_pitch_names(name: str) -> None:
    with pytest.raises(MusicError):
        name_to_pitch(name)


def test_pitch_to_name_range() -> None:
    with pytest.raises(MusicError):
        pitch_to_name(128)
