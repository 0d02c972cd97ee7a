"""read_midi / write_midi on MIDI files built in code, including every error case."""

from __future__ import annotations

import os
import random
import struct
from pathlib import Path

import mido
import pytest

from pianist.music import MidiFileError, Note, OutOfRangeError, Song, read_midi, write_midi
from pianist.music.midi import song_to_midi

TPB = 480


def _track(*events: tuple[int, mido.Message | mido.MetaMessage]) -> mido.MidiTrack:
    """Track from (absolute tick, message) pairs, converted to delta times."""
    track = mido.MidiTrack()
    last = 0
    for tick, msg in sorted(events, key=lambda e: e[0]):
        track.append(msg.copy(time=tick - last))
        last = tick
    return track


def _on(note: int, velocity: int = 64, channel: int = 0) -> mido.Message:
    return mido.Message("note_on", note=note, velocity=velocity, channel=channel)


def _off(note: int, channel: int = 0) -> mido.Message:
    return mido.Message("note_off", note=note, velocity=0, channel=channel)


def _cc64(value: int, channel: int = 0) -> mido.Message:
    return mido.Message("control_change", control=64, value=value, channel=channel)


def _save(path: Path, *tracks: mido.MidiTrack, midi_type: int = 1) -> Path:
    midi = mido.MidiFile(type=midi_type, ticks_per_beat=TPB)
    midi.tracks.extend(tracks)
    midi.save(path)
    return path


def _spans(song: Song) -> list[tuple[int, float, float]]:
    return [(n.pitch, round(n.onset_s, 9), round(n.offset_s, 9)) for n in song.notes]


def test_format0_default_tempo(tmp_path: Path) -> None:
    path = _save(
        tmp_path / "f0.mid",
        _track((0, _on(60, 90)), (480, _off(60)), (480, _on(62)), (720, _on(62, 0))),
        midi_type=0,
    )
    song = read_midi(path)
    # 120 BPM default: 480 ticks = 0.5 s; note_on velocity 0 ends D4.
    assert _spans(song) == [(60, 0.0, 0.5), (62, 0.5, 0.75)]
    assert song.notes[0].velocity == 90
    assert song.name == "f0"
    assert all(n.hand is None and n.finger is None for n in song.notes)


def test_format1_tempo_change_across_tracks(tmp_path: Path) -> None:
    tempo_track = _track(
        (0, mido.MetaMessage("set_tempo", tempo=500_000)),
        (960, mido.MetaMessage("set_tempo", tempo=1_000_000)),  # 60 BPM from 1.0 s on
    )
    right = _track((0, _on(72)), (960, _off(72)), (960, _on(74)), (1440, _off(74)))
    left = _track((1200, _on(48, channel=1)), (1920, _off(48, channel=1)))
    song = read_midi(_save(tmp_path / "f1.mid", tempo_track, right, left))
    # Before tick 960: 0.5 s per beat -> 1.0 s; after: 1.0 s per beat of 480 ticks.
    # 74: 1.0 .. 1.0 + 480/480 = 2.0; 48: 1.0 + 240/480 = 1.5 .. 1.0 + 960/480 = 3.0.
    assert _spans(song) == [(72, 0.0, 1.0), (74, 1.0, 2.0), (48, 1.5, 3.0)]
    assert song.duration_s == pytest.approx(3.0)


def test_running_status_raw_bytes(tmp_path: Path) -> None:
    track = bytes(
        [
            0x00,
            0x90,
            60,
            64,  # note-on C4
            0x83,
            0x60,
            60,
            0,  # running status: note-on velocity 0 after 480 ticks
            0x00,
            62,
            80,  # running status: note-on D4
            0x83,
            0x60,
            62,
            0,
            0x00,
            0xFF,
            0x2F,
            0x00,
        ]
    )
    data = (
        b"MThd"
        + struct.pack(">LHHH", 6, 0, 1, TPB)
        + b"MTrk"
        + struct.pack(">L", len(track))
        + track
    )
    path = tmp_path / "running.mid"
    path.write_bytes(data)
    song = read_midi(path)
    assert _spans(song) == [(60, 0.0, 0.5), (62, 0.5, 1.0)]
    assert song.notes[1].velocity == 80


def test_overlapping_same_pitch_fifo(tmp_path: Path) -> None:
    # on@0, on@480 (re-strike cuts the first), off@960 (closes the first, already cut),
    # off@1440 closes the second.
    track = _track((0, _on(60)), (480, _on(60)), (960, _off(60)), (1440, _off(60)))
    song = read_midi(_save(tmp_path / "overlap.mid", track, midi_type=0))
    assert _spans(song) == [(60, 0.0, 0.5), (60, 0.5, 1.5)]


def test_a_zero_length_note_written_note_off_first_is_dropped(tmp_path: Path) -> None:
    # As music21 writes a grace note: at tick 960 the note-off comes before its note-on. Read
    # in order, that note-on would wait for the note-off at 1920, a note of another voice.
    track = mido.MidiTrack(
        [
            _on(60).copy(time=0),
            _off(60).copy(time=480),
            _off(60).copy(time=480),
            _on(60).copy(time=0),
            _on(60).copy(time=480),
            _off(60).copy(time=480),
        ]
    )
    song = read_midi(_save(tmp_path / "grace.mid", track, midi_type=0))
    assert _spans(song) == [(60, 0.0, 0.5), (60, 1.5, 2.0)]
    # A stray note-off at another tick, or on another channel, leaves a note-on alone.
    track = _track(
        (0, _off(60)),
        (240, _on(60)),
        (480, _off(60)),
        (720, _off(60, channel=1)),
        (720, _on(60, channel=2)),
        (960, _off(60, channel=2)),
    )
    song = read_midi(_save(tmp_path / "stray.mid", track, midi_type=0))
    assert _spans(song) == [(60, 0.25, 0.5), (60, 0.75, 1.0)]


def test_restrike_with_note_on_before_note_off_at_same_tick(tmp_path: Path) -> None:
    track = mido.MidiTrack(
        [
            _on(60).copy(time=0),
            _on(60).copy(time=480),
            _off(60).copy(time=0),
            _off(60).copy(time=480),
        ]
    )
    song = read_midi(_save(tmp_path / "order.mid", track, midi_type=0))
    assert _spans(song) == [(60, 0.0, 0.5), (60, 0.5, 1.0)]


def test_same_pitch_on_two_channels(tmp_path: Path) -> None:
    a = _track((0, _on(60, channel=0)), (960, _off(60, channel=0)))
    b = _track((480, _on(60, channel=1)), (1440, _off(60, channel=1)))
    song = read_midi(_save(tmp_path / "two.mid", a, b))
    assert _spans(song) == [(60, 0.0, 0.5), (60, 0.5, 1.5)]


def test_drum_hits_on_the_percussion_channel_are_left_out(tmp_path: Path) -> None:
    # General MIDI plays drums on channel 10 (9 from 0): note 38 there is a snare, not a D2.
    piano = _track((0, _on(60)), (480, _off(60)))
    drums = _track(
        (0, _on(36, channel=9)),
        (120, _off(36, channel=9)),
        (240, _on(38, channel=9)),
        (1920, _off(38, channel=9)),
    )
    song = read_midi(_save(tmp_path / "band.mid", piano, drums))
    assert _spans(song) == [(60, 0.0, 0.5)]
    only = _save(tmp_path / "drums.mid", drums)
    message = _error_message(only)
    assert "no notes" in message and "2 drum hit(s)" in message and "channel 10" in message


def test_open_note_closes_at_end_and_zero_length_dropped(tmp_path: Path) -> None:
    track = _track(
        (0, _on(60)),
        (240, _on(64)),
        (240, _off(64)),  # zero length: dropped
        (960, mido.MetaMessage("end_of_track")),
    )
    song = read_midi(_save(tmp_path / "open.mid", track, midi_type=0))
    assert _spans(song) == [(60, 0.0, 1.0)]


def test_sustain_cc64_any_channel(tmp_path: Path) -> None:
    notes = _track((0, _on(60)), (480, _off(60)))
    pedal = _track(
        (0, _cc64(100, channel=3)),
        (100, _cc64(127, channel=3)),  # still down: no new interval
        (960, _cc64(63, channel=3)),  # < 64 is up
        (1200, _cc64(10, channel=3)),  # already up: ignored
        (1440, _cc64(64, channel=3)),  # exactly 64 is down, never released
        (1920, mido.MetaMessage("end_of_track")),
    )
    song = read_midi(_save(tmp_path / "pedal.mid", notes, pedal))
    assert song.sustain == ((0.0, 1.0), (1.5, 2.0))
    assert song.duration_s == pytest.approx(2.0)


def test_out_of_range_error_and_drop(tmp_path: Path) -> None:
    track = _track(
        (0, _on(12)),
        (0, _on(60)),
        (0, _on(110)),
        (480, _off(12)),
        (480, _off(60)),
        (480, _off(110)),
    )
    path = _save(tmp_path / "range.mid", track, midi_type=0)
    with pytest.raises(OutOfRangeError) as info:
        read_midi(path)
    message = str(info.value)
    assert "range.mid" in message and "2 note(s)" in message and "12..110" in message
    assert "\n" not in message
    assert _spans(read_midi(path, out_of_range="drop")) == [(60, 0.0, 0.5)]
    with pytest.raises(ValueError):
        read_midi(path, out_of_range="clip")  # type: ignore[arg-type]


def test_only_out_of_range_notes_dropped_means_no_notes(tmp_path: Path) -> None:
    path = _save(tmp_path / "low.mid", _track((0, _on(10)), (480, _off(10))), midi_type=0)
    with pytest.raises(MidiFileError, match="no notes in the piano's range"):
        read_midi(path, out_of_range="drop")


def _valid_file(tmp_path: Path) -> Path:
    track = _track(
        *[(i * 240, _on(60 + i)) for i in range(20)],
        *[(i * 240 + 200, _off(60 + i)) for i in range(20)],
    )
    return _save(tmp_path / "valid.mid", track, midi_type=0)


def _error_message(path: Path) -> str:
    with pytest.raises(MidiFileError) as info:
        read_midi(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    return message


def test_missing_file(tmp_path: Path) -> None:
    assert "not found" in _error_message(tmp_path / "nope.mid")


def test_directory(tmp_path: Path) -> None:
    folder = tmp_path / "dir.mid"
    folder.mkdir()
    assert "directory" in _error_message(folder)


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.mid"
    path.write_bytes(b"")
    assert "empty" in _error_message(path)


@pytest.mark.parametrize("keep", [0.5, 0.9, 14 / 1000])
def test_truncated_file(tmp_path: Path, keep: float) -> None:
    path = _valid_file(tmp_path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mid"
    cut.write_bytes(data[: max(4, int(len(data) * keep))])
    assert "truncated" in _error_message(cut)


def test_random_bytes(tmp_path: Path) -> None:
    path = tmp_path / "noise.mid"
    path.write_bytes(random.Random(0).randbytes(500))
    assert "not a MIDI file" in _error_message(path)


def test_text_file_renamed(tmp_path: Path) -> None:
    path = tmp_path / "notes.mid"
    path.write_text("C4 D4 E4\nthis is not MIDI\n")
    assert "not a MIDI file" in _error_message(path)


def test_corrupt_track_data(tmp_path: Path) -> None:
    track = bytes([0x00, 60, 64, 0x00, 0xFF, 0x2F, 0x00])  # running status with no status yet
    data = (
        b"MThd"
        + struct.pack(">LHHH", 6, 0, 1, TPB)
        + b"MTrk"
        + struct.pack(">L", len(track))
        + track
    )
    path = tmp_path / "corrupt.mid"
    path.write_bytes(data)
    assert "corrupt" in _error_message(path)


def test_zero_ticks_per_beat_is_a_damaged_header_not_smpte(tmp_path: Path) -> None:
    track = bytes([0x00, 0x90, 60, 64, 0x60, 0x80, 60, 0, 0x00, 0xFF, 0x2F, 0x00])
    header = b"MThd" + struct.pack(">LHHH", 6, 0, 1, 0)
    path = tmp_path / "tpb0.mid"
    path.write_bytes(header + b"MTrk" + struct.pack(">L", len(track)) + track)
    message = _error_message(path)
    assert "0 ticks per beat" in message and "SMPTE" not in message


def test_no_notes(tmp_path: Path) -> None:
    track = _track((0, mido.MetaMessage("set_tempo", tempo=500_000)), (480, _cc64(127)))
    path = _save(tmp_path / "silent.mid", track, midi_type=0)
    assert "no notes" in _error_message(path)


@pytest.mark.parametrize("tempo", [10_000, 59_000])  # 6000 and ~1017 BPM
def test_absurd_tempo(tmp_path: Path, tempo: int) -> None:
    track = _track((0, mido.MetaMessage("set_tempo", tempo=tempo)), (0, _on(60)), (480, _off(60)))
    path = _save(tmp_path / "fast.mid", track, midi_type=0)
    assert "absurd tempo" in _error_message(path)


def test_extreme_but_valid_tempo(tmp_path: Path) -> None:
    track = _track((0, mido.MetaMessage("set_tempo", tempo=60_000)), (0, _on(60)), (480, _off(60)))
    song = read_midi(_save(tmp_path / "ok.mid", track, midi_type=0))  # exactly 1000 BPM
    assert song.notes[0].offset_s == pytest.approx(0.06)


def test_absurd_length(tmp_path: Path) -> None:
    # 4 million ticks at 120 BPM, 480 tpb = 4167 s > 1 hour.
    track = _track((0, _on(60)), (4_000_000, _off(60)))
    path = _save(tmp_path / "long.mid", track, midi_type=0)
    assert "hour" in _error_message(path)


def test_format2_refused(tmp_path: Path) -> None:
    path = _save(tmp_path / "f2.mid", _track((0, _on(60)), (480, _off(60))), midi_type=2)
    assert "format 2" in _error_message(path)


def _example_song() -> Song:
    rng = random.Random(1)
    notes = []
    for i in range(40):
        onset = i * 0.173 + rng.random() * 0.05
        notes.append(
            Note(
                rng.randint(21, 108),
                onset,
                onset + 0.05 + rng.random(),
                velocity=rng.randint(1, 127),
            )
        )
    # A re-struck key: the first note ends exactly where the second starts.
    notes += [Note(60, 8.0, 8.25, 70), Note(60, 8.25, 8.5, 71), Note(61, 9.0, 9.0001)]
    # Drop accidental same-pitch overlaps so the song is representable exactly in MIDI.
    kept: dict[int, float] = {}
    clean = []
    for note in sorted(notes, key=lambda n: n.onset_s):
        if note.onset_s >= kept.get(note.pitch, -1.0):
            clean.append(note)
            kept[note.pitch] = note.offset_s
    return Song(tuple(clean), sustain=[(0.3, 1.7), (2.0, 4.123)], name="example")


@pytest.mark.parametrize("midi_type", [0, 1])
def test_round_trip_within_one_tick(tmp_path: Path, midi_type: int) -> None:
    song = _example_song()
    path = tmp_path / "rt.mid"
    write_midi(song, path, midi_type=midi_type)
    assert mido.MidiFile(path).type == midi_type
    back = read_midi(path)
    tick = 1 / 960
    assert back.num_notes == song.num_notes
    for a, b in zip(song.notes, back.notes, strict=True):
        assert (a.pitch, a.velocity) == (b.pitch, b.velocity)
        assert abs(a.onset_s - b.onset_s) <= tick / 2 + 1e-9
        # A sub-tick note is stretched to one tick, so allow a full tick on offsets.
        assert abs(a.offset_s - b.offset_s) <= tick + 1e-9
    assert len(back.sustain) == len(song.sustain)
    for (s0, e0), (s1, e1) in zip(song.sustain, back.sustain, strict=True):
        assert abs(s0 - s1) <= tick and abs(e0 - e1) <= tick


def test_write_layout_and_atomic_overwrite(tmp_path: Path) -> None:
    song = Song((Note(60, 0, 0.5, finger=0),), name="one")
    midi = song_to_midi(song)
    assert midi.ticks_per_beat == 480 and len(midi.tracks) == 2
    assert any(m.type == "set_tempo" and m.tempo == 500_000 for m in midi.tracks[0])
    path = tmp_path / "out.mid"
    path.write_bytes(b"old contents")
    write_midi(song, path)
    assert read_midi(path).notes[0].offset_s == pytest.approx(0.5)
    assert sorted(os.listdir(tmp_path)) == ["out.mid"]  # no temporary file left behind
    with pytest.raises(ValueError):
        song_to_midi(song, midi_type=2)


def test_write_into_missing_directory(tmp_path: Path) -> None:
    with pytest.raises(MidiFileError, match="cannot write"):
        write_midi(Song((Note(60, 0, 1),)), tmp_path / "no" / "such" / "dir.mid")
