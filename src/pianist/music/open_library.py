"""The open song library: the ``open-etude-12`` benchmark suite, shipped with the package.

Twelve public-domain keyboard pieces, both hands, every note fingered, each a fixed segment
(20-40 s) so that results compare between users. They are PIG-format files in
``pianist/music/data/open/`` with ``provenance.json`` beside them: for each piece the
composer, the source encoding (the music21 corpus), its licence, the segment (measures and
seconds of the source at its marked tempo) and how the fingering was made. The files are
rebuilt by ``scripts/build_open_library.py`` (needs music21, which is not a dependency).
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources
from typing import Any

from pianist.music.errors import MusicError, UnknownSongError
from pianist.music.notes import Song
from pianist.music.pig import read_pig

OPEN_SUITE = "open-etude-12"
_DATA_PACKAGE = "pianist.music"
_DATA_PATH = ("data", "open")
PROVENANCE_FILE = "provenance.json"


def _data_dir() -> Any:
    root = resources.files(_DATA_PACKAGE)
    for part in _DATA_PATH:
        root = root / part
    return root


@lru_cache(maxsize=1)
def provenance() -> dict[str, Any]:
    """The suite's provenance record (``provenance.json``): suite info and one entry per piece.

    Raises:
        MusicError: the package data is missing (a broken installation).
    """
    path = _data_dir() / PROVENANCE_FILE
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise MusicError(
            f"the open song library is missing from this installation ({exc}); reinstall pianist"
        ) from exc
    return record


def list_open_songs() -> list[str]:
    """Names of the ``open-etude-12`` pieces, in suite order."""
    return [piece["name"] for piece in provenance()["pieces"]]


def open_song_info(name: str) -> dict[str, Any]:
    """Provenance entry of piece ``name`` (title, composer, source, licence, segment, ...).

    Raises:
        UnknownSongError: ``name`` is not in the suite.
    """
    for piece in provenance()["pieces"]:
        if piece["name"] == name:
            return dict(piece)
    raise UnknownSongError(f"{name!r} is not a piece of {OPEN_SUITE}")


def load_open_song(name: str) -> Song:
    """Load piece ``name`` of ``open-etude-12`` (fully fingered, both hands).

    Raises:
        UnknownSongError: ``name`` is not in the suite.
    """
    info = open_song_info(name)
    source = _data_dir() / info["file"]
    with resources.as_file(source) as path:
        song = read_pig(path)
    return Song(song.notes, song.sustain, name=name)
