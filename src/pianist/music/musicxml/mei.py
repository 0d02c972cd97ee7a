"""An MEI score's ornaments, fermatas, rolls and hairpins, which music21 does not read.

MEI writes these as control events beside the notes, pointing at the note they belong to
(``<trill startid="#n1"/>``); music21's MEI reader keeps each note's ``xml:id`` as its
``id`` but reads none of these events. :func:`put_control_events` reads them from the file
and puts each on its note (on the chord, for a note of a chord) as music21 would have:
trills, mordents (``form="upper"``: an inverted one), turns (``form="lower"``: inverted;
``delayed``), fermatas, rolled chords (``<arpeg>``, up or down) and hairpins (``<hairpin
form="cres">`` from its start note to its end note). Events that point at no note music21
read, or by time alone (``tstamp``), are left out.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

#: The MEI namespace.
_MEI = "{http://www.music-encoding.org/ns/mei}"


def put_control_events(score: Any, path: Path) -> None:
    """Put the control events of the MEI file at ``path`` on the notes of ``score``, music21's
    parse of it, in place (see the module docstring). A file that is not XML is left to
    music21's own message."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return
    events = [e for e in root.iter() if e.tag.removeprefix(_MEI) in _KINDS]
    if not events:
        return
    from music21 import dynamics, expressions

    owner: dict[str, Any] = {}  # an xml:id -> the note or chord that carries its marks
    for element in score.recurse().notes:
        owner[str(element.id)] = element
        for note in getattr(element, "notes", ()):  # a chord's notes: their chord
            owner[str(note.id)] = element
    for event in events:
        kind = event.tag.removeprefix(_MEI)
        targets = [owner.get(ref.lstrip("#")) for ref in _references(event)]
        first = targets[0] if targets else None
        if first is None:
            continue
        if kind == "hairpin":
            last = owner.get(event.get("endid", "").lstrip("#"))
            if last is not None:
                wedge = dynamics.Crescendo if event.get("form") == "cres" else dynamics.Diminuendo
                score.insert(0, wedge(first, last))
            continue
        if kind == "arpeg" and event.get("order") == "nonarp":
            continue
        mark = _mark(kind, event, expressions)
        if mark is not None:
            first.expressions.append(mark)


#: The control events read, by their MEI element name.
_KINDS = frozenset({"trill", "mordent", "turn", "fermata", "arpeg", "hairpin"})


def _references(event: ET.Element) -> list[str]:
    """The ids an event points at: its ``startid``, or an ``<arpeg>``'s ``plist``."""
    start = event.get("startid")
    return [start] if start else (event.get("plist") or "").split()


def _mark(kind: str, event: ET.Element, expressions: Any) -> Any | None:
    """music21's expression for a control event (``expressions``: music21's module)."""
    if kind == "trill":
        return expressions.Trill()
    if kind == "mordent":
        upper = event.get("form") == "upper"
        return expressions.InvertedMordent() if upper else expressions.Mordent()
    if kind == "turn":
        turn = expressions.InvertedTurn() if event.get("form") == "lower" else expressions.Turn()
        if event.get("delayed") == "true":
            turn.delay = expressions.OrnamentDelay.DEFAULT_DELAY
        return turn
    if kind == "fermata":
        return expressions.Fermata()
    if kind == "arpeg":
        return expressions.ArpeggioMark("down" if event.get("order") == "down" else "normal")
    return None
