"""The order a Humdrum score's sections are played in.

A Humdrum score labels its sections (``*>A``, ``*>B``, ``*>Trio``) and lists the order they
are played in (its expansion list, ``*>[A,A,B,B,C,C,D,A,B]``: the repeats, and a da capo
that repeat signs alone do not write). music21 reads neither: it gives the measures once
through, with the repeat signs of the bar lines. :func:`section_order` reads the list as
the measures to play, which the reader plays in place of the repeat signs.
"""

from __future__ import annotations

import re
from typing import NamedTuple

#: The default expansion list (``*>[A,A,B]``; a named one, ``*>norep[A,B]``, is another
#: performance's).
_EXPANSION = re.compile(r"\*>\[([^\]]*)\]")
#: A section label (``*>A``, ``*>Trio``).
_LABEL = re.compile(r"\*>([^\[\]]+)")


class SectionOrder(NamedTuple):
    """A Humdrum score's measures in the order its expansion list plays them."""

    #: The measures played, by their index from the score's first (a pickup counts).
    measures: list[int]
    #: How many measures the score has: music21 must give as many for the order to hold.
    total: int


def section_order(text: str) -> SectionOrder | None:
    """The measures a Humdrum score (its text) plays in its expansion list's order; None
    where it has no such list, or the list names a section the score does not label.

    The measures are counted as music21 lays them out: one from each bar line to the next,
    and one before the first bar line where notes come before it (a pickup)."""
    order: list[str] | None = None
    starts: list[tuple[int, str]] = []  # (bar lines before it, name) of each label
    bars = 0
    notes_before_first_bar = False
    for line in text.splitlines():
        tokens = line.split("\t")
        first = tokens[0]
        if first.startswith("="):
            bars += 1
        elif first.startswith("*"):
            expansion = _EXPANSION.fullmatch(first)
            label = _LABEL.fullmatch(first)
            if order is None and expansion and all(t == first for t in tokens):
                order = [name.strip() for name in expansion[1].split(",")]
            elif label and all(t == first for t in tokens):
                starts.append((bars, label[1]))
        elif first and not first.startswith("!") and bars == 0:
            notes_before_first_bar = True
    if not order or not starts:
        return None
    shift = 0 if notes_before_first_bar else 1  # a bar line before any note opens measure 0
    total = bars - shift
    spans: dict[str, list[int]] = {}
    ends = [at for at, _ in starts[1:]] + [bars]
    for (begin, name), end in zip(starts, ends, strict=True):
        first_measure = max(0, begin - shift)
        spans.setdefault(name, []).extend(range(first_measure, max(first_measure, end - shift)))
    if any(name not in spans for name in order):
        return None
    return SectionOrder([m for name in order for m in spans[name]], total)
