"""An ABC tune's music rewritten line by line where music21 would misread it, and the
decorations music21 cannot read put back on its notes after it parses the tune.

See :mod:`pianist.music.musicxml.abc` for what each rewrite mends: decorations, double
repeat signs, rests, accidentals and annotations (:func:`music_rewritten`), the decorations
put back by :func:`put_decorations`.
"""

from __future__ import annotations

import re
import warnings
from fractions import Fraction
from pathlib import Path
from typing import Any, NamedTuple

#: A field line (``X:``, ``K:``, ``V:``, ``w:``, ...).
FIELD = re.compile(r"[A-Za-z+]:")
#: A voice field line: the voice's name and its properties (``V:RH clef=treble``).
VOICE_LINE = re.compile(r"V:\s*(\S+)[ \t]*(.*)")


def header_end(lines: list[str]) -> int | None:
    """The index of a tune's ``K:`` line, which ends its header; None where it has none."""
    return next((i for i, line in enumerate(lines) if line.startswith("K:")), None)


class Decorated(NamedTuple):
    """A note or chord of an ABC voice, in the order the text gives them, and the decorations
    written before it."""

    #: Its pitches' letters ("C", "F", ...), sorted: to check it against music21's note.
    steps: tuple[str, ...]
    #: Whether it is a grace note (inside ``{...}``).
    grace: bool
    #: Its decorations, by their ABC names ("trill", "fermata", "p", ...).
    names: tuple[str, ...]


#: ABC's one-character decorations (its defaults; a tune's ``U:`` redefinitions are not read).
_SHORTHAND = {
    ".": "staccato",
    "~": "roll",
    "H": "fermata",
    "L": "accent",
    "M": "lowermordent",
    "O": "coda",
    "P": "uppermordent",
    "S": "segno",
    "T": "trill",
    "u": "upbow",
    "v": "downbow",
}
#: Decorations a pianist plays, by ABC name: music21's expression or articulation class
#: (module, name), or a dynamic's name.
_PLAYED: dict[str, tuple[str, str]] = {
    "trill": ("expressions", "Trill"),
    "trill(": ("expressions", "Trill"),
    "lowermordent": ("expressions", "Mordent"),
    "mordent": ("expressions", "Mordent"),
    "uppermordent": ("expressions", "InvertedMordent"),
    "pralltriller": ("expressions", "InvertedMordent"),
    "turn": ("expressions", "Turn"),
    "invertedturn": ("expressions", "InvertedTurn"),
    "roll": ("expressions", "Turn"),
    "fermata": ("expressions", "Fermata"),
    "invertedfermata": ("expressions", "Fermata"),
    "arpeggio": ("expressions", "ArpeggioMark"),
    "staccato": ("articulations", "Staccato"),
    "wedge": ("articulations", "Staccatissimo"),
    "accent": ("articulations", "Accent"),
    "emphasis": ("articulations", "Accent"),
    ">": ("articulations", "Accent"),
    "tenuto": ("articulations", "Tenuto"),
    **{
        level: ("dynamics", level)
        for level in ("pppp", "ppp", "pp", "p", "mp", "mf", "f", "ff", "fff", "ffff", "sfz")
    },
}
#: Decorations taken out of the text and not played (a string player's bowing).
_DROPPED = frozenset({"upbow", "downbow"})
#: ABC 2.1's hairpin forms, written as the ones music21 reads.
_HAIRPINS = {
    "<(": "crescendo(",
    "<)": "crescendo)",
    ">(": "diminuendo(",
    ">)": "diminuendo)",
}
#: Where a note, chord, grace group or rest starts (after decorations).
_EVENT_START = re.compile(r"[\^_=]*[A-Ga-g]|\[(?![A-Za-z]:|\d|\|)|\{|[zx]")


def music_rewritten(tune: str) -> tuple[str, list[list[Decorated]]]:
    """One tune's music rewritten line by line (the decorations this module reads taken out;
    hairpins, repeats, annotations and rests as the module docstring says), and per voice (a
    ``V:`` block, in order; the whole tune where it has none) every note and chord of it with
    the decorations written before it."""
    lines = tune.splitlines(keepends=True)
    key = header_end(lines)
    key = len(lines) if key is None else key
    voices: dict[str, list[Decorated]] = {"": []}  # "": the music before any voice field
    accidentals: dict[str, _Accidentals] = {}
    current = ""
    bar = _Bar()
    for i, line in enumerate(lines):
        bar.read_field(line)
        if i <= key:
            continue
        voice = VOICE_LINE.match(line)
        if voice:
            current = voice[1]
            continue
        if FIELD.match(line) or line.startswith("%"):
            continue
        events = voices.setdefault(current, [])
        lines[i] = _line_rewritten(
            line, events, bar, accidentals.setdefault(current, _Accidentals())
        )
    if len(voices) > 1 and not voices.get("", True):
        del voices[""]  # only fields before the first voice
    return "".join(lines), list(voices.values())


class _Bar:
    """The length of a bar, from a tune's meter (``M:``) and unit note length (``L:``) fields
    as they come, to write a multi-measure rest out."""

    def __init__(self) -> None:
        self.meter: Fraction | None = None
        self.unit: Fraction | None = None

    def read_field(self, field: str) -> None:
        """Take an ``M:`` or ``L:`` field (a line, or an inline field's text without its
        brackets) into account; anything else is ignored."""
        name, _, value = field.partition(":")
        value = value.split("%")[0].strip()
        if name == "M":
            meters = {"C": Fraction(4, 4), "C|": Fraction(2, 2)}
            self.meter = meters.get(value) or _fraction(value)
        elif name == "L":
            self.unit = _fraction(value)

    def units(self) -> str | None:
        """A bar's length in unit notes, as ABC writes a length ("8", "3/2"); None in free
        meter, or where the fields cannot be read."""
        if self.meter is None:
            return None
        # ABC's default unit: a sixteenth in metres under 3/4, an eighth otherwise.
        unit = self.unit or (Fraction(1, 16) if self.meter < Fraction(3, 4) else Fraction(1, 8))
        length = self.meter / unit
        return str(length.numerator) + ("" if length.denominator == 1 else f"/{length.denominator}")


#: A note's pitch in ABC: its accidentals, letter and octave marks.
_NOTE = re.compile(r"([\^_=]*)([A-Ga-g])([',]*)")


class _Accidentals:
    """The accidentals a voice's notes carry within a bar: in ABC, as on paper, an accidental
    holds for the notes of its pitch (letter and octave) to the bar's end, and a note tied
    over the bar line keeps its own. music21 applies each to its own note only."""

    def __init__(self) -> None:
        self.carried: dict[tuple[str, int], str] = {}
        self.tied: dict[tuple[str, int], str] = {}  # a tied note's, for the note it is tied to

    def note(self, match: re.Match[str], tied: bool) -> str:
        """A note's pitch (a :data:`_NOTE` match) with the accidental it carries written out;
        ``tied``: a tie goes from it to the next."""
        accidental, letter, marks = match.groups()
        octave = (1 if letter.islower() else 0) + marks.count("'") - marks.count(",")
        key = (letter.upper(), octave)
        if accidental:
            self.carried[key] = accidental
            self.tied.pop(key, None)
        else:
            accidental = self.tied.pop(key, None) or self.carried.get(key, "")
        if tied and accidental:
            self.tied[key] = accidental
        return accidental + letter + marks

    def chord(self, inside: str, tied: bool) -> str:
        """A chord's notes (the text inside its brackets), each as :meth:`note` writes it."""
        pieces, last = [], 0
        for match in _NOTE.finditer(inside):
            pieces += [inside[last : match.start()], self.note(match, tied)]
            last = match.end()
        return "".join(pieces) + inside[last:]

    def bar(self) -> None:
        """A bar line: the accidentals end (a tied note's is kept for the note it is tied to)."""
        self.carried.clear()


def _fraction(text: str) -> Fraction | None:
    """``"6/8"`` or ``"2+3/8"`` as a fraction; None for anything else."""
    match = re.fullmatch(r"([\d+]+)\s*/\s*(\d+)", text)
    if not match or not match[2].strip("0"):
        return None
    return Fraction(sum(int(k) for k in match[1].split("+") if k), int(match[2]))


def _line_rewritten(
    line: str, events: list[Decorated], bar: _Bar, accidentals: _Accidentals
) -> str:
    """A line of music rewritten (see :func:`music_rewritten`); each note and chord appended
    to ``events`` with the decorations before it (a rest or a bar line drops those before
    it). ``bar`` follows the line's inline meter and length fields, ``accidentals`` the
    voice's accidentals, written out on the notes that carry them."""
    out: list[str] = []
    pending: list[str] = []
    grace = False
    i, n = 0, len(line)
    while i < n:
        char = line[i]
        if char == "%":
            out.append(line[i:])
            break
        if char == '"':  # a chord symbol, kept; an annotation ("^text", ">text"), left out
            end = line.find('"', i + 1)
            end = n - 1 if end < 0 else end
            if line[i + 1 : i + 2] not in ("^", "_", "<", ">", "@"):
                out.append(line[i : end + 1])
            i = end + 1
            continue
        if line.startswith("::", i) and not (out and out[-1] in "|:"):
            if line[i + 2 : i + 3] not in ("|", ":"):
                out.append(":|:")  # music21 loses the notes around a bare "::"
                pending = []
                accidentals.bar()
                i += 2
                continue
        if char in "!+":
            end = line.find(char, i + 1)
            name = line[i + 1 : end] if end > i else ""
            if name in _HAIRPINS:
                out.append(f"!{_HAIRPINS[name]}!")
                i = end + 1
                continue
            if name in _PLAYED or name in _DROPPED:
                pending.append(name)
                i = end + 1
                continue
            if end > i:  # another decoration (a segno, "D.C."), kept for music21 to skip
                out.append(line[i : end + 1])
                i = end + 1
                continue
        if char in _SHORTHAND and _SHORTHAND[char] in {*_PLAYED, *_DROPPED}:
            rest = re.sub(r"^(?:[.~HLMOPSTuv]|![^!]*!|\+[^+]*\+)*", "", line[i + 1 :])
            if _EVENT_START.match(rest):
                pending.append(_SHORTHAND[char])
                i += 1
                continue
        if char == "[" and re.match(r"\[[A-Za-z]:", line[i:]):  # an inline field
            end = line.find("]", i)
            end = n - 1 if end < 0 else end
            bar.read_field(line[i + 1 : end])
            out.append(line[i : end + 1])
            i = end + 1
            continue
        if char in "ZX" and bar.units() is not None:  # a rest of whole bars: one per bar
            count = re.match(r"\d*", line[i + 1 :])
            digits = count[0] if count else ""
            out.append("|".join([f"z{bar.units()}"] * max(1, int(digits or 1))))
            pending = []
            accidentals.bar()
            i += 1 + len(digits)
            continue
        if char == "x":  # an invisible rest: a rest all the same
            char = "z"
        if char == "[" and _EVENT_START.match(line[i:]):  # a chord
            end = line.find("]", i)
            end = n - 1 if end < 0 else end
            inside = re.sub(r"[.~HLMOPSTuv]|![^!]*!", "", line[i + 1 : end])
            steps = tuple(sorted(c.upper() for c in re.findall(r"[A-Ga-g]", inside)))
            events.append(Decorated(steps, grace, tuple(pending)))
            pending = []
            tied = re.match(r"[\d/]*-", line[end + 1 :]) is not None
            out.append(accidentals.chord(inside, tied).join("[]"))
            i = end + 1
            continue
        note = _NOTE.match(line, i) if char in "^_=ABCDEFGabcdefg" else None
        if note:
            events.append(Decorated((note[2].upper(),), grace, tuple(pending)))
            pending = []
            tied = re.match(r"[\d/]*-", line[note.end() :]) is not None
            out.append(accidentals.note(note, tied))
            i = note.end()
            continue
        if char in "{}":
            grace = char == "{"
        elif char in "zxZXy|:":
            pending = []  # a rest's or a bar line's decorations are not read
            if char == "|":
                accidentals.bar()
        out.append(char)
        i += 1
    return "".join(out)


def put_decorations(score: Any, voices: list[list[Decorated]], path: Path) -> None:
    """Put the decorations :func:`music_rewritten` took out of a tune on the notes and
    chords music21 parsed from it (``score``), in place: voice by voice, the k-th note of a
    voice's text on music21's k-th note of the part. A voice whose notes music21 read
    differently (their number or letters) keeps none, with a warning."""
    played = [[sum(name in _PLAYED for name in e.names) for e in events] for events in voices]
    if not any(map(any, played)):
        return
    from music21 import articulations, dynamics, expressions

    modules = {"expressions": expressions, "articulations": articulations}
    parts = list(getattr(score, "parts", ())) or [score]
    if len(parts) != len(voices):  # music21 made other parts of the voices
        parts, lost = [], sum(map(sum, played))
    else:
        lost = 0
    for part, events, counts in zip(parts, voices, played, strict=False):
        notes = [n for n in part.recurse().notes if "Harmony" not in n.classes]
        read = [(tuple(sorted(p.step for p in n.pitches)), bool(n.duration.isGrace)) for n in notes]
        if read != [(e.steps, e.grace) for e in events]:
            lost += sum(counts)
            continue
        for element, event in zip(notes, events, strict=True):
            for name in event.names:
                if name in _DROPPED:
                    continue
                module, kind = _PLAYED[name]
                if module == "dynamics":
                    element.activeSite.insert(element.offset, dynamics.Dynamic(kind))
                    continue
                mark = getattr(modules[module], kind)()
                if name == "roll":  # an Irish roll: the note, then a turn around it
                    mark.delay = expressions.OrnamentDelay.DEFAULT_DELAY
                if module == "articulations":
                    element.articulations.append(mark)
                else:
                    element.expressions.append(mark)
    if lost:
        warnings.warn(
            f"{path}: {lost} ABC decoration(s) (ornaments, articulations, dynamics) left out: "
            "music21 read the notes of their voice differently from the text",
            stacklevel=4,
        )
