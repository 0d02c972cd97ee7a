"""The notes each ornament stands for (pianist.music.ornaments), timed in quarter lengths."""

from __future__ import annotations

import pytest

from pianist.music.ornaments import (
    alternation,
    grace_length,
    mordent,
    roll_starts,
    tremolo,
    trill,
    trill_carried_on,
    turn,
)

C4, D4, B3 = 60, 62, 59


def _covers(notes: list[tuple[int, float, float]], length: float) -> None:
    """The notes follow each other without gap or overlap over the whole written length."""
    assert notes[0][1] == 0.0 and notes[-1][2] == pytest.approx(length)
    for (_, _, end), (_, start, _) in zip(notes, notes[1:], strict=False):
        assert start == pytest.approx(end)


def test_a_trill_alternates_at_the_pace_and_ends_on_its_note() -> None:
    notes = trill(C4, D4, 1.0, 0.1)
    assert [p for p, _, _ in notes] == [C4, D4] * 4 + [C4]  # 9: the most of >= 0.1, odd
    _covers(notes, 1.0)
    assert min(b - a for _, a, b in notes) >= 0.1
    # A note too short for the pace keeps three notes, shared evenly.
    short = trill(C4, D4, 0.15, 0.1)
    assert [p for p, _, _ in short] == [C4, D4, C4]
    _covers(short, 0.15)


def test_a_mordent_and_turns() -> None:
    assert mordent(C4, B3, 1.0, 0.1) == [(C4, 0.0, 0.1), (B3, 0.1, 0.2), (C4, 0.2, 1.0)]
    squeezed = mordent(C4, D4, 0.15, 0.1)  # three notes share a short note
    assert [p for p, _, _ in squeezed] == [C4, D4, C4]
    _covers(squeezed, 0.15)
    notes = turn(C4, D4, B3, 1.0, 0.1)
    assert [p for p, _, _ in notes] == [D4, C4, B3, C4]
    assert notes[-1][1] == pytest.approx(0.3)
    _covers(notes, 1.0)
    delayed = turn(C4, D4, B3, 1.0, 0.1, delayed=True)
    assert [p for p, _, _ in delayed] == [C4, D4, C4, B3, C4]
    assert delayed[0][2] == pytest.approx(0.6)  # the written note held, then the turn
    _covers(delayed, 1.0)


def test_a_tremolo_repeats_at_its_strokes_value_or_the_pace() -> None:
    assert [a for _, a, _ in tremolo(C4, 1.0, 1, 0.1)] == [0.0, 0.5]  # eighths
    assert len(tremolo(C4, 1.0, 3, 0.1)) == 8  # 32nds
    assert len(tremolo(C4, 1.0, 4, 0.2)) == 5  # 64ths slower than the pace: at the pace
    assert tremolo(C4, 0.3, 1, 0.1) == [(C4, 0.0, 0.3)]  # no room for one repetition
    _covers(tremolo(C4, 1.0, 3, 0.15), 1.0)


def test_grace_notes_take_at_most_half_their_note() -> None:
    assert grace_length(1, 1.0, 0.1) == 0.1
    assert grace_length(3, 0.4, 0.1) == pytest.approx(0.4 / 6)


def test_a_rolled_chord_starts_its_notes_a_step_apart_within_half_its_length() -> None:
    assert roll_starts(3, 1.0, 0.05) == [0.0, 0.05, 0.1]
    assert roll_starts(5, 0.2, 0.05) == pytest.approx([0.0, 0.025, 0.05, 0.075, 0.1])
    assert roll_starts(1, 1.0, 0.05) == [0.0]


def test_a_tremolo_between_two_notes_alternates_them_from_the_first() -> None:
    notes = alternation([C4], [D4, B3], 1.0, 2, 0.1)  # sixteenths over a quarter
    assert [(p, a) for p, a, _ in notes] == [
        (C4, 0.0),
        (D4, 0.25),
        (B3, 0.25),
        (C4, 0.5),
        (D4, 0.75),
        (B3, 0.75),
    ]
    assert len(alternation([C4], [D4], 1.0, 4, 0.2)) == 4  # at the pace, an even count
    assert [p for p, _, _ in alternation([C4], [D4], 0.3, 1, 0.1)] == [C4, D4]  # at least two


def test_a_trill_carried_on_by_a_tie_starts_above_and_ends_on_its_note() -> None:
    notes = trill_carried_on(C4, D4, 1.0, 0.11)
    assert [p for p, _, _ in notes] == [D4, C4] * 4  # 0.125 each: the most pairs of >= 0.11
    _covers(notes, 1.0)
    assert [p for p, _, _ in trill_carried_on(C4, D4, 0.1, 0.11)] == [D4, C4]  # at least two
