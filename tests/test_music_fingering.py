"""Automatic hand assignment and fingering, MIDI hand hints, fingering modes, song stats."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mido
import numpy as np
import pytest

from pianist.music import (
    MusicError,
    Note,
    Song,
    assign_fingering,
    assign_hands,
    check_playability,
    describe_midi_hands,
    ensure_fingering,
    get_song,
    load_song,
    midi_hand_hints,
    read_midi,
    song_stats,
    strip_fingering,
)
from pianist.music import fingering as F
from pianist.sim import constants as C


def _fingers(song: Song, hand: str) -> list[int]:
    """Pianist's numbers 1..5 of ``hand``'s notes in time order."""
    return [n.finger % 5 + 1 for n in song.notes if n.hand == hand]


def test_key_geometry_matches_the_simulated_piano() -> None:
    y = C.key_centre_y()
    assert np.allclose(np.array(F.KEY_Y_M), y - y[0])
    assert list(F.KEY_IS_BLACK) == list(C.BLACK_KEY_MASK)


@pytest.mark.parametrize("name", ["c-major-scale-both", "d-major-scale-both"])
def test_scales_get_the_standard_fingering_with_thumb_crossings(name: str) -> None:
    human = get_song(name)
    auto = assign_fingering(strip_fingering(human))
    assert auto.has_full_fingering
    assert [n.hand for n in auto.notes] == [n.hand for n in human.notes]
    assert _fingers(auto, "right") == [1, 2, 3, 1, 2, 3, 4, 5, 4, 3, 2, 1, 3, 2, 1]
    assert _fingers(auto, "left") == [5, 4, 3, 2, 1, 3, 2, 1, 2, 3, 1, 2, 3, 4, 5]
    assert check_playability(auto) == []


def test_deterministic() -> None:
    song = strip_fingering(get_song("c-major-chords"))
    assert assign_fingering(song) == assign_fingering(song)


def test_keeps_human_fingers_and_fills_the_rest() -> None:
    human = get_song("twinkle-twinkle")
    partial = Song(
        tuple(
            n if i % 2 == 0 else dataclasses.replace(n, finger=None, hand="right")
            for i, n in enumerate(human.notes)
        ),
        name="partial",
    )
    auto = assign_fingering(partial)
    assert auto.has_full_fingering
    for i, (before, after) in enumerate(zip(human.notes, auto.notes, strict=True)):
        if i % 2 == 0:
            assert after.finger == before.finger
    # keep_existing=False re-estimates (hands are kept).
    redone = assign_fingering(human, keep_existing=False)
    assert redone.has_full_fingering and redone.hands == {"right"}


def test_chords_within_the_hand_and_fingers_in_pitch_order() -> None:
    notes = []
    for t, chord in enumerate([(60, 64, 67), (60, 64, 67, 72), (62, 65, 69), (59, 62, 67)]):
        notes += [Note(p, float(t), t + 1.0, hand="right") for p in chord]
    auto = assign_fingering(Song(tuple(notes)))
    for t in range(4):
        chord = sorted((n for n in auto.notes if n.onset_s == t), key=lambda n: n.pitch)
        fingers = [n.finger for n in chord]
        assert fingers == sorted(set(fingers))  # distinct, thumb lowest
    octave = [n.finger for n in auto.notes if n.onset_s == 1.0]
    assert octave[0] == 0 and octave[-1] == 4  # an octave takes thumb and little finger
    assert check_playability(auto) == []


def test_left_hand_chord_little_finger_lowest() -> None:
    notes = [Note(p, 0.0, 1.0, hand="left") for p in (36, 43, 48)]
    auto = assign_fingering(Song(tuple(notes)))
    assert [n.finger for n in auto.notes] == [9, 6, 5]  # 5 on C2, 2 on G2, 1 on C3


def test_hand_split_keeps_each_hand_within_reach() -> None:
    # A wide chord and a passage with no hands at all: the split must make them playable.
    notes = [Note(p, 0.0, 1.0) for p in (36, 48, 64, 67, 72)]
    notes += [Note(p, 1.0 + 0.25 * i, 1.25 + 0.25 * i) for i, p in enumerate(range(72, 84, 2))]
    notes += [Note(p, 1.0, 2.5) for p in (41, 48)]
    auto = assign_fingering(Song(tuple(notes)))
    assert auto.has_full_fingering and auto.hands == {"left", "right"}
    assert check_playability(auto) == []
    first = {n.pitch: n.hand for n in auto.notes if n.onset_s == 0.0}
    assert first[36] == "left" and first[72] == "right"
    assert song_stats(auto).max_hand_span <= 14  # no hand beyond an octave and a tone


def test_more_than_ten_keys_still_get_a_finger_each() -> None:
    song = Song(tuple(Note(p, 0.0, 1.0) for p in range(48, 72, 2)))
    auto = assign_fingering(song)
    assert auto.has_full_fingering
    assert check_playability(auto)  # and the problem is reported


def test_hints_decide_hands_of_unlabelled_notes() -> None:
    song = Song((Note(60, 0.0, 1.0), Note(62, 1.0, 2.0)))
    auto = assign_fingering(song, hands=["left", None])
    assert auto.notes[0].hand == "left" and auto.notes[0].finger >= 5
    with pytest.raises(MusicError, match="hand hints"):
        assign_hands(song, ["left"])
    with pytest.raises(MusicError, match="hand hint"):
        assign_hands(song, ["up", None])


def test_ensure_fingering_modes() -> None:
    bare = strip_fingering(get_song("twinkle-twinkle"))
    assert ensure_fingering(bare, "none") is bare
    with pytest.raises(MusicError, match="no finger"):
        ensure_fingering(bare, "file")
    assert ensure_fingering(bare, "auto").has_full_fingering
    human = get_song("twinkle-twinkle")
    assert ensure_fingering(human, "auto") == human
    with pytest.raises(MusicError, match="unknown fingering mode"):
        ensure_fingering(bare, "magic")  # type: ignore[arg-type]


def test_empty_song() -> None:
    assert assign_fingering(Song(())) == Song(())


def _two_track_midi(path: Path, names: tuple[str, str]) -> None:
    """Track 1 plays high notes, track 2 low notes, except one crossing note at 1 s."""
    midi = mido.MidiFile(type=1, ticks_per_beat=480)
    midi.tracks.append(mido.MidiTrack([mido.MetaMessage("set_tempo", tempo=500_000)]))
    for name, pitches in zip(names, ((72, 74, 76, 60), (48, 50, 52, 62)), strict=True):
        track = mido.MidiTrack([mido.MetaMessage("track_name", name=name)])
        for pitch in pitches:  # one note per beat (0.5 s)
            track.append(mido.Message("note_on", note=pitch, velocity=80, time=0))
            track.append(mido.Message("note_off", note=pitch, velocity=0, time=480))
        midi.tracks.append(track)
    midi.save(path)


def test_midi_tracks_named_for_hands(tmp_path: Path) -> None:
    path = tmp_path / "hands.mid"
    _two_track_midi(path, ("Piano RH", "Piano LH"))
    song = read_midi(path)
    hints = midi_hand_hints(path, song)
    by_pitch = dict(zip((n.pitch for n in song.notes), hints, strict=True))
    assert by_pitch[60] == "right" and by_pitch[62] == "left"  # crossed hands kept
    loaded = load_song(path, fingering="auto")
    assert loaded.has_full_fingering
    assert {n.pitch: n.hand for n in loaded.notes} == by_pitch
    with pytest.raises(MusicError, match="no finger"):
        load_song(path, fingering="file")
    assert load_song(path, fingering="none").fingering_coverage == 0.0


def test_a_drum_track_is_neither_a_hand_nor_notes(tmp_path: Path) -> None:
    # Two unnamed tracks a register apart are the hands; a third, of drums on the General
    # MIDI percussion channel, would otherwise make three groups and no hands at all.
    path = tmp_path / "band.mid"
    _two_track_midi(path, ("Piano", "Piano"))
    midi = mido.MidiFile(path)
    drums = mido.MidiTrack([mido.MetaMessage("track_name", name="Drums")])
    for _ in range(8):  # a kick drum every half beat
        drums.append(mido.Message("note_on", note=36, velocity=100, channel=9, time=0))
        drums.append(mido.Message("note_off", note=36, velocity=0, channel=9, time=240))
    midi.tracks.append(drums)
    midi.save(path)
    song = read_midi(path)
    assert sorted(n.pitch for n in song.notes) == [48, 50, 52, 60, 62, 72, 74, 76]
    hints = midi_hand_hints(path, song)
    assert hints is not None
    by_pitch = dict(zip((n.pitch for n in song.notes), hints, strict=True))
    assert by_pitch[72] == by_pitch[60] == "right" and by_pitch[48] == by_pitch[62] == "left"


@pytest.mark.parametrize(
    ("right", "left"),
    [
        ("Right Hand", "Left Hand"),
        ("RH", "LH"),
        ("Piano right", "Piano left"),
        ("Treble", "Bass"),
        ("R.H.", "L.H."),
        ("RightHand", "LeftHand"),
        ("Piano_RH", "Piano_LH"),
        ("PianoRH", "PianoLH"),
        ("rechte Hand", "linke Hand"),
        ("Piano RH", "Piano"),  # one named: the other is the other hand
        ("Piano", "LH"),
    ],
)
def test_midi_hand_names_are_recognised(tmp_path: Path, right: str, left: str) -> None:
    # The right-hand name is on the low track: the hands come from the names, not the register.
    path = tmp_path / "named.mid"
    _two_track_midi(path, (left, right))
    hints = midi_hand_hints(path, read_midi(path))
    assert hints is not None
    by_pitch = dict(zip((n.pitch for n in read_midi(path).notes), hints, strict=True))
    assert by_pitch[72] == "left" and by_pitch[48] == "right"
    assert (describe_midi_hands(path) or "").startswith("by track name: ")


def test_midi_hand_from_instrument_name(tmp_path: Path) -> None:
    path = tmp_path / "instrument.mid"
    midi = mido.MidiFile(type=1, ticks_per_beat=480)
    for name, pitch in (("Right Hand", 48), ("Left Hand", 72)):
        midi.tracks.append(
            mido.MidiTrack(
                [
                    mido.MetaMessage("track_name", name="Piano"),
                    mido.MetaMessage("instrument_name", name=name),
                    mido.Message("note_on", note=pitch, velocity=80, time=0),
                    mido.Message("note_off", note=pitch, velocity=0, time=480),
                ]
            )
        )
    midi.save(path)
    assert midi_hand_hints(path, read_midi(path)) == ("right", "left")


def test_midi_unnamed_tracks_by_register_and_single_track(tmp_path: Path) -> None:
    path = tmp_path / "parts.mid"
    _two_track_midi(path, ("one", "two"))
    hints = midi_hand_hints(path, read_midi(path))
    assert hints is not None and set(hints) == {"left", "right"}
    assert describe_midi_hands(path) == "by register: 'one' right, 'two' left"
    single = tmp_path / "single.mid"
    from pianist.music import write_midi

    write_midi(get_song("c-major-chords"), single)
    assert midi_hand_hints(single, read_midi(single)) is None
    assert describe_midi_hands(single) is None


def test_song_stats() -> None:
    stats = song_stats(get_song("c-major-chords"))
    assert stats.num_notes == 16 and stats.duration_s == pytest.approx(4.0)
    assert stats.notes_per_second == pytest.approx(4.0)
    assert stats.peak_notes_per_second == 4
    assert stats.max_polyphony == 4
    assert stats.max_hand_span == 9  # C4..A4 in the IV chord
    assert stats.hands == ("left", "right")
    assert song_stats(strip_fingering(get_song("twinkle-twinkle"))).max_hand_span is None
    assert song_stats(Song(())).notes_per_second == 0.0


@pytest.mark.parametrize(
    "pitches",
    [
        (63, 67, 70, 75),  # E-flat arpeggio
        (66, 68, 70, 71, 73, 75, 77, 78),  # F# major up an octave from F#4
    ],
)
def test_the_thumb_is_kept_off_black_keys(pitches):
    # The robot's thumb cannot press a black key (a human's would start both on the thumb).
    song = assign_fingering(
        Song(tuple(Note(p, 0.25 * i, 0.25 * i + 0.25) for i, p in enumerate(pitches)))
    )
    on_black = [n.pitch for n in song.notes if n.finger == 0 and F.KEY_IS_BLACK[n.pitch - 21]]
    assert on_black == [], [(n.pitch, n.finger) for n in song.notes]


def test_robot_fingering_refingers_a_human_thumb_off_black_keys():
    # A human fingering (thumb on E-flat) for the right hand, and a left-hand bass note.
    right = [
        Note(p, 0.25 * i, 0.25 * i + 0.25, finger=f)
        for i, (p, f) in enumerate([(63, 0), (67, 1), (70, 2), (75, 4)])
    ]
    song = Song(tuple(right) + (Note(39, 0.0, 1.0, finger=9),))
    assert ensure_fingering(song, "auto") == song  # the file's own fingers are kept
    robot = ensure_fingering(song, "robot")
    assert [n.hand for n in robot.notes] == [n.hand for n in song.notes]
    assert not [n for n in robot.notes if n.finger == 0 and F.KEY_IS_BLACK[n.pitch - 21]]
    assert load_song(song, fingering="robot") == robot
