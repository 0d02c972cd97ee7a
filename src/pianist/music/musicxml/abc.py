"""ABC tunes rewritten into the shapes music21 reads as they are meant.

- **The fermata shorthand.** music21 drops the note after ``H`` (ABC's shorthand for a
  fermata), shifting every later note of its voice a note early; each ``H`` in the music is
  written out as ``!fermata!``.
"""

from __future__ import annotations

import re
from pathlib import Path

#: A field line (``X:``, ``K:``, ``V:``, ``w:``, ...).
_FIELD = re.compile(r"[A-Za-z+]:")


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
    rewritten = [pieces[0]] + [shorthand_fermatas_written_out(tune) for tune in pieces[1:]]
    changed = "".join(rewritten)
    return changed if changed != text else None


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
