"""ABC tunes rewritten into the shapes music21 reads as they are meant.

music21's ABC reader misreads some common, valid ABC; before it parses a tune, its text is
rewritten here into an equivalent form it reads right:

- **Voices.** A tune for two hands is usually written in voices that take turns, a line or
  a few bars each (``V:1`` ... ``V:2`` ... ``V:1`` ..., or ``[V:RH]`` at a line's start).
  music21 starts a new part at every ``V:`` line, so the same voice's second turn plays at
  the same time as its first, and it reads no ``[V:...]`` field, so all voices play one after
  the other; it also takes a ``V:`` only where the voice's name starts with a digit. Each
  voice's turns are gathered into one block, named 1, 2, ... in the order the voices first
  appear (their properties kept).
- **The fermata shorthand.** music21 drops the note after ``H`` (ABC's shorthand for a
  fermata), shifting every later note of its voice a note early; each ``H`` in the music is
  written out as ``!fermata!``.
"""

from __future__ import annotations

import re
from pathlib import Path

#: A field line (``X:``, ``K:``, ``V:``, ``w:``, ...).
_FIELD = re.compile(r"[A-Za-z+]:")
#: A voice field line: the voice's name and its properties (``V:RH clef=treble``).
_VOICE_LINE = re.compile(r"V:\s*(\S+)[ \t]*(.*)")
#: An inline voice field (``[V:RH]``, ``[V: 2 clef=bass]``).
_INLINE_VOICE = re.compile(r"\[V:\s*([^\]\s]+)[ \t]*([^\]]*)\]")


def reference_numbers(text: str) -> list[int]:
    """The reference numbers (``X:`` fields) of the tunes in an ABC file's text, in order."""
    return [int(m[1]) for m in re.finditer(r"^X:\s*(\d+)", text, flags=re.MULTILINE)]


def abc_for_music21(path: Path) -> str | None:
    """The text of the ABC file at ``path`` with every tune rewritten as the module docstring
    says; None where nothing needs rewriting."""
    text = path.read_text(encoding="utf-8", errors="replace")
    # A book's tunes each start at an X: field; the text before the first is the book's.
    starts = [m.start() for m in re.finditer(r"^X:", text, flags=re.MULTILINE)] or [0]
    pieces = [text[: starts[0]]] + [
        text[a:b] for a, b in zip(starts, [*starts[1:], len(text)], strict=True)
    ]
    rewritten = [pieces[0]] + [
        shorthand_fermatas_written_out(voices_in_blocks(tune)) for tune in pieces[1:]
    ]
    changed = "".join(rewritten)
    return changed if changed != text else None


def voices_in_blocks(tune: str) -> str:
    """One tune's text with each voice's turns gathered into one ``V:`` block, the voices
    named 1, 2, ... in the order they first appear (their declarations in the header, which
    music21 would read as voices of their own, dropped; their properties kept); the tune as
    it is where it has fewer than two voices, or music before its first voice field."""
    lines = tune.splitlines(keepends=True)
    key = next((i for i, line in enumerate(lines) if line.startswith("K:")), None)
    if key is None:
        return tune
    header: list[str] = []
    declared: dict[str, str] = {}  # a voice's properties, from the header or its first field
    for line in lines[: key + 1]:
        voice = _VOICE_LINE.match(line)
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
        voice = _VOICE_LINE.match(line)
        if voice:
            start(voice[1], voice[2].strip())
            continue
        fields = list(_INLINE_VOICE.finditer(line)) if not _FIELD.match(line) else []
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
        line.strip() and not _FIELD.match(line) and not line.startswith("%") for line in before
    ):
        return tune  # one voice, or music before the first voice field (a voice unnamed)
    out = header + before
    for number, name in enumerate(names, start=1):
        properties = declared.get(name, "")
        out.append(f"V:{number}" + (f" {properties}" if properties else "") + "\n")
        out.extend(blocks[name])
    return "".join(out)


def shorthand_fermatas_written_out(tune: str) -> str:
    """One tune's text with each fermata written as the shorthand ``H`` (``HE``: E under a
    fermata) written out (``!fermata!E``), which music21 reads without losing the note.

    Only the music is changed: field lines (``X:``, ``H:``...), comments, quoted text,
    decorations (``!...!``, ``+...+``) and inline fields (``[K:...]``) are kept as they are."""
    lines = tune.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if _FIELD.match(line) or "H" not in line:
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
