"""Finding a score's file, and music21's parse of it (its format from the suffix, an ABC
book's tunes, the forms of a file music21 would misread written as it reads them)."""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple

from pianist.music.errors import MusicError, one_line
from pianist.music.fileio import require_file
from pianist.music.musicxml.abc import abc_for_music21, reference_numbers
from pianist.music.musicxml.abc_lines import Decorated, put_decorations
from pianist.music.musicxml.humdrum import SectionOrder, section_order
from pianist.music.musicxml.mei import put_control_events

#: File suffixes read as MusicXML (``.mxl`` is the compressed form).
MUSICXML_SUFFIXES = (".musicxml", ".mxl", ".xml")


#: File suffixes of every score :func:`~pianist.music.musicxml.read_score` reads: MusicXML,
#: Humdrum ``**kern``, ABC and MEI (the Music Encoding Initiative's).
SCORE_SUFFIXES = (*MUSICXML_SUFFIXES, ".krn", ".abc", ".mei")


#: Per suffix, music21's name of the format and the name messages give it.
_FORMATS = {
    **{suffix: ("musicxml", "MusicXML") for suffix in MUSICXML_SUFFIXES},
    ".krn": ("humdrum", "Humdrum **kern"),
    ".abc": ("abc", "ABC"),
    ".mei": ("mei", "MEI"),
}


class OpenScore(NamedTuple):
    """A score file as :func:`open_score` opens it."""

    #: The score's file (a ``BOOK.abc#X`` reference resolved).
    path: Path
    #: The ABC tune read (None for one tune or another format).
    tune: int | None
    #: music21's parse of it.
    score: Any
    #: A Humdrum score's measures in the order its sections are played
    #: (:func:`pianist.music.musicxml.humdrum.section_order`); None for other scores.
    sections: SectionOrder | None
    #: Per part, the staff (an ABC voice) it was written in, where some parts share one (an
    #: ABC overlay's part); None otherwise.
    staves: list[int] | None


def open_score(path: str | os.PathLike[str]) -> OpenScore:
    """Find, check and parse a score file (see :class:`OpenScore`)."""
    reference = None if Path(path).exists() else tune_reference(os.fspath(path))
    path, tune = reference if reference is not None else (Path(path), None)
    music21_format, kind = _FORMATS.get(path.suffix.lower(), _FORMATS[".musicxml"])
    require_file(path, MusicError, f"{kind} file")
    score, tune, staves = _parse(path, tune, music21_format, kind)
    sections = None
    if music21_format == "humdrum":
        sections = section_order(path.read_text(encoding="utf-8", errors="replace"))
    return OpenScore(path, tune, score, sections, staves)


def _parse(
    path: Path, tune: int | None, music21_format: str, kind: str
) -> tuple[Any, int | None, list[int] | None]:
    """The score music21 parses from ``path`` in ``music21_format`` (``kind`` names it in
    messages), the reference number of the ABC tune read (``tune``, or a book's first: only
    that tune is parsed; None for one tune or another format), and :attr:`OpenScore.staves`.

    Raises:
        MusicError: music21 missing, or the file not of its format.
    """
    try:
        from music21 import converter
    except ImportError:
        raise MusicError(
            f"{path}: reading {kind} needs music21 (pip install 'pianist[musicxml]')"
        ) from None
    book: list[int] = []  # an ABC book's reference numbers, when no tune is named
    if music21_format == "abc" and tune is None:
        book = reference_numbers(path.read_text(encoding="utf-8", errors="replace"))
        tune = book[0] if len(book) > 1 else None  # music21 then parses that tune alone
    try:
        options = {} if tune is None else {"number": tune}
        source: str = str(path)
        decorations: list[list[Decorated]] = []  # an ABC tune's, put on its notes after
        staves: list[int] | None = None
        if path.suffix.lower() in (".musicxml", ".xml"):
            source = _partwise(path.read_bytes()) or source  # music21 reads partwise only
        if music21_format == "abc":
            rewritten = abc_for_music21(path, tune)
            source, decorations = rewritten.text or source, rewritten.decorations
            staves = rewritten.staves
        score = converter.parse(source, format=music21_format, forceSource=True, **options)
    except Exception as exc:  # music21 raises many types for a file it cannot read
        raise MusicError(f"{path}: not a readable {kind} score ({one_line(exc)})") from None
    tunes = list(getattr(score, "scores", ()))  # music21 parses several tunes into an Opus
    score = tunes[0] if tunes else score
    with as_music_error(path):
        put_decorations(score, decorations, path)
        if music21_format == "mei":
            put_control_events(score, path)
    if len(book) > 1:
        title = getattr(score.metadata, "title", None) if score.metadata else None
        warnings.warn(
            f"{path}: a book of {len(book)} tunes; the first"
            + (f", {title!r}," if title else "")
            + f" is read (name another as {path.name}#X, X its reference number)",
            stacklevel=3,
        )
    return score, tune, staves


#: The encodings a MusicXML file comes in (music21's corpus holds UTF-16 ones).
_ENCODINGS = ("utf-8", "utf-16-le", "utf-16-be")


def _partwise(document: bytes) -> str | None:
    """A ``score-timewise`` MusicXML document (measures holding parts) turned into the
    ``score-partwise`` one music21 reads (parts holding measures); None for any other
    document, or one that is not XML (music21 then says what is wrong with it)."""
    import xml.etree.ElementTree as ET

    head = document[:65536]  # the root element's name, in UTF-8 or UTF-16
    if not any("score-timewise".encode(encoding) in head for encoding in _ENCODINGS):
        return None
    try:
        root = ET.fromstring(document)
    except ET.ParseError:
        return None
    if root.tag != "score-timewise":
        return None
    partwise = ET.Element("score-partwise", root.attrib)
    parts: dict[str, ET.Element] = {}
    for child in root:
        if child.tag != "measure":  # the header: work, identification, part-list, ...
            partwise.append(child)
            continue
        for part in child.findall("part"):
            measure = ET.SubElement(
                parts.setdefault(part.get("id", ""), ET.Element("part", part.attrib)),
                "measure",
                child.attrib,
            )
            measure.extend(list(part))
    partwise.extend(parts.values())
    return ET.tostring(partwise, encoding="unicode")


def tune_reference(text: str) -> tuple[Path, int] | None:
    """``BOOK.abc#X`` names the tune of reference number X (its ``X:`` field) in an ABC book:
    (the book's path, X); None for any other text."""
    match = re.fullmatch(r"(.+\.abc)#(\d+)", text, flags=re.IGNORECASE)
    return (Path(match[1]), int(match[2])) if match else None


@contextmanager
def as_music_error(path: Path) -> Iterator[None]:
    """Turn a failure inside music21's parsed score into a :class:`MusicError` naming the
    file: music21 parses many files into shapes that no reader of it can foresee."""
    try:
        yield
    except MusicError:
        raise
    except Exception as exc:
        raise MusicError(
            f"{path}: a score this reader cannot follow ({type(exc).__name__}: {one_line(exc)})"
        ) from exc
