"""read_musicxml on scores written out here: hands from staves, the score's fingers, times."""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import pytest

from pianist.cli import main
from pianist.music import MusicError, OutOfRangeError, load_song, musicxml
from pianist.music.musicxml import merge_voices, read_musicxml, read_score


def _note(
    step: str,
    octave: int,
    duration: int,
    *,
    staff: int = 1,
    chord: bool = False,
    tie: str | None = None,
    fingering: str | None = None,
) -> str:
    """One <note> (durations in quarters: a division of 1), its children in the schema's order."""
    notations = ""
    if tie is not None:
        notations += f'<tied type="{tie}"/>'
    if fingering is not None:
        notations += f"<technical><fingering>{fingering}</fingering></technical>"
    return (
        "<note>"
        + ("<chord/>" if chord else "")
        + f"<pitch><step>{step}</step><octave>{octave}</octave></pitch>"
        + f"<duration>{duration}</duration>"
        + (f'<tie type="{tie}"/>' if tie else "")
        + f"<staff>{staff}</staff>"
        + (f"<notations>{notations}</notations>" if notations else "")
        + "</note>"
    )


def _score(measure: str, parts: int = 1, staves: int = 2) -> str:
    """A partwise score of ``parts`` identical parts of one 4/4 measure (``measure``'s notes)."""
    header = '<?xml version="1.0" encoding="UTF-8"?><score-partwise version="3.1"><part-list>'
    header += "".join(
        f'<score-part id="P{i}"><part-name>Piano</part-name></score-part>'
        for i in range(1, parts + 1)
    )
    body = "".join(
        f'<part id="P{i}"><measure number="1"><attributes><divisions>1</divisions>'
        f"<time><beats>4</beats><beat-type>4</beat-type></time><staves>{staves}</staves>"
        "</attributes>"
        '<direction placement="above"><direction-type><metronome><beat-unit>quarter</beat-unit>'
        '<per-minute>60</per-minute></metronome></direction-type><sound tempo="60"/></direction>'
        f"{measure}</measure></part>"
        for i in range(1, parts + 1)
    )
    return header + "</part-list>" + body + "</score-partwise>"


# The right hand: E5 (finger 3); the chord C4 E4 G4 (1 3 5); a grace D5; C5 tied over two
# beats. The left hand: C3 for the whole bar. Quarter = 60: one beat a second.
GRAND_STAFF = (
    _note("E", 5, 1, fingering="3")
    + _note("C", 4, 1, fingering="1")
    + _note("E", 4, 1, chord=True, fingering="3")
    + _note("G", 4, 1, chord=True, fingering="5")
    + "<note><grace/><pitch><step>D</step><octave>5</octave></pitch><staff>1</staff></note>"
    + _note("C", 5, 1, tie="start")
    + _note("C", 5, 1, tie="stop")
    + "<backup><duration>4</duration></backup>"
    + _note("C", 3, 4, staff=2)
)


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_a_grand_staff_gives_hands_fingers_and_times(tmp_path: Path) -> None:
    song = read_musicxml(_write(tmp_path / "piece.musicxml", _score(GRAND_STAFF)))
    notes = [(n.pitch, n.onset_s, n.offset_s, n.hand, n.finger) for n in song.notes]
    assert notes == [
        (48, 0.0, 4.0, "left", None),  # the lower staff, no finger in the score
        (76, 0.0, 1.0, "right", 2),  # finger 3 of the right hand is index 2
        (60, 1.0, 2.0, "right", 0),
        (64, 1.0, 2.0, "right", 2),
        (67, 1.0, 2.0, "right", 4),
        (74, 2.0, 2.1, "right", None),  # the grace note, on the beat, for 0.1 s
        (72, 2.1, 4.0, "right", None),  # tied over two beats, after its grace note
    ]
    assert song.name == "piece" and not song.sustain
    # The fingering estimate keeps the score's fingers and hands and fills in the rest.
    played = load_song(tmp_path / "piece.musicxml", fingering="auto")
    assert played.has_full_fingering
    assert [(n.pitch, n.finger) for n in played.notes][1:5] == [(76, 2), (60, 0), (64, 2), (67, 4)]
    assert [n.hand for n in played.notes] == [n.hand for n in song.notes]


def test_transposing_instruments_are_read_at_the_pitch_they_sound(tmp_path: Path) -> None:
    # A clarinet in B-flat: its written D4 sounds C4.
    clarinet = _score(_note("D", 4, 4), staves=1).replace(
        "</attributes>",
        "<transpose><diatonic>-1</diatonic><chromatic>-2</chromatic></transpose></attributes>",
    )
    song = read_musicxml(_write(tmp_path / "clarinet.musicxml", clarinet))
    assert [n.pitch for n in song.notes] == [60]
    # The MusicXML test suite's trumpet in B-flat, horn in E-flat and piano, each writing the
    # C major scale its own way: one scale, the parts in unison.
    import music21

    suite = Path(music21.__file__).parent / "musicxml" / "lilypondTestSuite"
    song = read_musicxml(suite / "72a-TransposingInstruments.xml")
    assert sorted({n.pitch for n in song.notes}) == [60, 62, 64, 65, 67, 69, 71, 72]
    assert len({n.onset_s for n in song.notes}) == len(song.notes)


def test_a_timewise_score_reads_as_its_partwise_form(tmp_path: Path) -> None:
    def part(number: int, pid: str, step: str, octave: int) -> str:
        attributes = "<attributes><divisions>1</divisions></attributes>" if number == 1 else ""
        note = _note(step, octave, 4).replace("<staff>1</staff>", "")
        return f'<part id="{pid}">{attributes}{note}</part>'

    measures = "".join(
        f'<measure number="{n}">{part(n, "P1", step, 5)}{part(n, "P2", step, 3)}</measure>'
        for n, step in ((1, "C"), (2, "D"))
    )
    text = (
        '<?xml version="1.0" encoding="UTF-8"?><score-timewise version="3.1"><part-list>'
        '<score-part id="P1"><part-name>R</part-name></score-part>'
        '<score-part id="P2"><part-name>L</part-name></score-part></part-list>'
        f"{measures}</score-timewise>"
    )
    expected = [(48, 0.0, "left"), (72, 0.0, "right"), (50, 2.0, "left"), (74, 2.0, "right")]
    song = read_musicxml(_write(tmp_path / "timewise.musicxml", text))
    assert [(n.pitch, n.onset_s, n.hand) for n in song.notes] == expected
    utf16 = tmp_path / "timewise16.xml"
    utf16.write_bytes(text.replace("UTF-8", "UTF-16").encode("utf-16"))
    assert [(n.pitch, n.onset_s, n.hand) for n in read_musicxml(utf16).notes] == expected


def test_dynamics_give_the_velocities(tmp_path: Path) -> None:
    def dynamic(mark: str) -> str:
        return (
            f"<direction><direction-type><dynamics><{mark}/></dynamics></direction-type>"
            "<staff>1</staff></direction>"
        )

    # Right hand: p C5, sf D5 (an accent: the level stays p), E5, f F5. Left hand: C3 for
    # the bar, under the upper staff's p (the staves of a grand staff share their marks).
    measure = dynamic("p") + _note("C", 5, 1) + dynamic("sf") + _note("D", 5, 1)
    measure += _note("E", 5, 1) + dynamic("f") + _note("F", 5, 1)
    measure += "<backup><duration>4</duration></backup>" + _note("C", 3, 4, staff=2)
    song = read_musicxml(_write(tmp_path / "dynamics.musicxml", _score(measure)))
    velocity = {n.pitch: n.velocity for n in song.notes}
    assert velocity == {72: 44, 74: 108, 76: 44, 77: 89, 48: 44}  # p 0.35, f 0.7, sf 0.85 of 127


def test_hairpins_go_from_one_level_to_the_next(tmp_path: Path) -> None:
    def direction(inner: str) -> str:
        return f"<direction><direction-type>{inner}</direction-type></direction>"

    # p, a crescendo over C4 D4 E4 to f on F4; then a diminuendo over G4 A4 that no mark ends:
    # one step softer (13), which B4 keeps.
    measure = (
        direction("<dynamics><p/></dynamics>")
        + direction('<wedge type="crescendo"/>')
        + _note("C", 4, 1)
        + _note("D", 4, 1)
        + _note("E", 4, 1)
        + direction('<wedge type="stop"/>')
        + direction("<dynamics><f/></dynamics>")
        + _note("F", 4, 1)
    )
    second = (
        direction('<wedge type="diminuendo"/>')
        + _note("G", 4, 2)
        + _note("A", 4, 1)
        + direction('<wedge type="stop"/>')
        + _note("B", 4, 1)
    )
    text = _score(measure, staves=1).replace(
        "</measure></part>", f'</measure><measure number="2">{second}</measure></part>'
    )
    song = read_musicxml(_write(tmp_path / "hairpins.musicxml", text))
    assert [n.velocity for n in song.notes] == [44, 59, 74, 89, 89, 80, 76]
    # p 44 to f 89 over three beats; f 89 to 76 over three beats (G4 at 0, A4 at 2 of 3).


def _ornamented(step: str, octave: int, duration: int, ornament: str) -> str:
    """A right-hand note (durations in sixteenths) carrying an ``<ornaments>`` child."""
    return (
        f"<note><pitch><step>{step}</step><octave>{octave}</octave></pitch>"
        f"<duration>{duration}</duration><staff>1</staff>"
        f"<notations><ornaments>{ornament}</ornaments></notations></note>"
    )


def _sixteenths_score(measure: str) -> str:
    """A one-part, one-staff 4/4 measure in D major (divisions 4: durations in sixteenths)
    at quarter = 60."""
    return (
        '<?xml version="1.0" encoding="UTF-8"?><score-partwise version="3.1"><part-list>'
        '<score-part id="P1"><part-name>Piano</part-name></score-part></part-list>'
        '<part id="P1"><measure number="1"><attributes><divisions>4</divisions>'
        "<key><fifths>2</fifths></key><time><beats>4</beats><beat-type>4</beat-type></time>"
        "</attributes>"
        "<direction><direction-type><metronome><beat-unit>quarter</beat-unit>"
        '<per-minute>60</per-minute></metronome></direction-type><sound tempo="60"/></direction>'
        f"{measure}</measure></part></score-partwise>"
    )


def test_ornaments_are_played_as_a_performer_plays_them(tmp_path: Path, capsys) -> None:
    grace = (
        '<note><grace slash="yes"/><pitch><step>G</step><octave>4</octave></pitch>'
        "<staff>1</staff></note>"
    )
    measure = (
        _ornamented("B", 4, 4, "<trill-mark/>")  # beat 1: a trill, in D major up to C#
        + grace
        + _note("E", 5, 4)  # beat 2, after its grace note
        + _ornamented("D", 5, 4, "<mordent/>")  # beat 3: D C# D
        + _ornamented("E", 5, 2, "<turn/>")  # beat 4: F# E D E, a short note
        + _ornamented("A", 4, 2, '<tremolo type="single">3</tremolo>')  # four A4s
    )
    path = _write(tmp_path / "ornaments.musicxml", _sixteenths_score(measure))
    song = read_musicxml(path)
    notes = [(n.pitch, round(n.onset_s, 4), round(n.offset_s, 4)) for n in song.notes]
    # A one-second trill: nine notes (the most of 0.1 s or more, odd to end on B4).
    trill = [(71 if k % 2 == 0 else 73, round(k / 9, 4), round((k + 1) / 9, 4)) for k in range(9)]
    assert notes[:9] == trill
    assert notes[9:] == [
        (67, 1.0, 1.1),  # the grace note on the beat, taking its time from E5
        (76, 1.1, 2.0),
        (74, 2.0, 2.1),  # the mordent: D5 C#5 D5
        (73, 2.1, 2.2),
        (74, 2.2, 3.0),
        (78, 3.0, 3.1),  # the turn on a half-beat note: F#5 E5 D5 E5, 0.1 s each
        (76, 3.1, 3.2),
        (74, 3.2, 3.3),
        (76, 3.3, 3.5),
        (69, 3.5, 3.625),  # the tremolo's three strokes: the eighth as four 32nds
        (69, 3.625, 3.75),
        (69, 3.75, 3.875),
        (69, 3.875, 4.0),
    ]
    # As written: the grace note left out, every other note once.
    written = read_musicxml(path, ornaments=False)
    assert [(n.pitch, n.onset_s, n.offset_s) for n in written.notes] == [
        (71, 0.0, 1.0),
        (76, 1.0, 2.0),
        (74, 2.0, 3.0),
        (76, 3.0, 3.5),
        (69, 3.5, 4.0),
    ]
    summary = musicxml.score_summary(path)
    assert summary.once_through_s == 4.0
    assert summary.ornaments == {
        "trills": 1,
        "grace notes": 1,
        "mordents": 1,
        "turns": 1,
        "tremolos": 1,
    }
    assert main(["info", str(path)]) == 0
    assert (
        "ornaments:  1 trill, 1 grace note, 1 mordent, 1 turn, 1 tremolo (played; any quicker"
        in capsys.readouterr().out
    )


def test_chord_symbols_are_not_played(tmp_path: Path) -> None:
    # A lead sheet's chord symbols (MusicXML <harmony>, ABC "G") name chords for an
    # accompanist. music21 gives them as chords of no length; read as grace notes, each
    # would sound before its melody note and shorten it.
    harmony = "<harmony><root><root-step>{}</root-step></root><kind>major</kind></harmony>"
    measure = harmony.format("C") + _note("E", 5, 2) + harmony.format("G") + _note("D", 5, 2)
    path = _write(tmp_path / "lead.musicxml", _score(measure, staves=1))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in read_score(path).notes] == [
        (76, 0.0, 2.0),
        (74, 2.0, 4.0),
    ]
    assert musicxml.score_summary(path).ornaments == {}
    tune = 'X:1\nT:Chords\nM:4/4\nL:1/4\nQ:1/4=60\nK:G\n"G"d2 "C"e2 | "D7"f4 |]\n'
    song = read_score(_write(tmp_path / "chords.abc", tune))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in song.notes] == [
        (74, 0.0, 2.0),
        (76, 2.0, 4.0),
        (78, 4.0, 8.0),
    ]


def test_ornaments_too_quick_for_the_goals_frames_are_played_as_written(tmp_path: Path) -> None:
    grace = (
        '<note><grace slash="yes"/><pitch><step>G</step><octave>4</octave></pitch>'
        "<staff>1</staff></note>"
    )
    measure = (  # in 32nds (divisions 8) at quarter = 60
        _ornamented("B", 4, 1, "<trill-mark/>")  # 0.125 s: three notes would be 42 ms each
        + grace
        + grace
        + _note("E", 5, 1)  # two grace notes would be 31 ms each
        + _ornamented("B", 4, 2, "<trill-mark/>")  # 0.25 s: three notes of 83 ms
        + _note("E", 5, 28)
    )
    text = _sixteenths_score(measure).replace(
        "<divisions>4</divisions>", "<divisions>8</divisions>"
    )
    song = read_musicxml(_write(tmp_path / "quick.musicxml", text))
    assert [(n.pitch, n.onset_s) for n in song.notes][:5] == [
        (71, 0.0),
        (76, 0.125),
        (71, 0.25),
        (73, round(0.25 + 0.25 / 3, 6)),
        (71, round(0.25 + 0.5 / 3, 6)),
    ]


def test_a_chord_tremolo_repeats_the_chord_and_a_trill_goes_on_through_its_tie(
    tmp_path: Path,
) -> None:
    chord = _ornamented("D", 4, 8, '<tremolo type="single">1</tremolo>')
    chord += _ornamented("G", 4, 8, '<tremolo type="single">1</tremolo>').replace(
        "<note>", "<note><chord/>"
    )
    trilled = (  # a trilled quarter tied on to a quarter
        "<note><pitch><step>A</step><octave>4</octave></pitch><duration>4</duration>"
        '<tie type="start"/><staff>1</staff><notations><tied type="start"/>'
        "<ornaments><trill-mark/></ornaments></notations></note>"
        "<note><pitch><step>A</step><octave>4</octave></pitch><duration>4</duration>"
        '<tie type="stop"/><staff>1</staff><notations><tied type="stop"/></notations></note>'
    )
    path = _write(tmp_path / "tremolo.musicxml", _sixteenths_score(chord + trilled))
    between = (  # a two-note tremolo over a whole measure: C4 and the chord E4 G4, in eighths
        _ornamented("C", 4, 8, '<tremolo type="start">1</tremolo>')
        + _ornamented("E", 4, 8, '<tremolo type="stop">1</tremolo>')
        + _ornamented("G", 4, 8, '<tremolo type="stop">1</tremolo>').replace(
            "<note>", "<note><chord/>"
        )
    )
    two = read_musicxml(_write(tmp_path / "between.musicxml", _sixteenths_score(between)))
    assert [(n.pitch, n.onset_s) for n in two.notes] == [
        (p, k / 2) for k in range(8) for p in ((60,) if k % 2 == 0 else (64, 67))
    ]
    notes = [(n.pitch, n.onset_s, n.offset_s) for n in read_musicxml(path).notes]
    for pitch in (62, 67):  # D4 G4 struck four times, in eighths
        assert [(on, off) for p, on, off in notes if p == pitch] == [
            (0.0, 0.5),
            (0.5, 1.0),
            (1.0, 1.5),
            (1.5, 2.0),
        ]
    trill = [note for note in notes if note[1] >= 2.0]
    # Nine notes over the written quarter, then on through the tie: eight more of 0.125 s
    # from B4, ending on A4 at the tie's end.
    assert [p for p, _, _ in trill] == [69, 71] * 4 + [69] + [71, 69] * 4
    assert trill[8][1:] == (round(2 + 8 / 9, 6), 3.0)
    assert [on for _, on, _ in trill[9:]] == [3 + k / 8 for k in range(8)]
    assert trill[-1] == (69, 3.875, 4.0)


def test_a_metronome_mark_without_a_number_keeps_the_tempo(tmp_path: Path) -> None:
    unnumbered = (
        "<direction><direction-type><metronome><beat-unit>quarter</beat-unit>"
        "<per-minute></per-minute></metronome></direction-type></direction>"
    )
    measure = _note("C", 4, 2) + unnumbered + _note("D", 4, 2)
    song = read_musicxml(_write(tmp_path / "tempo.musicxml", _score(measure)))
    assert [(n.onset_s, n.offset_s) for n in song.notes] == [(0.0, 2.0), (2.0, 4.0)]  # 60 on


def _words(text: str) -> str:
    return f"<direction><direction-type><words>{text}</words></direction-type></direction>"


def test_rolled_chords_strike_their_notes_a_frame_apart(tmp_path: Path) -> None:
    def chord(sign: str) -> str:
        notes = [_ornamented(step, 4, 4, "") for step in "CEG"]
        notes = [n.replace("<ornaments></ornaments>", sign) for n in notes]
        return notes[0] + "".join(n.replace("<note>", "<note><chord/>") for n in notes[1:])

    measure = (
        chord("<arpeggiate/>")
        + chord('<arpeggiate direction="down"/>')
        + chord("<non-arpeggiate/>")
        + _note("C", 4, 4)
    )
    path = _write(tmp_path / "rolled.musicxml", _sixteenths_score(measure))
    notes = {(n.pitch, n.onset_s, n.offset_s) for n in read_musicxml(path).notes}
    assert {(60, 0.0, 1.0), (64, 0.05, 1.0), (67, 0.1, 1.0)} <= notes  # up, 50 ms apart
    assert {(67, 1.0, 2.0), (64, 1.05, 2.0), (60, 1.1, 2.0)} <= notes  # down
    assert {(60, 2.0, 3.0), (64, 2.0, 3.0), (67, 2.0, 3.0)} <= notes  # a bracket: together
    assert musicxml.score_summary(path).ornaments == {"rolled chords": 2}
    assert {n.onset_s for n in read_musicxml(path, ornaments=False).notes} == {0, 1, 2, 3}


def test_a_roll_across_both_staves_goes_through_both_hands(tmp_path: Path) -> None:
    def rolled(step: str, octave: int, staff: int, chord: bool = False) -> str:
        note = _note(step, octave, 4, staff=staff, chord=chord)
        return note.replace("</note>", '<notations><arpeggiate number="1"/></notations></note>')

    measure = (
        rolled("C", 5, 1)
        + rolled("E", 5, 1, chord=True)
        + "<backup><duration>4</duration></backup>"
        + rolled("C", 3, 2)
        + rolled("G", 3, 2, chord=True)
    )
    song = read_musicxml(_write(tmp_path / "both.musicxml", _score(measure)))
    assert [(n.pitch, n.onset_s, n.offset_s, n.hand) for n in song.notes] == [
        (48, 0.0, 4.0, "left"),
        (55, 0.05, 4.0, "left"),
        (72, 0.1, 4.0, "right"),
        (76, 0.15, 4.0, "right"),
    ]


def test_words_that_name_a_tempo_set_it_where_no_mark_does(tmp_path: Path) -> None:
    # "Adagio" (quarter = 56 in music21's table), "poco più lento" (a change, not a tempo:
    # music21 alone reads it as Lento), then "Presto" (184) at the same time as a metronome
    # mark of 60, which holds.
    mark = (
        "<direction><direction-type><metronome><beat-unit>quarter</beat-unit>"
        '<per-minute>60</per-minute></metronome></direction-type><sound tempo="60"/>'
        "</direction>"
    )
    measure = (
        _words("Adagio")
        + _note("C", 4, 1)
        + _words("poco più lento")
        + _note("D", 4, 1)
        + _words("Presto")
        + mark
        + _note("E", 4, 2)
    )
    text = _score(measure).replace(  # no mark at the start
        '<direction placement="above"><direction-type><metronome><beat-unit>quarter</beat-unit>'
        '<per-minute>60</per-minute></metronome></direction-type><sound tempo="60"/></direction>',
        "",
    )
    song = read_musicxml(_write(tmp_path / "words.musicxml", text))
    beat = 60 / 56
    assert [(n.onset_s, n.offset_s) for n in song.notes] == [
        (0.0, round(beat, 6)),
        (round(beat, 6), round(2 * beat, 6)),
        (round(2 * beat, 6), round(2 * beat + 2, 6)),
    ]


def test_a_fermata_holds_its_note_twice_as_long_and_every_part_waits(tmp_path: Path) -> None:
    def held(note: str) -> str:
        return note.replace("</note>", '<notations><fermata type="upright"/></notations></note>')

    # Upper staff: C5 under a fermata, then D5 E5 F5; lower staff: C3 for two beats, then G3
    # under a fermata on the last half note of the measure.
    measure = (
        held(_note("C", 5, 1))
        + _note("D", 5, 1)
        + _note("E", 5, 1)
        + _note("F", 5, 1)
        + "<backup><duration>4</duration></backup>"
        + _note("C", 3, 2, staff=2)
        + held(_note("G", 3, 2, staff=2))
    )
    path = _write(tmp_path / "fermata.musicxml", _score(measure))
    notes = [(n.pitch, n.onset_s, n.offset_s) for n in read_musicxml(path).notes]
    assert notes == [
        (48, 0.0, 3.0),  # two beats, one of them held: 3 s
        (72, 0.0, 2.0),  # the fermata: one beat held for two seconds
        (74, 2.0, 3.0),
        (55, 3.0, 7.0),  # the last two beats held: 4 s, the upper staff's notes with them
        (76, 3.0, 5.0),
        (77, 5.0, 7.0),
    ]
    written = [(n.pitch, n.onset_s) for n in read_musicxml(path, fermatas=False).notes]
    assert written == [(48, 0.0), (72, 0.0), (74, 1.0), (55, 2.0), (76, 2.0), (77, 3.0)]
    # At quarter = 30 the half note's 4 s are held only 2 s longer (the most a hold adds).
    slow = _score(measure).replace("60<", "30<").replace('tempo="60"', 'tempo="30"')
    notes = [(n.pitch, n.onset_s, n.offset_s) for n in read_musicxml(_write(path, slow)).notes]
    assert notes[3:] == [(55, 6.0, 12.0), (76, 6.0, 9.0), (77, 9.0, 12.0)]


def test_articulations_shorten_and_accent_their_notes(tmp_path: Path) -> None:
    def marked(note: str, marks: str) -> str:
        return note.replace(
            "</note>", f"<notations><articulations>{marks}</articulations></notations></note>"
        )

    measure = (
        marked(_note("C", 4, 1), "<staccato/>")
        + marked(_note("D", 4, 1), "<staccatissimo/>")
        + marked(_note("E", 4, 1), "<accent/>")
        + marked(_note("F", 4, 1), "<tenuto/>")
    )
    path = _write(tmp_path / "marks.musicxml", _score(measure))
    notes = [(n.pitch, n.onset_s, n.offset_s, n.velocity) for n in read_musicxml(path).notes]
    # music21's shifts: staccato 0.7 of the length and +0.05 volume, staccatissimo 0.5,
    # accent +0.1 (times 127 on the velocity of 80), tenuto -0.05 and the written length.
    assert notes == [(60, 0.0, 0.7, 86), (62, 1.0, 1.5, 86), (64, 2.0, 3.0, 93), (65, 3.0, 4.0, 74)]
    written = [(n.offset_s, n.velocity) for n in read_musicxml(path, articulations=False).notes]
    assert written == [(1.0, 80), (2.0, 80), (3.0, 80), (4.0, 80)]
    # A staccato at the end of a tie shortens the tie's last note.
    tied = _note("G", 4, 2, tie="start") + marked(_note("G", 4, 2, tie="stop"), "<staccato/>")
    tied = tied.replace('<tied type="stop"/></notations><notations>', '<tied type="stop"/>')
    song = read_musicxml(_write(tmp_path / "tied.musicxml", _score(tied)))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in song.notes] == [(67, 0.0, 3.4)]


def test_ties_join_voice_by_voice_and_pitch_by_pitch(tmp_path: Path) -> None:
    rest = "<note><rest/><duration>1</duration><staff>1</staff></note>"
    measure = (
        # The chord C4 G4 with only G4 tied into the next chord G4 B4: C4 ends, G4 goes on.
        _note("C", 4, 1)
        + _note("G", 4, 1, chord=True, tie="start")
        + _note("G", 4, 1, tie="stop")
        + _note("B", 4, 1, chord=True)
        # E5 tied to the next E5, whose end of the tie the file forgets: still one note.
        + _note("E", 5, 1, tie="start")
        + _note("E", 5, 1)
        + "<backup><duration>4</duration></backup>"
        # A3 "tied" across a rest to the next A3: two notes, a tie does not bridge silence.
        + _note("A", 3, 1, staff=2, tie="start")
        + rest.replace("<staff>1</staff>", "<staff>2</staff>")
        + _note("A", 3, 2, staff=2, tie="stop")
    )
    song = read_musicxml(_write(tmp_path / "ties.musicxml", _score(measure)))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in song.notes] == [
        (57, 0.0, 1.0),
        (60, 0.0, 1.0),
        (67, 0.0, 2.0),
        (71, 1.0, 2.0),
        (57, 2.0, 4.0),
        (76, 2.0, 4.0),
    ]

    # Two voices of one staff tie the same pitch with different lengths: each tie is its
    # voice's, and the unison is the longer note (E4 for three beats, not cut at beat 1).
    def in_voice(number: int, text: str) -> str:
        return text.replace("<staff>", f"<voice>{number}</voice><staff>")

    voices = in_voice(1, _note("E", 4, 1, tie="start") + _note("E", 4, 1, tie="stop"))
    voices += "<backup><duration>2</duration></backup>"
    voices += in_voice(2, _note("E", 4, 2, tie="start") + _note("E", 4, 1, tie="stop"))
    two = read_musicxml(_write(tmp_path / "voices.musicxml", _score(voices)))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in two.notes] == [(64, 0.0, 3.0)]


def test_a_substitution_keeps_its_first_finger_and_other_marks_are_no_fingers() -> None:
    from music21 import articulations, note

    marked = note.Note("C4")
    marked.articulations += [articulations.Fingering("4-3"), articulations.Accent()]
    from pianist.music.musicxml.marks import finger_numbers

    assert finger_numbers(marked) == [4]
    odd = note.Note("C4")
    odd.articulations.append(articulations.Fingering("p"))  # a guitarist's thumb
    assert finger_numbers(odd) == [None]


def test_three_staves_give_no_hands(tmp_path: Path) -> None:
    one_staff = _note("C", 4, 4).replace("<staff>1</staff>", "")
    song = read_musicxml(_write(tmp_path / "trio.xml", _score(one_staff, parts=3, staves=1)))
    assert [(n.pitch, n.hand, n.finger) for n in song.notes] == [(60, None, None)]  # unison


def test_a_voice_above_a_grand_staff_leaves_the_staves_their_hands(tmp_path: Path) -> None:
    # A song: the voice's part (one staff, G4 for the bar), then the piano's grand staff.
    voice = _note("G", 4, 4).replace("<staff>1</staff>", "")
    piano = _note("E", 5, 4) + "<backup><duration>4</duration></backup>" + _note("C", 3, 4, staff=2)
    text = _score(voice, parts=2, staves=1)
    # The second part becomes the piano: two staves, and its own notes.
    second = text.index('<part id="P2">')
    piano_part = text[second:].replace("<staves>1</staves>", "<staves>2</staves>")
    piano_part = piano_part.replace(voice, piano)
    song = read_musicxml(_write(tmp_path / "song.musicxml", text[:second] + piano_part))
    assert [(n.pitch, n.hand) for n in song.notes] == [(48, "left"), (67, None), (76, "right")]


def _pedal(kind: str) -> str:
    return (
        f'<direction><direction-type><pedal type="{kind}" line="yes"/></direction-type>'
        "<staff>2</staff></direction>"
    )


def test_a_sustain_pedal_mark_holds_from_its_first_note_to_the_end_of_its_last(
    tmp_path: Path,
) -> None:
    # Right hand: four quarters. Left hand: C3 for two beats under the pedal, then G3 after it.
    measure = "".join(_note(step, 5, 1) for step in "CDEF")
    measure += "<backup><duration>4</duration></backup>" + _pedal("start")
    measure += _note("C", 3, 2, staff=2) + _pedal("stop") + _note("G", 3, 2, staff=2)
    song = read_musicxml(_write(tmp_path / "pedal.musicxml", _score(measure)))
    assert song.sustain == ((0.0, 2.0),)
    assert [n.pitch for n in song.notes if n.hand == "left"] == [48, 55]


def test_a_pedal_change_inside_a_mark_lifts_the_pedal_there(tmp_path: Path) -> None:
    from pianist.music.musicxml import PEDAL_CHANGE_S

    # Left hand: three quarters under one mark, the pedal changed at the third (2 s), then a
    # fourth after the mark.
    measure = "".join(_note(step, 5, 1) for step in "CDEF")
    measure += "<backup><duration>4</duration></backup>" + _pedal("start")
    measure += _note("C", 3, 1, staff=2) + _note("E", 3, 1, staff=2)
    measure += _pedal("change") + _note("G", 3, 1, staff=2) + _pedal("stop")
    measure += _note("C", 4, 1, staff=2)
    song = read_musicxml(_write(tmp_path / "change.musicxml", _score(measure)))
    assert song.sustain == ((0.0, 2.0), (2.0 + PEDAL_CHANGE_S, 3.0))
    # In a repeated part the change lifts the pedal each time it is played.
    text = _one_staff_score("C", "D|forward", "E|backward", "F", pedalled=3)
    whole = _note("E", 4, 4).replace("<staff>1</staff>", "")
    change = _pedal("change").replace("<staff>2</staff>", "")
    halves = (_note("E", 4, 2) + change + _note("G", 4, 2)).replace("<staff>1</staff>", "")
    repeated = read_musicxml(_write(tmp_path / "repeated.musicxml", text.replace(whole, halves)))
    lift = 10.0 + PEDAL_CHANGE_S, 18.0 + PEDAL_CHANGE_S
    assert repeated.sustain == ((8.0, 10.0), (lift[0], 12.0), (16.0, 18.0), (lift[1], 20.0))


def _one_staff_score(*measures: str, pedalled: int | None = None) -> str:
    """A one-part, one-staff score of whole notes, one per measure, given as "C",
    "D|forward", "E|backward" (the barline's repeat sign; "backward3": played 3 times),
    "F|backward|1" or "G||2" (under the first or second ending's bracket; "" for a bracket
    without a number) and "A|||segno", "A|||coda" (the sign) or "A|||D.C. al Fine" (words
    after the note); measure ``pedalled`` (from 1) under a sustain-pedal mark."""
    attributes = (
        "<attributes><divisions>1</divisions><time><beats>4</beats><beat-type>4</beat-type>"
        '</time></attributes><sound tempo="60"/>'
    )
    body = ""
    for number, spec in enumerate(measures, start=1):
        step, repeat, ending, mark = (spec.split("|") + ["", "", ""])[:4]
        note = _note(step, 4, 4).replace("<staff>1</staff>", "")
        left = (
            '<barline location="left"><repeat direction="forward"/></barline>'
            if repeat == "forward"
            else ""
        )
        right = ""
        if repeat.startswith("backward"):
            times = f' times="{repeat[8:]}"' if repeat[8:] else ""
            right = f'<barline location="right"><repeat direction="backward"{times}/></barline>'
        if ending:  # the bracket's ends go first in their barlines
            label = "" if ending == "?" else ending
            start = f'<barline location="left"><ending number="{label}" type="start"/>'
            left = start + (left.replace('<barline location="left">', "") or "</barline>")
            stop = f'<barline location="right"><ending number="{label}" type="stop"/>'
            right = stop + (right.replace('<barline location="right">', "") or "</barline>")
        if mark in ("segno", "coda"):
            note = f"<direction><direction-type><{mark}/></direction-type></direction>" + note
        elif mark:
            note += f"<direction><direction-type><words>{mark}</words></direction-type></direction>"
        first = attributes if number == 1 else ""
        if number == pedalled:
            note = _pedal("start").replace("<staff>2</staff>", "") + note
            note += _pedal("stop").replace("<staff>2</staff>", "")
        body += f'<measure number="{number}">{left}{first}{note}{right}</measure>'
    return (
        '<?xml version="1.0" encoding="UTF-8"?><score-partwise version="3.1"><part-list>'
        '<score-part id="P1"><part-name>Piano</part-name></score-part></part-list>'
        f'<part id="P1">{body}</part></score-partwise>'
    )


def _pitches(path: Path) -> list[int]:
    return [n.pitch for n in read_musicxml(path).notes]


def test_repeats_are_played_as_a_performer_plays_them(tmp_path: Path) -> None:
    path = _write(
        tmp_path / "minuet.musicxml", _one_staff_score("C", "D|forward", "E|backward", "F")
    )
    assert [(n.pitch, n.onset_s) for n in read_musicxml(path).notes] == [
        (60, 0.0),
        (62, 4.0),
        (64, 8.0),
        (62, 12.0),
        (64, 16.0),
        (65, 20.0),
    ]
    once = read_musicxml(path, expand_repeats=False)
    assert [n.pitch for n in once.notes] == [60, 62, 64, 65]
    # A pedal mark inside the repeated part is pressed each time it is played.
    measures = ("C", "D|forward", "E|backward", "F")
    pedalled = _write(tmp_path / "pedal.musicxml", _one_staff_score(*measures, pedalled=3))
    assert read_musicxml(pedalled).sustain == ((8.0, 12.0), (16.0, 20.0))
    assert read_musicxml(pedalled, expand_repeats=False).sustain == ((8.0, 12.0),)
    # Two forward signs and no backward one: nothing to play again.
    bad = _write(tmp_path / "bad.musicxml", _one_staff_score("C", "D|forward", "E|forward", "F"))
    assert _pitches(bad) == [60, 62, 64, 65]
    # Backward signs without forward ones go back to just after the previous backward sign
    # (music21 alone goes back to the piece's start each time), past its endings.
    implied = ("C|backward", "D", "E|backward", "F|backward")
    sections = _write(tmp_path / "sections.musicxml", _one_staff_score(*implied))
    assert _pitches(sections) == [60, 60, 62, 64, 62, 64, 65, 65]
    endings = ("C|backward", "D", "E|backward|1", "F||2", "G|backward")
    with_endings = _write(tmp_path / "endings.musicxml", _one_staff_score(*endings))
    assert _pitches(with_endings) == [
        *(60, 60),
        *(62, 64, 62, 65),  # the first ending, then the second
        *(67, 67),  # back to just after the second ending, not into it
    ]


def test_endings_without_numbers_and_repeats_played_more_than_twice(tmp_path: Path) -> None:
    # Brackets without numbers (which music21 refuses to expand) are the run's first and
    # second endings.
    unnumbered = ("C|forward", "D|backward|?", "E||?", "F")
    path = _write(tmp_path / "unnumbered.musicxml", _one_staff_score(*unnumbered))
    assert _pitches(path) == [60, 62, 60, 64, 65]
    # A sign that says three times, and endings "1, 2" then "3".
    thrice = _write(tmp_path / "thrice.musicxml", _one_staff_score("C|forward", "D|backward3"))
    assert _pitches(thrice) == [60, 62] * 3
    three = ("C|forward", "D|backward|1, 2", "E||3")
    path = _write(tmp_path / "three.musicxml", _one_staff_score(*three))
    assert _pitches(path) == [60, 62, 60, 62, 60, 64]


def test_da_capo_and_dal_segno(tmp_path: Path) -> None:
    # A minuet and trio: the minuet repeated, the trio repeated, then the minuet again
    # without its repeat, to the fine.
    minuet = ("C|backward", "D|||Fine", "E|forward", "F|backward||D.C. al Fine")
    path = _write(tmp_path / "minuet.musicxml", _one_staff_score(*minuet))
    assert _pitches(path) == [60, 60, 62, 64, 65, 64, 65, 60, 62]
    # Dal segno al coda: back to the segno, from the to-coda mark to the coda; after the jump
    # only the last ending of a repeat is played.
    segno = (
        "C",
        "D|forward||segno",
        "E|backward|1",
        "F||2|To Coda",
        "G|||D.S. al Coda",
        "A|||coda",
    )
    path = _write(tmp_path / "segno.musicxml", _one_staff_score(*segno))
    assert _pitches(path) == [60, 62, 64, 62, 65, 67, 62, 65, 69]
    # A dal segno with no segno: played once as written, and said so.
    lost = _write(tmp_path / "lost.musicxml", _one_staff_score("C", "D|||D.S."))
    with pytest.warns(UserWarning, match="could not be expanded.*has no segno"):
        assert _pitches(lost) == [60, 62]


def test_an_order_that_plays_a_measure_too_often_is_played_once(tmp_path: Path) -> None:
    from pianist.music.repeats import MAX_PLAYINGS

    count = f"backward{MAX_PLAYINGS + 1}"
    path = _write(tmp_path / "many.musicxml", _one_staff_score("C|forward", f"D|{count}"))
    with pytest.warns(UserWarning, match=f"would play measure 1 {MAX_PLAYINGS + 1} times"):
        assert _pitches(path) == [60, 62]


def _measures_played(name: str, tmp_path: Path) -> list[int]:
    """The measure numbers, in the order played, of a repeat test of the MusicXML test suite
    that music21 ships (Lilypond's; one rest or note per measure): each measure's rest or note
    is made a pitch that names the measure."""
    import re

    import music21

    suite = Path(music21.__file__).parent / "musicxml" / "lilypondTestSuite"
    text = next(suite.glob(f"{name}-*.xml")).read_text(encoding="utf-8")
    chunks = re.split(r'(?=<measure number=")', text)
    measure_of = {}
    for k, chunk in enumerate(chunks[1:], start=1):
        step, octave = "CDEFGAB"[k % 7], 3 + k // 7
        measure_of[12 * (octave + 1) + [0, 2, 4, 5, 7, 9, 11][k % 7]] = k
        pitch = f"<pitch><step>{step}</step><octave>{octave}</octave></pitch>"
        chunks[k] = re.sub(r"<rest/>|<pitch>.*?</pitch>", pitch, chunk, flags=re.S)
    path = _write(tmp_path / f"{name}.musicxml", "".join(chunks))
    return [measure_of[n.pitch] for n in read_musicxml(path).notes]


def test_the_repeat_tests_of_a_musicxml_test_suite(tmp_path: Path) -> None:
    # A measure repeated five times, the count on its sign (music21 too).
    assert _measures_played("45a", tmp_path) == [1, 1, 1, 1, 1, 2]
    assert _measures_played("45b", tmp_path) == [1, 2, 1, 3, 4]
    # Repeats after repeats, with endings: the repeat at the end of measure 7, under a first
    # ending, goes back to measure 6, after the previous repeat (music21 does not take it).
    expected = [1, 2, 1, 3, 4, 5, 5, 6, 7, 6, 8, 9, 8, 9, 10]
    assert _measures_played("45e", tmp_path) == expected
    # A start-repeat sign without an end (music21 refuses to expand the score).
    assert _measures_played("45g", tmp_path) == [1, 2]


def _two_parts(upper: str, lower: str) -> str:
    """A score of two parts (the right and the left hand) from two one-part scores, the lower
    one's notes an octave down."""
    body = lower[lower.index('<part id="P1">') : lower.index("</score-partwise>")]
    body = body.replace('id="P1"', 'id="P2"').replace("<octave>4</octave>", "<octave>3</octave>")
    return upper.replace(
        "</part-list>", '<score-part id="P2"><part-name>B</part-name></score-part></part-list>'
    ).replace("</score-partwise>", body + "</score-partwise>")


def test_parts_of_different_lengths_are_played_as_written(tmp_path: Path) -> None:
    lower = _one_staff_score("C")
    path = _write(
        tmp_path / "uneven.musicxml", _two_parts(_one_staff_score("C|forward", "D|backward"), lower)
    )
    with pytest.warns(UserWarning, match="different numbers of measures"):
        assert _pitches(path) == [48, 60, 62]
    # Without repeat marks there is nothing to warn about.
    plain = _two_parts(_one_staff_score("C", "D"), lower)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert _pitches(_write(tmp_path / "plain.musicxml", plain)) == [48, 60, 62]
    assert not [w for w in caught if "could not be expanded" in str(w.message)]


def test_the_parts_start_every_measure_together(tmp_path: Path) -> None:
    # The left hand's file leaves its first measure half empty: its second measure still
    # starts with the right hand's (music21 lays it out 2 s early).
    lower = _one_staff_score("C", "D").replace(
        "<duration>4</duration>", "<duration>2</duration>", 1
    )
    path = _write(tmp_path / "short.musicxml", _two_parts(_one_staff_score("E", "F"), lower))
    song = read_musicxml(path)
    assert [(n.pitch, n.onset_s) for n in song.notes if n.hand == "left"] == [(48, 0.0), (50, 4.0)]


def test_a_mark_in_one_part_is_played_by_every_part(tmp_path: Path) -> None:
    # The segno and the dal segno are written over the right hand only.
    upper = _one_staff_score("C", "D|||segno", "E|||D.S.")
    path = _write(tmp_path / "segno.musicxml", _two_parts(upper, _one_staff_score("F", "G", "A")))
    song = read_musicxml(path)
    assert [n.pitch for n in song.notes if n.hand == "left"] == [53, 55, 57, 55, 57]
    assert [n.pitch for n in song.notes if n.hand == "right"] == [60, 62, 64, 62, 64]


def test_a_da_capo_goes_back_to_its_movement(tmp_path: Path) -> None:
    # A first movement in 4/4 (C, D); a second in 3/4 with one sharp (E with the fine, F with
    # "da capo al fine"); then G, which follows the fine.
    def measure(number: int, step: str, beats: int, extra: str = "", attributes: str = "") -> str:
        note = _note(step, 4, beats).replace("<staff>1</staff>", "")
        return f'<measure number="{number}">{attributes}{note}{extra}</measure>'

    def words(text: str) -> str:
        return f"<direction><direction-type><words>{text}</words></direction-type></direction>"

    first = (
        "<attributes><divisions>1</divisions><key><fifths>0</fifths></key><time><beats>4</beats>"
        '<beat-type>4</beat-type></time></attributes><sound tempo="60"/>'
    )
    second = (
        "<attributes><key><fifths>1</fifths></key><time><beats>3</beats><beat-type>4</beat-type>"
        "</time></attributes>"
    )
    body = (
        measure(1, "C", 4, attributes=first)
        + measure(2, "D", 4)
        + measure(3, "E", 3, words("Fine"), attributes=second)
        + measure(4, "F", 3, words("D.C. al Fine"))
        + measure(5, "G", 3)
    )
    text = (
        '<?xml version="1.0" encoding="UTF-8"?><score-partwise version="3.1"><part-list>'
        '<score-part id="P1"><part-name>Piano</part-name></score-part></part-list>'
        f'<part id="P1">{body}</part></score-partwise>'
    )
    song = read_musicxml(_write(tmp_path / "movements.musicxml", text))
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        (60, 0.0),
        (62, 4.0),
        (64, 8.0),
        (65, 11.0),
        (64, 14.0),
        (67, 17.0),
    ]


def test_voices_merge_on_one_keyboard() -> None:
    raw = [
        (60, 0.0, 1.0, 80, "right", 0),
        (60, 0.0, 2.0, 80, "left", None),  # unison: the longer note stays
        (60, 1.5, 3.0, 80, "right", None),  # struck again while it sounds: the first ends
        (62, 1.0, 1.0, 80, None, None),  # no length
    ]
    assert [(n.pitch, n.onset_s, n.offset_s, n.hand) for n in merge_voices(raw)] == [
        (60, 0.0, 1.5, "left"),
        (60, 1.5, 3.0, "right"),
    ]


def test_bad_scores_are_clear_errors(tmp_path: Path, monkeypatch) -> None:
    def message(path: Path, error: type[Exception] = MusicError) -> str:
        with pytest.raises(error) as info:
            load_song(path)
        assert "\n" not in str(info.value) and str(path) in str(info.value)
        return str(info.value)

    assert "not a readable MusicXML" in message(_write(tmp_path / "x.xml", "<html></html>"))
    assert "empty" in message(_write(tmp_path / "empty.musicxml", ""))
    assert "not found" in message(tmp_path / "missing.mxl")
    rest = "<note><rest/><duration>4</duration><staff>1</staff></note>"
    assert "no notes" in message(_write(tmp_path / "rests.musicxml", _score(rest)))
    drum = "<note><unpitched><display-step>C</display-step><display-octave>5</display-octave>"
    drum += "</unpitched><duration>4</duration><staff>1</staff></note>"
    drums = message(_write(tmp_path / "drums.musicxml", _score(drum)))
    assert "no notes (only 1 unpitched percussion note(s))" in drums
    high = _note("B", 8, 1) + _note("C", 4, 1)  # B8 is MIDI 119, above the top C (108)
    path = _write(tmp_path / "high.musicxml", _score(high))
    assert "--out-of-range drop" in message(path, OutOfRangeError)
    assert [n.pitch for n in load_song(path, out_of_range="drop").notes] == [60]
    # A failure inside music21's parsed score is named as the file's, not a traceback.
    from pianist.music.musicxml import reader

    with monkeypatch.context() as patched:
        patched.setattr(reader, "finger_numbers", lambda element: element.no_such_field)
        assert "a score this reader cannot follow (AttributeError" in message(path)
    monkeypatch.setitem(sys.modules, "music21", None)  # as if it were not installed
    assert "pip install 'pianist[musicxml]'" in message(tmp_path / "rests.musicxml")


def test_importing_pianist_does_not_load_music21() -> None:
    import subprocess

    code = "import sys, pianist, pianist.music, pianist.cli; assert 'music21' not in sys.modules"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_info_says_the_hands_come_from_the_staves(tmp_path: Path, capsys) -> None:
    path = _write(tmp_path / "piece.musicxml", _score(GRAND_STAFF))
    assert main(["info", str(path)]) == 0
    assert "hands:      left, right (from the score's staves)" in capsys.readouterr().out


def test_info_says_what_the_repeats_add(tmp_path: Path, capsys) -> None:
    measures = ("C", "D|forward", "E|backward", "F")
    path = _write(tmp_path / "minuet.musicxml", _one_staff_score(*measures))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "duration:   24.00 s" in out
    assert "repeats:    played (16.00 s once through as written)" in out
    plain = _write(tmp_path / "plain.musicxml", _one_staff_score("C", "D"))
    assert main(["info", str(plain)]) == 0
    out = capsys.readouterr().out
    assert "repeats:    none" in out and "ornaments:  none" in out
    lost = _write(tmp_path / "lost.musicxml", _one_staff_score("C", "D|||D.S."))
    assert main(["info", str(lost)]) == 0
    assert "repeats:    not played (see the warning)" in capsys.readouterr().out


def test_info_parses_a_score_once(tmp_path: Path, capsys, monkeypatch) -> None:
    parses = []
    from pianist.music.musicxml import files

    parse = files._parse
    monkeypatch.setattr(files, "_parse", lambda *a: parses.append(a) or parse(*a))
    path = _write(tmp_path / "piece.musicxml", _score(GRAND_STAFF))  # fingered in part
    assert main(["info", str(path)]) == 0
    assert "notes:      7" in capsys.readouterr().out and len(parses) == 1


def test_play_a_musicxml_score(tmp_path: Path) -> None:
    path = _write(tmp_path / "piece.musicxml", _score(GRAND_STAFF))
    out = tmp_path / "out"
    assert main(["play", str(path), "--no-audio", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["f1"] > 0.7 and metrics["steps"] == 81
    assert metrics["notes"] == 7 and metrics["as_written"] is False  # the grace note played
    written = tmp_path / "written"
    assert main(["play", str(path), "--no-audio", "--as-written", "--out", str(written)]) == 0
    metrics = json.loads((written / "metrics.json").read_text())
    assert metrics["notes"] == 6 and metrics["as_written"] is True


# A Humdrum **kern score: the left hand's spine first (C3 D3 E3 F3), then the right's (C4 ...),
# quarter = 60.
KERN = """**kern\t**kern
*clefF4\t*clefG2
*M4/4\t*M4/4
*MM60\t*MM60
=1-\t=1-
4C\t4c
4D\t4d
4E\t4e
4F\t4f
==\t==
*-\t*-
"""

# An ABC book of two tunes; the first repeats its first two bars (a scale), then D5 and C5.
ABC = """X:1
T:One
M:4/4
L:1/4
Q:1/4=60
K:C
|: C D E F | G A B c :| d4 | c4 |]

X:2
T:Two
M:4/4
L:1/4
K:C
c d e f |]
"""


# An MEI score of two staves and two measures, the second ending with an end-repeat sign.
MEI = """<?xml version="1.0" encoding="UTF-8"?>
<mei xmlns="http://www.music-encoding.org/ns/mei" meiversion="4.0.0">
<meiHead><fileDesc><titleStmt><title>Test</title></titleStmt><pubStmt/></fileDesc></meiHead>
<music><body><mdiv><score>
<scoreDef meter.count="4" meter.unit="4" key.sig="0"><staffGrp>
<staffDef n="1" lines="5" clef.shape="G" clef.line="2"/>
<staffDef n="2" lines="5" clef.shape="F" clef.line="4"/>
</staffGrp></scoreDef>
<section>
<measure n="1"><staff n="1"><layer n="1"><note pname="c" oct="5" dur="2"/>
<note pname="d" oct="5" dur="2"/></layer></staff>
<staff n="2"><layer n="1"><note pname="c" oct="3" dur="1"/></layer></staff></measure>
<measure n="2" right="rptend"><staff n="1"><layer n="1"><note pname="e" oct="5" dur="1"/>
</layer></staff><staff n="2"><layer n="1"><note pname="g" oct="2" dur="1"/></layer></staff>
</measure>
</section></score></mdiv></body></music></mei>
"""


def test_an_abc_fermata_shorthand_keeps_its_note(tmp_path: Path) -> None:
    # "HE": E under a fermata, held twice as long. music21 alone drops the E and plays F on
    # the third beat; the H of the history field, of the quoted text and of the comment are
    # not fermatas.
    tune = 'X:1\nT:Held\nH:Heard in Hexham\nM:4/4\nL:1/4\nQ:1/4=60\nK:C\n"Hi"C D HE F|] % Hm\n'
    song = read_score(_write(tmp_path / "held.abc", tune))
    assert [(n.pitch, n.onset_s, n.offset_s) for n in song.notes] == [
        (60, 0.0, 1.0),
        (62, 1.0, 2.0),
        (64, 2.0, 4.0),
        (65, 4.0, 5.0),
    ]


# A two-hand ABC tune as such tunes are written: voices declared in the header, then taking
# turns a line each ([V:name] at the line's start), the right hand first.
ABC_TURNS = """X:1
T:Turns
M:4/4
L:1/4
Q:1/4=60
V:RH clef=treble name="Right"
V:LH clef=bass name="Left"
%%score {RH | LH}
K:C
[V:RH] c d e f |
[V:LH] C,2 G,,2 |
[V:RH] g2 c2 |]
[V:LH] C,4 |]
"""


def test_abc_voices_taking_turns_play_together(tmp_path: Path) -> None:
    # music21 alone reads no [V:...] field (all eight bars play one after another, with no
    # hands) and starts a new part at every V: line (a voice's second line would sound with
    # its first, and each header declaration is a part of no notes).
    expected = [
        (48, 0.0, "left"),
        (72, 0.0, "right"),
        (74, 1.0, "right"),
        (43, 2.0, "left"),
        (76, 2.0, "right"),
        (77, 3.0, "right"),
        (48, 4.0, "left"),
        (79, 4.0, "right"),
        (72, 6.0, "right"),
    ]
    song = read_score(_write(tmp_path / "turns.abc", ABC_TURNS))
    assert [(n.pitch, n.onset_s, n.hand) for n in song.notes] == expected
    # The same with V: lines of names music21 takes (digits), in turns, declared in the header.
    lines = ABC_TURNS.replace("[V:RH]", "V:1\n").replace("[V:LH]", "V:2\n")
    lines = lines.replace("V:RH", "V:1").replace("V:LH", "V:2")
    song = read_score(_write(tmp_path / "lines.abc", lines))
    assert [(n.pitch, n.onset_s, n.hand) for n in song.notes] == expected
    # In a book, only the tune read is rewritten; a tune of one voice is left as it is.
    book = _write(tmp_path / "book.abc", ABC.replace("X:2", ABC_TURNS.replace("X:1", "X:2")))
    assert [(n.pitch, n.onset_s) for n in read_score(f"{book}#2").notes][:3] == [
        (48, 0.0),
        (72, 0.0),
        (74, 1.0),
    ]
    from pianist.music.musicxml.abc import abc_for_music21, voices_in_blocks

    one_voice = ABC.split("\n\n")[1]
    assert voices_in_blocks(one_voice) == (one_voice, None)
    assert abc_for_music21(_write(tmp_path / "plain.abc", ABC), None).text is None


def test_abc_decorations_are_played(tmp_path: Path) -> None:
    # music21 alone reads only the staccato dot, on single notes, and M as a tenuto.
    tune = (
        "X:1\nT:Decorated\nM:4/4\nL:1/4\nQ:1/4=60\nK:G\n"
        "Tc2 Mc2 | .c !>!c !fermata!c2 | !arpeggio![ceg]2 !p!d !f!e |]\n"
    )
    song = read_score(_write(tmp_path / "decorated.abc", tune))
    notes = [(n.pitch, round(n.onset_s, 3), round(n.offset_s, 3), n.velocity) for n in song.notes]
    trill = [n for n in notes if n[1] < 2.0]
    # The trill: C and D in turn, an odd number of notes of at least 0.1 s, ending on C.
    assert trill[:3] == [(72, 0.0, 0.105, 80), (74, 0.105, 0.211, 80), (72, 0.211, 0.316, 80)]
    assert len(trill) == 19 and trill[-1] == (72, 1.895, 2.0, 80)
    assert notes[19:] == [
        (72, 2.0, 2.1, 80),  # the lower mordent: C, B (in G major), C
        (71, 2.1, 2.2, 80),
        (72, 2.2, 4.0, 80),
        (72, 4.0, 4.7, 86),  # staccato: 0.7 of the note
        (72, 5.0, 6.0, 93),  # accent: +13
        (72, 6.0, 10.0, 80),  # the fermata: held twice as long, at most 2 s longer
        (72, 10.0, 12.0, 80),  # the rolled chord, a frame per note
        (76, 10.05, 12.0, 80),
        (79, 10.1, 12.0, 80),
        (74, 12.0, 13.0, 44),  # p
        (76, 13.0, 14.0, 89),  # f
    ]
    # A voice music21 reads other than its text (it reads one A of this line twice) keeps
    # none of its decorations, and says so; its notes are read as music21 reads them.
    odd = "X:1\nM:4/4\nL:1/8\nQ:1/4=60\nK:C\n(TB>c)(B>A) FA z A2 | Mc8 | d8 |]\n"
    with pytest.warns(UserWarning, match="2 ABC decoration.*left out"):
        song = read_score(_write(tmp_path / "odd.abc", odd))
    assert (song.notes[0].pitch, song.notes[0].offset_s) == (71, 0.75)  # no trill


def test_abc_double_repeat_signs_and_annotations_keep_their_notes(tmp_path: Path) -> None:
    # music21 alone loses every note from the A before "::" on (7 notes read), and drops the
    # note after an annotation that starts with ">".
    tune = 'X:1\nM:4/4\nL:1/4\nQ:1/4=60\nK:C\n|:ABcA|ABcA::">2,1"Bddd|Bddd:|\n'
    song = read_score(_write(tmp_path / "twice.abc", tune))
    first, second = [69, 71, 72, 69] * 4, [71, 74, 74, 74] * 4
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        (pitch, float(k)) for k, pitch in enumerate(first + second)
    ]


def test_abc_invisible_and_whole_bar_rests_keep_their_time(tmp_path: Path) -> None:
    # music21 drops an invisible rest ("x2") and a rest of whole bars ("Z2"), and every later
    # note comes that much early (here at 0, 4, 6, 14 s); a bar of 3/4 after [M:3/4].
    tune = (
        "X:1\nM:4/4\nL:1/4\nQ:1/4=60\nK:C\nc2 z2 | x2 c2 | Z2 | c4 | z4 | d4 | [M:3/4] Z | e3 |]\n"
    )
    song = read_score(_write(tmp_path / "rests.abc", tune))
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        (72, 0.0),
        (72, 6.0),
        (72, 16.0),
        (74, 24.0),
        (76, 31.0),
    ]


def test_abc_accidentals_hold_to_the_end_of_the_bar(tmp_path: Path) -> None:
    # As on paper, an accidental holds for its pitch (letter and octave) to the bar line, and
    # a note tied over the bar line keeps its own; music21 alone applies each to its own note
    # (here F# F# in G major, C natural after ^c, E natural in the chord).
    tune = "X:1\nM:4/4\nL:1/4\nQ:1/4=60\nK:G\n=F F f ^c- | c c [_EG] [EG] | F f E F |]\n"
    song = read_score(_write(tmp_path / "accidentals.abc", tune))
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        (65, 0.0),  # =F, and the F after it
        (65, 1.0),
        (78, 2.0),  # f: another octave, so F# from the key
        (73, 3.0),  # ^c, tied over the bar line: one note, to 5 s
        (72, 5.0),  # the bar's next c: natural
        (63, 6.0),  # _E in a chord, and the E of the next chord
        (67, 6.0),
        (63, 7.0),
        (67, 7.0),
        (66, 8.0),  # a new bar: the key again
        (78, 9.0),
        (64, 10.0),
        (66, 11.0),
    ]


def test_abc_parts_play_in_the_headers_order(tmp_path: Path) -> None:
    # P:ABA, ABC's da capo: music21 alone plays A and B once each. The tune's blank line, which
    # ends it in a book, stays at its end.
    tune = (
        "X:1\nM:4/4\nL:1/4\nQ:1/4=60\nP:A2(B.A)\nK:C\nP:A\nC D E F | G4 |\nP:B % middle\n"
        "c B A G | F4 |]\n\nX:2\nK:C\nC4 |]\n"
    )
    song = read_score(f"{_write(tmp_path / 'parts.abc', tune)}#1")
    a, b = [60, 62, 64, 65, 67], [72, 71, 69, 67, 65]
    assert [n.pitch for n in song.notes] == a + a + b + a
    assert song.duration_s == 32.0


def test_humdrum_sections_play_in_the_expansion_lists_order(tmp_path: Path) -> None:
    # Sections A (C D, E) and B (G, A) played A A B A: the da capo that the repeat sign at
    # A's end (A A B) does not write. music21 alone reads neither the labels nor the list.
    kern = "**kern\n*>[A,A,B,A]\n*>A\n*M4/4\n=1-\n2c\n2d\n=2\n1e\n=3:|!\n*>B\n1g\n=4\n1a\n==\n*-\n"
    path = _write(tmp_path / "sections.krn", kern)
    a, b = [(60, 0.0), (62, 1.0), (64, 2.0)], [(67, 4.0), (69, 6.0)]
    later = [(pitch, at + 4.0) for pitch, at in a]
    song = read_score(path)
    assert [(n.pitch, n.onset_s) for n in song.notes] == a + later + [
        (pitch, at + 4.0) for pitch, at in b
    ] + [(pitch, at + 12.0) for pitch, at in a]
    assert [(n.pitch, n.onset_s) for n in read_score(path, expand_repeats=False).notes] == a + b


# An MEI measure with its control events: a trill on C5, an upper mordent on D5, a fermata
# on E5, a crescendo from C5 to E5; then a chord rolled downwards.
MEI_EVENTS = MEI.replace(
    '<measure n="1"><staff n="1"><layer n="1"><note pname="c" oct="5" dur="2"/>\n'
    '<note pname="d" oct="5" dur="2"/></layer></staff>',
    '<measure n="1"><staff n="1"><layer n="1"><note xml:id="c" pname="c" oct="5" dur="2"/>'
    '<note xml:id="d" pname="d" oct="5" dur="4"/><note xml:id="e" pname="e" oct="5" dur="4"/>'
    '</layer></staff><trill startid="#c"/><mordent startid="#d" form="upper"/>'
    '<fermata startid="#e"/><hairpin form="cres" startid="#c" endid="#e"/>',
).replace(
    '<note pname="e" oct="5" dur="1"/>\n</layer>',
    '<chord dur="1"><note xml:id="g1" pname="c" oct="5"/><note xml:id="g2" pname="g" oct="5"/>'
    '</chord></layer><arpeg plist="#g1 #g2" order="down"/>',
)


def test_mei_ornaments_fermatas_rolls_and_hairpins_are_read(tmp_path: Path) -> None:
    # music21 reads the notes of an MEI score but none of its control events.
    path = _write(tmp_path / "events.mei", MEI_EVENTS)
    right = [
        (n.pitch, round(n.onset_s, 3), round(n.offset_s, 3), n.velocity)
        for n in read_score(path, expand_repeats=False).notes
        if n.hand == "right"
    ]
    trill = [n for n in right if n[1] < 1.0]
    assert len(trill) == 9 and {n[0] for n in trill} == {72, 74} and trill[-1][0] == 72
    assert right[9:] == [
        (74, 1.0, 1.1, 86),  # the upper mordent: D E D, louder on the crescendo
        (76, 1.1, 1.2, 86),
        (74, 1.2, 1.5, 86),
        (76, 1.5, 2.5, 90),  # the fermata: twice as long
        (79, 2.5, 4.5, 93),  # the chord rolled downwards, a frame per note
        (72, 2.55, 4.5, 93),
    ]
    assert musicxml.score_summary(path).ornaments == {
        "trills": 1,
        "mordents": 1,
        "rolled chords": 1,
    }


def test_abc_voices_on_the_staves_the_score_directive_gives(tmp_path: Path) -> None:
    # Three voices: a melody and an inner voice on the upper staff, a bass on the lower, as
    # the %%score directive draws them. Without it, three voices give no hands.
    tune = (
        "X:1\nM:4/4\nL:1/4\nQ:1/4=60\n%%score {(S A) | B}\nK:C\n"
        "[V:S] e f g a |]\n[V:A] c4 |]\n[V:B] C,4 |]\n"
    )
    song = read_score(_write(tmp_path / "staves.abc", tune))
    assert [(n.pitch, n.hand) for n in song.notes if n.onset_s == 0.0] == [
        (48, "left"),
        (72, "right"),
        (76, "right"),
    ]
    plain = read_score(_write(tmp_path / "plain.abc", tune.replace("%%score {(S A) | B}\n", "")))
    assert {n.hand for n in plain.notes} == {None}


def test_abc_overlays_play_with_their_bar(tmp_path: Path) -> None:
    # "&" lays a second voice over a bar. music21 alone plays the overlay after the bar's
    # notes (the C under bar 1 at 4 s, and every later note 4 s late). The overlay becomes
    # a voice of its own, silent in the bars without one; the repeat and its endings hold
    # for both. One staff gives no hands (estimated).
    tune = "X:1\nM:4/4\nL:1/4\nQ:1/4=60\nK:G\n|:c d e f & C4 |1 g4 :|2 [CE]2 G2 & c2 (3cde |]\n"
    song = read_score(_write(tmp_path / "overlay.abc", tune))
    bar = [(72, 0.0), (74, 1.0), (76, 2.0), (78, 3.0)]
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        (60, 0.0),
        *bar,
        (79, 4.0),
        (60, 8.0),
        *[(pitch, at + 8.0) for pitch, at in bar],
        (60, 12.0),
        (64, 12.0),
        (72, 12.0),
        (67, 14.0),
        (72, 14.0),
        (74, 14.666667),
        (76, 15.333333),
    ]
    assert {n.hand for n in song.notes} == {None}
    # With a second voice, the overlay is of the first's staff: the right hand.
    bass = tune.replace("K:G\n", "K:G\nV:1\n") + "V:2\n|:C,4 |1 D,4 :|2 G,,4 |]\n"
    song = read_score(_write(tmp_path / "two.abc", bass))
    assert [n.pitch for n in song.notes if n.hand == "left"] == [48, 50, 48, 43]
    assert {n.pitch for n in song.notes if n.hand == "right"} == {60, 64, 67, 72, 74, 76, 78, 79}


def test_abc_tunes_of_a_book_keep_their_ends_and_default_unit(tmp_path: Path) -> None:
    # The first tune's voices are gathered, but the blank line that ends it stays at its end
    # (gathered after it, its second voice would fall outside the tune). The second tune has
    # no metre and no L: field: eighths, by the standard (music21 alone refuses it).
    book = (
        "X:1\nM:4/4\nL:1/4\nQ:1/4=60\nK:C\nV:1\nc d e f |\nV:2\nC, D, E, F, |\nV:1\n"
        "g a b c |]\n\nX:2\nQ:1/4=60\nK:C\nC D E F |]\n"
    )
    path = _write(tmp_path / "book.abc", book)
    from pianist.music.musicxml.abc import abc_for_music21

    assert "F, |\n\nX:2" in (abc_for_music21(path, 1).text or "")
    first = read_score(f"{path}#1")
    assert [n.pitch for n in first.notes if n.hand == "left"] == [48, 50, 52, 53]
    second = read_score(f"{path}#2")
    assert [(n.pitch, n.onset_s, n.offset_s) for n in second.notes] == [
        (60, 0.0, 0.5),
        (62, 0.5, 1.0),
        (64, 1.0, 1.5),
        (65, 1.5, 2.0),
    ]


def test_humdrum_abc_and_mei_scores(tmp_path: Path, capsys) -> None:
    from pianist.music import load_song
    from pianist.music.fileio import song_files

    kern = _write(tmp_path / "scale.krn", KERN)
    song = load_song(kern)
    assert [(n.pitch, n.onset_s, n.hand) for n in song.notes if n.hand == "left"] == [
        (48, 0.0, "left"),
        (50, 1.0, "left"),
        (52, 2.0, "left"),
        (53, 3.0, "left"),
    ]
    assert [n.pitch for n in song.notes if n.hand == "right"] == [60, 62, 64, 65]
    assert main(["info", str(kern)]) == 0
    assert "hands:      left, right (from the score's staves)" in capsys.readouterr().out
    abc = _write(tmp_path / "book.abc", ABC)
    with pytest.warns(UserWarning, match=r"a book of 2 tunes; the first, 'One', is read \(name"):
        song = load_song(abc)
    # Another tune of the book, named by its reference number; a number the book lacks.
    second = load_song(f"{abc}#2")
    assert ([n.pitch for n in second.notes], second.name) == ([72, 74, 76, 77], "book-2")
    with pytest.raises(MusicError, match="book.abc: not a readable ABC score.*9"):
        load_song(f"{abc}#9")
    assert main(["info", f"{abc}#2"]) == 0
    assert "repeats:    none" in capsys.readouterr().out
    scale = [60, 62, 64, 65, 67, 69, 71, 72]
    assert [(n.pitch, n.onset_s) for n in song.notes] == [
        *((pitch, float(k)) for k, pitch in enumerate(scale + scale)),
        (74, 16.0),
        (72, 20.0),
    ]
    mei = _write(tmp_path / "repeat.mei", MEI)
    song = load_song(mei)
    assert [n.pitch for n in song.notes if n.hand == "right"] == [72, 74, 76] * 2
    assert [n.pitch for n in song.notes if n.hand == "left"] == [48, 43] * 2
    assert song_files(tmp_path) == [abc, mei, kern]
    # A file that is not of its suffix's format says which format was expected.
    with pytest.raises(MusicError, match="not a readable Humdrum"):
        load_song(_write(tmp_path / "bad.krn", "<html></html>"))
