"""playing_order on measures described directly: repeats, endings, jumps, refusals."""

from __future__ import annotations

import pytest

from pianist.music.repeats import MAX_PLAYINGS, Bar, RepeatError, playing_order

PLAIN = Bar()
START = Bar(start_repeat=True)
END = Bar(end_repeat=True)


def _ending(*numbers: int, end_repeat: bool = False) -> Bar:
    return Bar(ending=frozenset(numbers), end_repeat=end_repeat)


def test_no_marks_is_the_written_order() -> None:
    assert playing_order([PLAIN] * 4) == [0, 1, 2, 3]
    assert playing_order([]) == []


def test_sections_each_repeated_with_and_without_start_signs() -> None:
    # ||: A :||: B :|| C, then A :|| B :|| with the start signs left implied.
    assert playing_order([START, END, START, END, PLAIN]) == [0, 1, 0, 1, 2, 3, 2, 3, 4]
    assert playing_order([PLAIN, END, PLAIN, END]) == [0, 1, 0, 1, 2, 3, 2, 3]


def test_endings_are_played_on_their_passes() -> None:
    # A |1. B :| 2. C | D :| -- the second repeat goes back to D, not into the endings.
    bars = [PLAIN, _ending(1, end_repeat=True), _ending(2), PLAIN, END]
    assert playing_order(bars) == [0, 1, 0, 2, 3, 4, 3, 4]
    # A first ending of two measures.
    bars = [START, _ending(1), _ending(1, end_repeat=True), _ending(2), PLAIN]
    assert playing_order(bars) == [0, 1, 2, 0, 3, 4]
    # Endings "1, 2" and "3": the passage three times.
    assert playing_order([START, _ending(1, 2, end_repeat=True), _ending(3)]) == [0, 1, 0, 1, 0, 2]
    # A sign's own count.
    assert playing_order([START, Bar(end_repeat=True, times=3)]) == [0, 1, 0, 1, 0, 1]


def test_da_capo_dal_segno_fine_and_coda() -> None:
    # Da capo to the end, repeats not taken again.
    assert playing_order([PLAIN, END, Bar(jump="capo")]) == [0, 1, 0, 1, 2, 0, 1, 2]
    # Da capo al fine, with the fine's measure repeated before the jump.
    fine = Bar(end_repeat=True, fine=True)
    assert playing_order([PLAIN, fine, Bar(jump="capo", jump_to="fine")]) == [0, 1, 0, 1, 2, 0, 1]
    # Dal segno al fine: the fine is ignored before the jump.
    bars = [PLAIN, Bar(segno=True), Bar(fine=True), Bar(jump="segno", jump_to="fine")]
    assert playing_order(bars) == [0, 1, 2, 3, 1, 2]
    # Dal segno al coda.
    bars = [Bar(segno=True), Bar(to_coda=True), Bar(jump="segno", jump_to="coda"), Bar(coda=True)]
    assert playing_order(bars) == [0, 1, 2, 0, 1, 3]
    # Al coda with no coda sign after the mark: played on to the end.
    bars = [Bar(to_coda=True), Bar(jump="capo", jump_to="coda"), PLAIN]
    assert playing_order(bars) == [0, 1, 0, 1, 2]
    # One jump only: a da capo reached again after the jump is not taken.
    assert playing_order([PLAIN, Bar(jump="capo")]) == [0, 1, 0, 1]


def test_orders_no_performer_could_play_are_refused() -> None:
    with pytest.raises(RepeatError, match="has no segno"):
        playing_order([PLAIN, Bar(jump="segno")])
    with pytest.raises(RepeatError, match=f"measure 1 {MAX_PLAYINGS + 1} times"):
        playing_order([START, Bar(end_repeat=True, times=MAX_PLAYINGS + 1)])
    # A repeat played three times, and once more after a jump, is allowed.
    bars = [START, Bar(end_repeat=True, times=3), Bar(jump="capo")]
    assert playing_order(bars).count(0) == 4


def test_a_first_ending_shorter_than_its_repeat() -> None:
    # |: A |1. B | C :|2. D -- the bracket over B only (as in a quartet's file): the second
    # time B is left out and C leads to the second ending, C is not repeated on its own.
    bars = [START, _ending(1), END, _ending(2), PLAIN]
    assert playing_order(bars) == [0, 1, 2, 0, 2, 3, 4]


def test_a_da_capo_stays_in_its_movement() -> None:
    # Movement 1 (A B), then a scherzo C with its fine and a trio D with "da capo al fine",
    # then movement 3 (E): the da capo goes back to C, and after the fine E is played.
    bars = [
        PLAIN,
        PLAIN,
        Bar(new_movement=True, fine=True),
        Bar(jump="capo", jump_to="fine"),
        Bar(new_movement=True),
    ]
    assert playing_order(bars) == [0, 1, 2, 3, 2, 4]
