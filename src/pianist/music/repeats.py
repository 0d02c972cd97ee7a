"""The order in which a performer plays a score's measures: repeat signs, numbered endings,
da capo and dal segno (al fine, al coda).

This module knows nothing of any score format: a reader describes each measure's marks as a
:class:`Bar` and :func:`playing_order` returns the measures' indices as played. The
conventions it follows, the ones a performer follows:

- An end-repeat sign goes back to the last start-repeat sign, or, where there is none, to just
  after the previous repeat (past its endings), or to the start. It is taken once (the passage
  is played twice) unless the sign says how many times, or its ending's numbers say more (an
  end-repeat under an ending "1, 2" is taken twice).
- A measure under an ending (a first, second, ... ending's bracket) is played only on the
  passes its numbers name.
- A da capo goes back to the start (of its movement, in a score of several), a dal segno to
  the segno. Each is taken once. Until the music passes the jump's measure again, repeats
  are not taken and only the last ending of each repeat is played; "al fine" ends there
  (what follows the jump's measure, the next movement, is played next), "al coda" goes from
  the to-coda mark to the coda.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

#: The most times one measure may be played. A count on a repeat sign (a passage played five
#: times), a repeat taken again after a jump, stay below it; more is a file's slip (a count of
#: 100), refused rather than played for minutes.
MAX_PLAYINGS = 16


class RepeatError(ValueError):
    """The marks give no order a performer could play (a dal segno without a segno, a measure
    played more than :data:`MAX_PLAYINGS` times)."""


@dataclass(frozen=True)
class Bar:
    """What one measure's notation says about the order of playing.

    Attributes:
        start_repeat: a start-repeat sign at its start.
        end_repeat: an end-repeat sign at its end.
        times: how many times the end-repeat's passage is played, where the sign says so.
        ending: the numbers of the ending whose bracket is over the measure (empty: none).
        segno: a segno sign (where a dal segno goes back to).
        coda: a coda sign where the coda starts (where a to-coda mark goes to).
        to_coda: a to-coda mark at its end (where "al coda" leaves for the coda).
        fine: a fine at its end (where "al fine" stops).
        jump: a da capo ("capo") or dal segno ("segno") at its end.
        jump_to: where that jump goes on to: the end (None), the fine or the coda.
        new_movement: the measure starts a new movement of a score that holds several (a
            da capo after it goes back here, not to the score's start).
    """

    start_repeat: bool = False
    end_repeat: bool = False
    times: int | None = None
    ending: frozenset[int] = frozenset()
    segno: bool = False
    coda: bool = False
    to_coda: bool = False
    fine: bool = False
    jump: Literal["capo", "segno"] | None = None
    jump_to: Literal["fine", "coda"] | None = None
    new_movement: bool = False


def playing_order(bars: Sequence[Bar]) -> list[int]:
    """The indices of ``bars`` in the order a performer plays them (see the module's
    conventions).

    Raises:
        RepeatError: a dal segno with no segno before it, or an order that plays a measure
            more than :data:`MAX_PLAYINGS` times.
    """
    last_ending = _last_endings(bars)
    order: list[int] = []
    played = [0] * len(bars)
    position = 0
    section = 0  # where the next end-repeat goes back to
    pass_number = 1  # which time the current section is being played
    closed = False  # the section's repeat is done: the next measure outside an ending opens one
    returning = False  # just gone back to the section's start
    taken: set[int] = set()  # the jumps taken (each once)
    jumped_from: int | None = None  # while playing a jump's passage: the jump's measure
    jump_to: Literal["fine", "coda"] | None = None
    while position < len(bars):
        if jumped_from is not None and position > jumped_from:
            jumped_from = jump_to = None  # past the jump: repeats are taken again
        bar = bars[position]
        if not returning and (bar.start_repeat or (closed and not bar.ending)):
            section, pass_number, closed = position, 1, False
        returning = False
        if bar.ending:
            wanted = last_ending[position] if jumped_from is not None else pass_number
            if wanted not in bar.ending:
                # A later pass's ending: the repeat is left once its sign is passed.
                closed = closed or bar.end_repeat
                position += 1
                continue
        played[position] += 1
        if played[position] > MAX_PLAYINGS:
            raise RepeatError(f"they would play measure {position + 1} {played[position]} times")
        order.append(position)
        if bar.end_repeat and jumped_from is None:
            times = bar.times or (max(bar.ending) + 1 if bar.ending else 2)
            if pass_number < times:
                pass_number += 1
                position, returning = section, True
                continue
            closed = True
        if jumped_from is not None and jump_to == "fine" and bar.fine:
            # The piece ends here; what follows the jump's measure is the next movement.
            position, jumped_from, jump_to, closed = jumped_from + 1, None, None, True
            continue
        if jumped_from is not None and jump_to == "coda" and bar.to_coda:
            coda = next((i for i in range(position + 1, len(bars)) if bars[i].coda), None)
            position = coda if coda is not None else position + 1
            continue
        if bar.jump is not None and position not in taken:
            taken.add(position)
            jumped_from, jump_to = position, bar.jump_to
            if bar.jump == "capo":
                position = _movement_start(bars, position)
            else:
                position = _segno_before(bars, position)
            continue
        position += 1
    return order


def _last_endings(bars: Sequence[Bar]) -> list[int]:
    """Per measure under an ending, the highest ending number of its run of consecutive
    endings (the ending played after a jump); 0 elsewhere."""
    last = [0] * len(bars)
    start = 0
    while start < len(bars):
        if not bars[start].ending:
            start += 1
            continue
        end = start
        while end < len(bars) and bars[end].ending:
            end += 1
        highest = max(max(b.ending) for b in bars[start:end])
        last[start:end] = [highest] * (end - start)
        start = end
    return last


def _movement_start(bars: Sequence[Bar], position: int) -> int:
    """The index of the measure a da capo at ``position`` goes back to: its movement's first
    (the piece's first, or the last :attr:`Bar.new_movement` before it)."""
    for index in range(position, 0, -1):
        if bars[index].new_movement:
            return index
    return 0


def _segno_before(bars: Sequence[Bar], position: int) -> int:
    """The index of the segno a dal segno at ``position`` goes back to: the last one before
    it (or at it)."""
    for index in range(position, -1, -1):
        if bars[index].segno:
            return index
    raise RepeatError(f"a dal segno in measure {position + 1} has no segno before it")
