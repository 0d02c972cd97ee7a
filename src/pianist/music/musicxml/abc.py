"""ABC tunes rewritten into the shapes music21 reads as they are meant.

music21's ABC reader misreads some common, valid ABC; before it parses a tune, its text is
rewritten here into an equivalent form it reads right:

- **Voices.** A tune for two hands is usually written in voices that take turns, a line or
  a few bars each (``V:1`` ... ``V:2`` ... ``V:1`` ..., or ``[V:RH]`` at a line's start).
  music21 starts a new part at every ``V:`` line, so the same voice's second turn plays at
  the same time as its first, and it reads no ``[V:...]`` field, so all voices play one after
  the other; it also takes a ``V:`` only where the voice's name starts with a digit. Each
  voice's turns are gathered into one block, named 1, 2, ... in the order the voices first
  appear (their properties kept). A ``%%score`` directive's staves (``{(S A) | B}``) say
  which voices share a staff, and so a hand.
- **Overlays.** ``&`` lays a second voice over a bar (``c2 d2 & C4``); music21 plays the
  overlay after the bar's notes, so that bar lasts twice as long and every later note comes
  late. Each overlay becomes a voice of its own, silent (invisible rests of the same
  lengths) in the bars it has no notes.
- **The unit note length.** A tune with neither a metre (``M:``) nor a unit note length
  (``L:``) has, by the standard, eighths as its unit; music21 refuses it. ``L:1/8`` is
  written in its header.
- **Parts.** A tune's header can give the order its parts are played in (``P:ABA``, the
  ABC form of a da capo; ``P:A2B``, ``P:(AB)2C``), the body marking where each part starts
  (``P:A``); music21 plays the parts once each, as written. They are written out in their
  order.
- **The fermata shorthand.** music21 drops the note after ``H`` (ABC's shorthand for a
  fermata), shifting every later note of its voice a note early; each ``H`` in the music is
  written out as ``!fermata!``.
- **Decorations.** music21 reads no ABC decoration but the staccato dot, and that on single
  notes only; it reads ``M`` (a lower mordent) as a tenuto. The decorations a pianist plays
  are taken out of the text (:mod:`pianist.music.musicxml.abc_lines`, like the rewrites
  below) and put on music21's notes after it parses the tune: trills (``T``, ``!trill!``), lower and
  upper mordents (``M``, ``P``, ``!mordent!``, ``!uppermordent!``), turns (``!turn!``,
  ``!invertedturn!``; an Irish roll, ``~``, as a turn after the note), fermatas (``H``,
  ``!fermata!``), rolled chords (``!arpeggio!``), staccato (``.``), staccatissimo
  (``!wedge!``), accents (``L``, ``!>!``, ``!accent!``), tenuto, dynamics (``!p!``,
  ``!mf!``, ``!sfz!``, ...). Hairpins written ``!<(!`` ... ``!<)!`` are written as the
  ``!crescendo(!`` ... ``!crescendo)!`` music21 reads. Bowings (``u``, ``v``) are left
  out. A voice whose notes music21 reads differently from the text (it reads a note twice
  after two broken rhythms in slurs, for one) keeps none of its decorations, with a
  warning.
- **Repeats.** music21 loses the notes around a bare ``::`` (the end of one repeated section
  and the start of the next): it is written ``:|:``.
- **Rests.** music21 drops an invisible rest (``x``) and a rest of whole bars (``Z4``: four
  bars), and every later note of the voice comes that much early: they are written as rests
  (``z``; ``z8|z8|z8|z8`` in 4/4 with eighths as the unit).
- **Accidentals.** An accidental holds for its pitch (letter and octave) to the bar's end,
  and a tied note keeps its own over the bar line; music21 applies each to its own note
  only. The accidentals a note carries are written out on it.
- **Annotations.** Quoted text placed by its first character (``"^Slow"``, ``">2,1"``) is
  text for the reader; music21 takes it for a chord symbol, and drops the note after one that
  starts with ``>``. It is left out.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

from pianist.music.musicxml.abc_lines import (
    FIELD,
    VOICE_LINE,
    Decorated,
    header_end,
    music_rewritten,
)

#: An inline voice field (``[V:RH]``, ``[V: 2 clef=bass]``).
_INLINE_VOICE = re.compile(r"\[V:\s*([^\]\s]+)[ \t]*([^\]]*)\]")


def reference_numbers(text: str) -> list[int]:
    """The reference numbers (``X:`` fields) of the tunes in an ABC file's text, in order."""
    return [int(m[1]) for m in re.finditer(r"^X:\s*(\d+)", text, flags=re.MULTILINE)]


class AbcText(NamedTuple):
    """An ABC file's text as music21 should parse it (:func:`abc_for_music21`)."""

    #: The whole file's text, each tune rewritten; None where nothing needed rewriting.
    text: str | None
    #: Of the tune read, per voice (music21's parts, in order), its notes and chords and the
    #: decorations taken out of the text before each.
    decorations: list[list[Decorated]]
    #: Of the tune read, per voice, the staff it is on (0, 1, ... from the top): its
    #: ``%%score`` directive's, else each voice its own (an overlay its voice's); None
    #: where the tune has neither a directive nor an overlay.
    staves: list[int] | None = None


def abc_for_music21(path: Path, tune: int | None) -> AbcText:
    """The text of the ABC file at ``path`` with every tune rewritten as the module docstring
    says, and the decorations of tune ``tune`` (its reference number; None: the file's only or
    first tune) taken out of it."""
    text = path.read_text(encoding="utf-8", errors="replace")
    # A book's tunes each start at an X: field; the text before the first is the book's.
    starts = [m.start() for m in re.finditer(r"^X:", text, flags=re.MULTILINE)] or [0]
    pieces = [text[: starts[0]]] + [
        text[a:b] for a, b in zip(starts, [*starts[1:], len(text)], strict=True)
    ]
    rewritten = [pieces[0]]
    decorations: list[list[Decorated]] = []
    staves: list[int] | None = None
    for k, piece in enumerate(pieces[1:]):
        number = re.match(r"X:\s*(\d+)", piece)
        read = (k == 0) if tune is None else (number is not None and int(number[1]) == tune)
        # The blank lines that end a tune stay at its end, whatever moves before them.
        music = piece.rstrip()
        ending = piece[len(music) :]
        music = unit_length_given(parts_in_order(music + "\n"))
        music, written_on = voices_in_blocks(music)
        music, sources = overlays_as_voices(music)
        music, voices = music_rewritten(shorthand_fermatas_written_out(music))
        rewritten.append(music.rstrip("\n") + ending)
        if read:
            decorations, staves = voices, sources
            if written_on is not None:  # each voice's staff, and an overlay's its voice's
                staves = [written_on[v] for v in sources or range(len(written_on))]
    changed = "".join(rewritten)
    return AbcText(changed if changed != text else None, decorations, staves)


def unit_length_given(tune: str) -> str:
    """One tune's text with the unit note length ABC gives a tune of no metre and no ``L:``
    field (an eighth) written in its header, which music21 refuses to read without."""
    lines = tune.splitlines(keepends=True)
    key = header_end(lines)
    if key is None or any(line.startswith(("L:", "M:")) for line in lines[:key]):
        return tune
    return "".join([*lines[:key], "L:1/8\n", *lines[key:]])


def parts_in_order(tune: str) -> str:
    """One tune's text with its parts written out in the order its header's ``P:`` field
    gives (``P:ABA``: part A, part B, part A again; ``P:A2B``, ``P:(AB)2C``), each part's
    music from its ``P:`` line in the body to the next; the tune as it is where the header
    gives no order, or names a part the body does not mark."""
    lines = tune.splitlines(keepends=True)
    key = header_end(lines)
    header = [m for line in lines[: key or 0] if (m := re.match(r"P:([^%]*)", line))]
    order = _part_order(header[0][1]) if header and key is not None else None
    if not order:
        return tune
    assert key is not None
    before: list[str] = []  # the body before its first part
    parts: dict[str, list[str]] = {}
    current: list[str] = before
    for line in lines[key + 1 :]:
        label = re.match(r"P:\s*([A-Z])\s*(%.*)?$", line.strip())
        if label:
            current = parts.setdefault(label[1], [])
        elif line.strip():  # a blank line ends the tune: kept for its end only
            current.append(line if line.endswith("\n") else line + "\n")
    if not parts or any(name not in parts for name in order):
        return tune
    body = before + [line for name in order for line in parts[name]]
    end = "\n" if not lines[-1].strip() else ""
    return "".join(lines[: key + 1] + body) + end


def _part_order(text: str) -> str | None:
    """The parts a ``P:`` field's order plays, one letter each (``"A2(BC)2"``: ``"AABCBC"``);
    None where the text is not such an order (a title, a single part)."""
    text = re.sub(r"[\s.]", "", text)
    if not re.fullmatch(r"[A-Z0-9()]+", text) or len(set(re.sub(r"[^A-Z]", "", text))) < 2:
        return None
    while "(" in text:  # innermost groups first
        group = re.search(r"\(([A-Z]*)\)(\d*)", text)
        if group is None:
            return None
        text = text[: group.start()] + group[1] * int(group[2] or 1) + text[group.end() :]
    return re.sub(r"([A-Z])(\d+)", lambda m: m[1] * int(m[2]), text)


def voices_in_blocks(tune: str) -> tuple[str, list[int] | None]:
    """One tune's text with each voice's turns gathered into one ``V:`` block, the voices
    named 1, 2, ... in the order they first appear (their declarations in the header, which
    music21 would read as voices of their own, dropped; their properties kept); and per
    voice the staff its ``%%score`` directive puts it on (None without one, or where it
    leaves a voice out). The tune as it is, and None, where it has fewer than two voices, or
    music before its first voice field."""
    lines = tune.splitlines(keepends=True)
    key = header_end(lines)
    if key is None:
        return tune, None
    header: list[str] = []
    declared: dict[str, str] = {}  # a voice's properties, from the header or its first field
    for line in lines[: key + 1]:
        voice = VOICE_LINE.match(line)
        if voice:
            declared.setdefault(voice[1], voice[2].strip())
        else:
            header.append(line)
    blocks: dict[str, list[str]] = {}  # per voice, in order of first appearance
    current: str | None = None
    before: list[str] = []  # lines before the first voice: they stay with the header

    def start(name: str, properties: str) -> None:
        nonlocal current
        if properties and not declared.get(name):
            declared[name] = properties
        declared.setdefault(name, "")
        blocks.setdefault(name, [])
        current = name

    for line in lines[key + 1 :]:
        voice = VOICE_LINE.match(line)
        if voice:
            start(voice[1], voice[2].strip())
            continue
        fields = list(_INLINE_VOICE.finditer(line)) if not FIELD.match(line) else []
        # The line in pieces, each with the inline voice field it starts with (None: none).
        pieces: list[tuple[re.Match[str] | None, str]] = [(None, line)] if not fields else []
        if fields:
            if line[: fields[0].start()].strip():
                pieces.append((None, line[: fields[0].start()] + "\n"))
            for k, found in enumerate(fields):
                end = fields[k + 1].start() if k + 1 < len(fields) else len(line)
                pieces.append((found, line[found.end() : end].strip() + "\n"))
        for field, text in pieces:
            if field is not None:
                start(field[1], field[2].strip())
            if current is None:
                before.append(text)
            elif text.strip() or field is None:
                blocks[current].append(text)
    names = list(blocks)
    if len(names) < 2 or any(
        line.strip() and not FIELD.match(line) and not line.startswith("%") for line in before
    ):
        return tune, None  # one voice, or music before the first voice field (a voice unnamed)
    out = header + before
    for number, name in enumerate(names, start=1):
        properties = declared.get(name, "")
        out.append(f"V:{number}" + (f" {properties}" if properties else "") + "\n")
        out.extend(blocks[name])
    directives = [line for line in header + before if line.startswith(("%%score", "%%staves"))]
    staves = _staves(directives[-1], names) if directives else None
    return "".join(out), staves


def _staves(directive: str, names: list[str]) -> list[int] | None:
    """Per voice (``names``), the staff a ``%%score`` (or ``%%staves``) directive puts it on,
    counting from 0 at the top: each voice is a staff of its own, or one staff with the
    others in its parentheses (``%%score {(RH1 RH2) | LH}``: 0, 0, 1). None where it leaves
    a voice out."""
    tokens = re.findall(r"[(){}\[\]|]|[^\s(){}\[\]|]+", directive.split(None, 1)[-1])
    staff, grouped, placed = -1, False, {}
    for token in tokens[1:] if tokens and tokens[0].startswith("%%") else tokens:
        if token == "(":
            staff, grouped = staff + 1, True
        elif token == ")":
            grouped = False
        elif token not in "{}[]|":
            staff += 0 if grouped else 1
            placed[token] = staff
    return [placed[name] for name in names] if all(name in placed for name in names) else None


def overlays_as_voices(tune: str) -> tuple[str, list[int] | None]:
    """One tune's text with each voice's overlays (``&``) written as voices of their own,
    after the tune's voices (``V:`` blocks; a tune without any becomes voice 1), silent in
    the bars they have no notes; and per voice of it the voice it was written in (0, 1,
    ...). The tune as it is, and None, where it has no overlay, or music before its first
    voice field."""
    lines = tune.splitlines(keepends=True)
    key = header_end(lines)
    if key is None or not any(_segments(line)[1] for line in lines[key + 1 :] if _music(line)):
        return tune, None
    blocks: list[list[str]] = [[]]  # each voice's lines, its V: line first
    for line in lines[key + 1 :]:
        if VOICE_LINE.match(line):
            blocks.append([])
        blocks[-1].append(line)
    names = [VOICE_LINE.match(block[0]) for block in blocks[1:]]
    if names and any(_music(line) for line in blocks[0]):
        return tune, None
    if not names:
        blocks = [[], ["V:1\n", *blocks[0]]]
    out = lines[: key + 1] + blocks[0]
    voices = blocks[1:]
    for number, (block, name) in enumerate(zip(voices, names or [None], strict=True), start=1):
        # Named 1, 2, ...: music21 takes a voice only where its name starts with a digit.
        block[0] = f"V:{number}" + (f" {name[2].strip()}" if name and name[2].strip() else "")
        block[0] += "\n"
    number = len(voices)
    added: list[list[str]] = []
    sources = list(range(len(voices)))
    for source, block in enumerate(voices):
        split = [_segments(line) if _music(line) else None for line in block]
        layers = max((len(o) for s in split if s for _, o, _ in s[0]), default=0)
        out.extend(
            line if s is None else "".join(main for main, _, _ in s[0]) + "\n"
            for line, s in zip(block, split, strict=True)
        )
        for layer in range(layers):
            number += 1
            voice = [f"V:{number}\n"]
            for line, s in zip(block[1:], split[1:], strict=True):
                if s is None:
                    if re.match(r"[KLM]:", line):  # the key, unit length and metre go on
                        voice.append(line)
                    continue
                pieces = [
                    main if bar else overlays[layer] if layer < len(overlays) else _silent(main)
                    for main, overlays, bar in s[0]
                ]
                voice.append("".join(pieces) + "\n")
            added.append(voice)
            sources.append(source)
    return "".join(out + [line for voice in added for line in voice]), sources


def _music(line: str) -> bool:
    """Whether a line of a tune's body is music (not a field, a comment or blank)."""
    return bool(line.strip()) and not FIELD.match(line) and not line.startswith("%")


#: A bar line, with a repeat's colons and an ending's number (``|``, ``:|2``, ``[1``, ``::``).
_BAR_LINE = re.compile(r"\[?[|:]*\|[|:\]]*(?:\d[\d,\-]*)?|::|\[\d[\d,\-]*")
#: What ``&`` does not split: quoted text, decorations and inline fields.
_SPAN = re.compile(r'"[^"]*"?|![^!]*!|\+[^+]*\+|\[[A-Za-z]:[^\]]*\]?')


def _segments(line: str) -> tuple[list[tuple[str, list[str], bool]], list[int]]:
    """A line of music cut at its bar lines: per piece (a bar's part of the line, or a bar
    line) its text without overlays, its overlays' texts and whether it is a bar line; and
    where ``&`` is (empty: the line has no overlay)."""
    text = line.rstrip("\r\n")
    comment = text.find("%")
    text = text if comment < 0 else text[:comment]
    pieces: list[tuple[str, list[str], bool]] = []
    ampersands: list[int] = []
    start = i = 0
    while i < len(text):
        span = _SPAN.match(text, i)
        if span and span.end() > i:
            i = span.end()
            continue
        bar = _BAR_LINE.match(text, i)
        if bar and bar.end() > i:
            pieces.append(_overlaid(text[start:i], ampersands, start))
            pieces.append((bar[0], [], True))
            start = i = bar.end()
            continue
        if text[i] == "&":
            ampersands.append(i)
        i += 1
    pieces.append(_overlaid(text[start:], ampersands, start))
    return pieces, ampersands


def _overlaid(bar: str, ampersands: list[int], start: int) -> tuple[str, list[str], bool]:
    """A bar's text (from ``start`` in its line) as its own notes and its overlays' texts,
    cut at the ``&`` in it (``ampersands``: positions in the line)."""
    cuts = [a - start for a in ampersands if start <= a < start + len(bar)]
    if not cuts:
        return bar, [], False
    ends = [*cuts, len(bar)]
    overlays = [bar[a + 1 : b] for a, b in zip(cuts, ends[1:], strict=True)]
    return bar[: cuts[0]], overlays, False


def _silent(bar: str) -> str:
    """A bar's notes as invisible rests of the same lengths (``[CE]2 d/ (3efg`` becomes
    ``x2 x/ (3xxx``): decorations, quoted text, grace notes, ties and slurs left out, inline
    fields and rests of whole bars kept."""
    out: list[str] = []
    i = 0
    while i < len(bar):
        char = bar[i]
        span = _SPAN.match(bar, i)
        if span and span.end() > i:
            out.append(span[0] if span[0].startswith("[") else "")  # an inline field stays
            i = span.end()
            continue
        note = re.match(r"[\^_=]*[A-Ga-g][,']*|\[[^\]]*\]?|[zx]", bar[i:])
        if note:
            out.append("x")
            i += note.end()
            continue
        if char == "{":
            end = bar.find("}", i)
            i = len(bar) if end < 0 else end + 1
            continue
        if char == "(" and not bar[i + 1 : i + 2].isdigit() or char in ")-y.~HLMOPSTuv":
            i += 1
            continue
        out.append(char)
        i += 1
    return "".join(out)


def shorthand_fermatas_written_out(tune: str) -> str:
    """One tune's text with each fermata written as the shorthand ``H`` (``HE``: E under a
    fermata) written out (``!fermata!E``), which music21 reads without losing the note.

    Only the music is changed: field lines (``X:``, ``H:``...), comments, quoted text,
    decorations (``!...!``, ``+...+``) and inline fields (``[K:...]``) are kept as they are."""
    lines = tune.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if FIELD.match(line) or "H" not in line:
            continue
        out, closing = [], ""  # closing: the character that ends the span we are in
        for k, char in enumerate(line):
            if closing:
                closing = "" if char == closing else closing
            elif char == "%":
                out.append(line[k:])
                break
            elif char in '"!+':
                closing = char
            elif char == "[" and re.match(r"\[[A-Za-z]:", line[k:]):
                closing = "]"
            elif char == "H":
                out.append("!fermata!")
                continue
            out.append(char)
        lines[i] = "".join(out)
    return "".join(lines)
