"""Built-in songs and load_song."""

from __future__ import annotations

from pathlib import Path

import pytest

from pianist.music import (
    MidiFileError,
    MusicError,
    Song,
    UnknownSongError,
    get_song,
    goal_frames,
    list_songs,
    load_song,
    name_to_pitch,
    song_description,
    write_midi,
    write_pig,
)

NAMES = [
    "twinkle-twinkle",
    "c-major-scale-right",
    "c-major-scale-both",
    "d-major-scale-right",
    "d-major-scale-both",
    "c-major-chords",
]
# name: (notes, duration s, hands, goal frames at 20 Hz)
EXPECTED = {
    "twinkle-twinkle": (14, 8.0, {"right"}, 161),
    "c-major-scale-right": (15, 7.5, {"right"}, 151),
    "c-major-scale-both": (30, 7.5, {"right", "left"}, 151),
    "d-major-scale-right": (15, 7.5, {"right"}, 151),
    "d-major-scale-both": (30, 7.5, {"right", "left"}, 151),
    "c-major-chords": (16, 4.0, {"right", "left"}, 81),
}


def test_names_stable() -> None:
    assert list_songs() == NAMES


@pytest.mark.parametrize("name", NAMES)
def test_builtin_song_shape(name: str) -> None:
    song = get_song(name)
    count, duration, hands, frames = EXPECTED[name]
    assert song.name == name
    assert song.num_notes == count
    assert song.duration_s == pytest.approx(duration)
    assert song.hands == hands
    assert song.has_full_fingering and song.fingering_coverage == 1.0
    assert goal_frames(song).num_frames == frames
    for note in song.notes:  # fingers belong to the note's hand
        assert (note.finger < 5) == (note.hand == "right")
    assert song_description(name)
    assert get_song(name) == song  # deterministic


def _line(song: Song, hand: str) -> list[tuple[int, int | None]]:
    return [(n.pitch, n.finger) for n in song.notes if n.hand == hand]


def _pitches(names: str) -> list[int]:
    return [name_to_pitch(n) for n in names.split()]


def test_twinkle_melody() -> None:
    song = get_song("twinkle-twinkle")
    assert [n.pitch for n in song.notes] == _pitches("C4 C4 G4 G4 A4 A4 G4 F4 F4 E4 E4 D4 D4 C4")
    lengths = [round(n.duration_s, 9) for n in song.notes]
    assert lengths == [0.5] * 6 + [1.0] + [0.5] * 6 + [1.0]


def test_c_major_scales() -> None:
    right = _line(get_song("c-major-scale-right"), "right")
    assert [p for p, _ in right] == _pitches("C4 D4 E4 F4 G4 A4 B4 C5 B4 A4 G4 F4 E4 D4 C4")
    assert [f + 1 for _, f in right] == [1, 2, 3, 1, 2, 3, 4, 5, 4, 3, 2, 1, 3, 2, 1]
    both = get_song("c-major-scale-both")
    assert _line(both, "right") == right
    left = _line(both, "left")
    assert [p for p, _ in left] == [p - 12 for p, _ in right]
    assert [f - 4 for _, f in left] == [5, 4, 3, 2, 1, 3, 2, 1, 2, 3, 1, 2, 3, 4, 5]
    onsets = [n.onset_s for n in get_song("c-major-scale-right").notes]
    assert onsets == pytest.approx([0.5 * i for i in range(15)])


def test_d_major_has_f_sharp_and_c_sharp() -> None:
    right = [p for p, _ in _line(get_song("d-major-scale-right"), "right")]
    assert right[:8] == _pitches("D4 E4 F#4 G4 A4 B4 C#5 D5")
    both = get_song("d-major-scale-both")
    assert [p for p, _ in _line(both, "left")][:8] == _pitches("D3 E3 F#3 G3 A3 B3 C#4 D4")


def test_chords_four_notes_per_second() -> None:
    song = get_song("c-major-chords")
    for second in range(4):
        chord = [n for n in song.notes if n.onset_s == second]
        assert len(chord) == 4
        assert all(n.offset_s == second + 1 for n in chord)
        assert sum(n.hand == "left" for n in chord) == 1
    first = sorted(n.pitch for n in song.notes if n.onset_s == 0)
    assert first == _pitches("C3 C4 E4 G4")


ORIGINAL = [
    "TwinkleTwinkleLittleStar",
    "CMajorScaleOneHand",
    "CMajorScaleTwoHands",
    "DMajorScaleOneHand",
    "DMajorScaleTwoHands",
    "CMajorChordProgressionTwoHands",
]


def test_the_original_debug_songs_are_listed_and_shaped_like_ours() -> None:
    assert list_songs("robopianist-debug") == ORIGINAL
    for ours, original in zip(NAMES, ORIGINAL, strict=True):
        song = get_song(original)
        count, duration, hands, frames = EXPECTED[ours]
        assert (song.num_notes, song.hands, goal_frames(song).num_frames) == (count, hands, frames)
        assert song.duration_s == pytest.approx(duration) and song.has_full_fingering
        assert song.name == original and song_description(original)
        # Also by the original's environment id.
        assert load_song(f"RoboPianist-debug-{original}-v0") == song


def _parts(name: str) -> list[tuple[float, int, int]]:
    return sorted((n.onset_s, n.pitch, n.finger) for n in get_song(name).notes)


def test_the_original_debug_songs_have_its_notes_and_fingers() -> None:
    # Written out as the original lists them: MIDI pitch and finger 0-4 right, 5-9 left.
    twinkle = [60, 60, 67, 67, 69, 69, 67, 65, 65, 64, 64, 62, 62, 60]
    fingers = [0, 0, 2, 2, 3, 3, 2, 3, 3, 2, 2, 1, 1, 0]
    assert [(p, f) for _, p, f in _parts("TwinkleTwinkleLittleStar")] == list(
        zip(twinkle, fingers, strict=True)
    )
    steps = [0, 2, 4, 5, 7, 9, 11, 12, 11, 9, 7, 5, 4, 2, 0]
    right = [0, 1, 2, 0, 1, 2, 3, 4, 3, 2, 1, 0, 2, 1, 0]
    left = [9, 8, 7, 6, 5, 7, 6, 5, 6, 7, 5, 6, 7, 8, 9]
    for tonic in (0, 2):
        name = "CMajorScale" if tonic == 0 else "DMajorScale"
        one = [(p, f) for _, p, f in _parts(f"{name}OneHand")]
        assert one == [(72 + tonic + d, f) for d, f in zip(steps, right, strict=True)]
        both = _parts(f"{name}TwoHands")
        assert [(p, f) for _, p, f in both if f >= 5] == [
            (48 + tonic + d, f) for d, f in zip(steps, left, strict=True)
        ]
        assert [(p, f) for _, p, f in both if f < 5] == one
    chords = [
        [(48, 5), (60, 0), (64, 2), (67, 4)],
        [(41, 8), (65, 0), (69, 2), (72, 4)],
        [(43, 7), (67, 0), (71, 2), (74, 4)],
        [(48, 5), (60, 0), (64, 2), (67, 4)],
    ]
    assert _parts("CMajorChordProgressionTwoHands") == [
        (float(second), p, f) for second, chord in enumerate(chords) for p, f in chord
    ]


def test_unknown_song_suggests_close_matches() -> None:
    with pytest.raises(UnknownSongError) as info:
        get_song("twinkle")
    message = str(info.value)
    assert "twinkle-twinkle" in message and "pianist songs" in message and "\n" not in message
    assert isinstance(info.value, LookupError) and isinstance(info.value, ValueError)
    with pytest.raises(UnknownSongError, match="c-major-scale"):
        load_song("c-major-scale")
    with pytest.raises(UnknownSongError):
        song_description("nope")


def test_load_song_dispatch(tmp_path: Path) -> None:
    song = get_song("c-major-chords")
    assert load_song(song) is song
    assert load_song("twinkle-twinkle") == get_song("twinkle-twinkle")
    midi_path = tmp_path / "chords.MID"
    write_midi(song, midi_path)
    from_midi = load_song(midi_path)
    assert from_midi.num_notes == 16 and from_midi.fingering_coverage == 0.0
    pig_path = tmp_path / "chords.txt"
    write_pig(song, pig_path)
    from_pig = load_song(str(pig_path))
    assert [(n.pitch, n.finger) for n in from_pig.notes] == [
        (n.pitch, n.finger) for n in song.notes
    ]


def test_load_song_out_of_range_passed_on(tmp_path: Path) -> None:
    path = tmp_path / "wide.txt"
    path.write_text("0\t0\t1\tC4\t64\t80\t0\t1\n1\t0\t1\tC9\t64\t80\t0\t5\n")
    with pytest.raises(MusicError, match="outside"):
        load_song(path)
    assert load_song(path, out_of_range="drop").num_notes == 1


def test_load_song_missing_path(tmp_path: Path) -> None:
    for missing in (tmp_path / "gone.mid", str(tmp_path / "gone"), "songs/gone", "gone.midi"):
        with pytest.raises(MidiFileError, match="file not found"):
            load_song(missing)


def test_load_song_unsupported_suffix(tmp_path: Path) -> None:
    path = tmp_path / "song.wav"
    path.write_bytes(b"RIFF")
    with pytest.raises(MusicError, match="unsupported"):
        load_song(path)


@pytest.mark.parametrize("reference", ["x", "", "1#2"])
def test_a_malformed_tune_reference_of_an_existing_book_says_so(tmp_path, reference) -> None:
    book = tmp_path / "book.abc"
    book.write_text("X:1\nT:One\nM:4/4\nL:1/4\nK:C\nCDEF|\n")
    with pytest.raises(MusicError, match=rf"BOOK\.abc#X.*not {reference!r}"):
        load_song(f"{book}#{reference}")
    with pytest.raises(MidiFileError, match="file not found"):  # no such book: as before
        load_song(f"{tmp_path / 'none.abc'}#{reference}")


def test_the_octaves_suite_stretches_each_hand_an_octave_or_a_seventh() -> None:
    names = list_songs("octaves")
    assert names == [
        "block-octaves",
        "broken-octaves",
        "stride-bass",
        "octave-chords",
        "seventh-chords",
        "octave-melody",
    ]
    for name in names:
        song = load_song(name)
        assert song.name == name and all(n.finger is not None for n in song.notes)
        assert "(octaves)" in song_description(name)
        # Described note counts are the songs' own.
        assert f"{len(song.notes)} notes" in song_description(name)
        # Every note on a white key: the turned hand plays no black key.
        assert all(n.pitch % 12 in (0, 2, 4, 5, 7, 9, 11) for n in song.notes)
        # Somewhere one hand spans a seventh or more within a quarter of a second.
        widest = 0
        for hand in ("right", "left"):
            notes = [n for n in song.notes if n.hand == hand]
            for n in notes:
                close = [m.pitch for m in notes if abs(m.onset_s - n.onset_s) <= 0.25]
                widest = max(widest, max(close) - min(close))
        assert widest >= 10, name


def test_the_dynamics_suite_marks_loudness() -> None:
    names = list_songs("dynamics")
    assert names == ["crescendo-scale", "accents", "voiced-melody", "soft-melody-loud-bass"]
    songs = {name: load_song(name) for name in names}
    for name, song in songs.items():
        assert all(n.finger is not None for n in song.notes)
        assert "(dynamics)" in song_description(name)
        assert f"{len(song.notes)} notes" in song_description(name)
        velocities = [n.velocity for n in song.notes]
        assert max(velocities) - min(velocities) >= 50, name  # loudness that matters
    # The crescendo rises to the top of the scale and falls back, both hands alike.
    right = [n.velocity for n in songs["crescendo-scale"].notes if n.hand == "right"]
    top = right.index(max(right))
    assert right[: top + 1] == sorted(right[: top + 1]) and right[0] == right[-1] == 30
    assert right[top:] == sorted(right[top:], reverse=True) and max(right) == 110
    # Every third note of the accents is loud; the melody and the bass swap loudness.
    accented = [n.velocity for n in songs["accents"].notes if n.hand == "right"]
    assert accented[::3] == [100] * 6 and set(accented[1::3] + accented[2::3]) == {50}
    for name, melody, bass in (("voiced-melody", 95, 40), ("soft-melody-loud-bass", 40, 105)):
        hands = {(n.hand, n.velocity) for n in songs[name].notes}
        assert hands == {("right", melody), ("left", bass)}, name
