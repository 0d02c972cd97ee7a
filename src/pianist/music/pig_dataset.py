"""Import a user's copy of the PIG fingering dataset, so that the paper's song names resolve.

PIG (Nakamura et al.) cannot be redistributed: users register, download
``PianoFingeringDataset_v1.2.zip`` and unpack it. :func:`import_pig` reads that folder (its
``FingeringFiles/NNN-M_fingering.txt`` and ``List.csv``), checks every file, and writes the
songs as PIG files plus an ``index.json`` into the PIG folder, :func:`pig_data_dir`:
``$PIANIST_PIG``, else ``pig/`` in the user data directory (``$PIANIST_DATA``, else
``$XDG_DATA_HOME/pianist``, else ``~/.local/share/pianist``). Songs are looked up in that same
folder, so an import into another folder (``dest_dir``, ``pianist import-pig --dest``) is used
by pointing ``$PIANIST_PIG`` at it; the import's summary says so, with the exact line.

Names follow the original RoboPianist: the first fingering version (lowest ``M``) of each
piece, named from List.csv's piece title in CamelCase (``FrenchSuiteNo1Allemande``).
RoboPianist-repertoire-150 is every piece, RoboPianist-etude-12 the 12 pieces of
:data:`ETUDE_12`. :func:`load_pig_song` accepts the plain name, the gym-style ids
``RoboPianist-etude-12-<Name>-v0`` / ``RoboPianist-repertoire-150-<Name>-v0`` and
``pig-NNN`` / ``pig-NNN-M``.

Known broken pieces (the original's issue #7 and :func:`check_playability`) are recorded in the
index and :func:`import_pig`'s report, and loading one warns (``UserWarning``) with its
problems rather than using it silently.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shlex
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pianist.files import write_text_atomic
from pianist.music.errors import MusicError, UnknownSongError, one_line
from pianist.music.fingering import assign_fingering
from pianist.music.notes import Song
from pianist.music.pig import read_pig, write_pig
from pianist.music.playability import check_playability

ETUDE_12 = (
    "FrenchSuiteNo1Allemande",
    "FrenchSuiteNo5Sarabande",
    "PianoSonataD8451StMov",
    "PartitaNo26",
    "WaltzOp64No1",
    "BagatelleOp3No4",
    "KreislerianaOp16No8",
    "FrenchSuiteNo5Gavotte",
    "PianoSonataNo232NdMov",
    "GolliwoggsCakewalk",
    "PianoSonataNo21StMov",
    "PianoSonataK279InCMajor1StMov",
)
PIG_SUITES = ("etude-12", "repertoire-150")
#: Problems reported by users of the original (its issue #7), by a word of the piece's name.
KNOWN_ISSUES = {
    "Nocturne": "reported with a wrong tempo (RoboPianist issue #7)",
    "Gymnop": "sustain pedal baked into note lengths (RoboPianist issue #7)",
}
INDEX_NAME = "index.json"
_FILE_RE = re.compile(r"^(\d{3})-(\d+)_fingering\.txt$")
_ID_RE = re.compile(r"^pig-(\d{1,3})(?:-(\d+))?$", re.IGNORECASE)
_GYM_RE = re.compile(r"^RoboPianist-(etude-12|repertoire-150)-(\w+?)(?:-v\d+)?$")


class PigDatasetError(MusicError):
    """The PIG dataset folder is missing, incomplete or malformed, or not imported yet."""


def user_data_dir() -> Path:
    """Where pianist keeps user data: ``$PIANIST_DATA``, ``$XDG_DATA_HOME/pianist`` or
    ``~/.local/share/pianist`` (the first that is set)."""
    if os.environ.get("PIANIST_DATA"):
        return Path(os.environ["PIANIST_DATA"]).expanduser()
    xdg = os.environ.get("XDG_DATA_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".local" / "share"
    return base / "pianist"


#: Environment variable naming the folder of the imported PIG songs (where they are looked up).
PIG_DIR_ENV = "PIANIST_PIG"


def pig_data_dir() -> Path:
    """Folder the imported PIG songs are written to by default and looked up in:
    ``$PIANIST_PIG``, else ``<user data dir>/pig``."""
    if os.environ.get(PIG_DIR_ENV):
        return Path(os.environ[PIG_DIR_ENV]).expanduser()
    return user_data_dir() / "pig"


def _not_imported(what: str) -> str:
    """The message for a PIG name or suite asked for before an import is found."""
    return (
        f"{what}: no imported PIG dataset in {pig_data_dir()}; register and download PIG, then "
        f"run `pianist import-pig DIR` once (for an import made with --dest D, set "
        f"{PIG_DIR_ENV}=D)"
    )


def piece_name(title: str) -> str:
    """List.csv piece title -> RoboPianist name, e.g. "Piano Sonata No.23 2nd mov" ->
    ``PianoSonataNo232NdMov`` (words title-cased, everything but letters and digits dropped)."""
    words = re.sub(r"[^0-9a-z]+", " ", title.replace("'", "").replace(".", "").lower()).split()
    # str.title() capitalises after digits too ("2nd" -> "2Nd"), as the original names do.
    return "".join(word.title() for word in words)


@dataclass
class PigPiece:
    """One imported fingering file."""

    id: int
    version: int
    file: str
    title: str
    composer: str
    name: str | None
    """The RoboPianist name (first version of the piece only, else None)."""
    num_notes: int
    duration_s: float
    problems: list[str] = field(default_factory=list)


@dataclass
class PigImportReport:
    """What :func:`import_pig` did."""

    dest_dir: Path
    pieces: list[PigPiece]
    missing_etude: list[str]
    skipped: list[str]
    """Files that could not be read (only with ``strict=False``), one line each."""

    @property
    def named(self) -> list[PigPiece]:
        return [p for p in self.pieces if p.name is not None]

    @property
    def with_problems(self) -> list[PigPiece]:
        return [p for p in self.named if p.problems]

    def summary(self) -> str:
        """A few lines for the command line; when the songs went elsewhere than where they are
        looked up (:func:`pig_data_dir`), the last lines give the variable to set."""
        lines = [
            f"imported {len(self.pieces)} PIG fingering files ({len(self.named)} pieces) into "
            f"{self.dest_dir}",
            f"etude-12: {12 - len(self.missing_etude)}/12 pieces"
            + (f" (missing: {', '.join(self.missing_etude)})" if self.missing_etude else ""),
        ]
        for piece in self.with_problems:
            lines.append(f"warning: {piece.name} ({piece.file}): {'; '.join(piece.problems)}")
        for line in self.skipped:
            lines.append(f"skipped: {line}")
        lookup = pig_data_dir()
        if _same_dir(self.dest_dir, lookup):
            return "\n".join(lines)
        lines += [
            f"songs are looked up in {lookup}: to use these, set {PIG_DIR_ENV} to their folder,",
            f"  export {PIG_DIR_ENV}={shlex.quote(str(self.dest_dir.resolve()))}",
        ]
        return "\n".join(lines)


def _same_dir(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def _find_fingering_dir(src: Path) -> Path:
    for candidate in (src / "FingeringFiles", src):
        if candidate.is_dir() and any(_FILE_RE.match(p.name) for p in candidate.iterdir()):
            return candidate
    raise PigDatasetError(
        f"{src}: no PIG fingering files (NNN-M_fingering.txt) here or in {src / 'FingeringFiles'};"
        " give the unpacked PianoFingeringDataset_v1.2 folder"
    )


def _read_list(src: Path, fingering_dir: Path) -> dict[int, tuple[str, str]]:
    """List.csv -> {piece id: (title, composer)}."""
    candidates = [src / "List.csv", fingering_dir / "List.csv", fingering_dir.parent / "List.csv"]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise PigDatasetError(
            f"{src}: List.csv not found (looked in {', '.join(str(p.parent) for p in candidates)});"
            " it names the pieces and comes with the dataset"
        )
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise PigDatasetError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise PigDatasetError(f"{path}: empty")
    header = [h.strip().lower() for h in rows[0]]
    if "piece" not in header:
        raise PigDatasetError(f"{path}: no 'Piece' column in the header {rows[0]}")
    piece_col = header.index("piece")
    composer_col = header.index("composer") if "composer" in header else None
    id_col = next((header.index(h) for h in ("id", "no", "no.", "number") if h in header), None)
    found: dict[int, tuple[str, str]] = {}
    for line_number, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        try:
            title = row[piece_col].strip()
            composer = row[composer_col].strip() if composer_col is not None else ""
            piece_id = int(row[id_col]) if id_col is not None else line_number - 1
        except (IndexError, ValueError):
            raise PigDatasetError(f"{path}:{line_number}: malformed row {row}") from None
        found[piece_id] = (title, composer)
    return found


def import_pig(
    src_dir: str | os.PathLike[str],
    dest_dir: str | os.PathLike[str] | None = None,
    *,
    strict: bool = True,
) -> PigImportReport:
    """Convert the PIG dataset at ``src_dir`` into pianist songs in ``dest_dir``.

    Args:
        src_dir: the unpacked ``PianoFingeringDataset_v1.2`` folder (holding
            ``FingeringFiles/`` and ``List.csv``), or its ``FingeringFiles`` folder with
            ``List.csv`` beside or inside it.
        dest_dir: where to write; default :func:`pig_data_dir`, where songs are looked up
            (elsewhere, set ``$PIANIST_PIG`` to it to use the songs). Any earlier import there
            is replaced once every file has been read (the index written last, atomically):
            an import that fails on a file leaves the earlier one as it was.
        strict: raise on the first unreadable fingering file (default); with False, skip it
            and list it in the report.
    Returns:
        A :class:`PigImportReport` (pieces, missing etude-12 pieces, problems found).

    Raises:
        PigDatasetError: ``src_dir`` is not a directory, holds no fingering files, or
            List.csv is missing or malformed.
        PigFormatError: a fingering file is malformed (file and line in the message), with
            ``strict=True``.
    """
    src = Path(src_dir).expanduser()
    if not src.exists():
        raise PigDatasetError(f"{src}: no such directory")
    if not src.is_dir():
        raise PigDatasetError(f"{src}: not a directory (unpack the PIG zip file first)")
    fingering_dir = _find_fingering_dir(src)
    titles = _read_list(src, fingering_dir)
    dest = Path(dest_dir).expanduser() if dest_dir is not None else pig_data_dir()
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PigDatasetError(f"{dest}: cannot create ({exc.strerror or exc})") from exc

    files = sorted(
        (int(m.group(1)), int(m.group(2)), p)
        for p in fingering_dir.iterdir()
        if (m := _FILE_RE.match(p.name))
    )
    pieces: list[PigPiece] = []
    converted: list[tuple[str, Song]] = []  # written once every file has been read
    skipped: list[str] = []
    named: set[int] = set()
    used_names: set[str] = set()
    for piece_id, version, path in files:
        try:
            song = read_pig(path, out_of_range="drop")
        except MusicError as exc:
            if strict:
                raise
            skipped.append(one_line(exc))
            continue
        title, composer = titles.get(piece_id, ("", ""))
        name = None
        if piece_id not in named and title:
            name = piece_name(title)
            if name in used_names:  # two pieces with one title: keep both, number the second
                name = f"{name}{piece_id:03d}"
            named.add(piece_id)
            used_names.add(name)
        out_name = f"{piece_id:03d}-{version}.txt"
        problems = []
        unfingered = sum(n.finger is None for n in song.notes)
        if unfingered:  # PIG writes finger 0 for unlabelled notes; PIG files need a finger
            song = assign_fingering(song)
            problems.append(f"{unfingered} note(s) without a finger in the file, estimated")
        converted.append((out_name, Song(song.notes, name=name or out_name)))
        if name:
            problems += check_playability(song)
        if name:
            problems += [
                text for word, text in KNOWN_ISSUES.items() if word.lower() in name.lower()
            ]
        pieces.append(
            PigPiece(
                id=piece_id,
                version=version,
                file=out_name,
                title=title,
                composer=composer,
                name=name,
                num_notes=song.num_notes,
                duration_s=round(song.duration_s, 3),
                problems=problems,
            )
        )
    # Only now, with every file read (a strict import that fails writes nothing), the songs,
    # then the index that makes them visible.
    for out_name, converted_song in converted:
        write_pig(converted_song, dest / out_name)
    names = {p.name for p in pieces if p.name}
    index = {
        "format": 1,
        "source": str(src.resolve()),
        "etude_12": [n for n in ETUDE_12 if n in names],
        "pieces": [p.__dict__ for p in pieces],
    }
    write_text_atomic(json.dumps(index, indent=1) + "\n", dest / INDEX_NAME, error=PigDatasetError)
    return PigImportReport(
        dest_dir=dest,
        pieces=pieces,
        missing_etude=[n for n in ETUDE_12 if n not in names],
        skipped=skipped,
    )


def _load_index(dest: Path | None = None) -> dict[str, Any] | None:
    path = (dest if dest is not None else pig_data_dir()) / INDEX_NAME
    if not path.is_file():
        return None
    try:
        index = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PigDatasetError(
            f"{path}: unreadable PIG index ({one_line(exc)}); run `pianist import-pig DIR` again"
        ) from exc
    if not isinstance(index, dict) or not isinstance(index.get("pieces"), list):
        raise PigDatasetError(f"{path}: not a PIG index; run `pianist import-pig DIR` again")
    return index


def is_pig_name(name: str) -> bool:
    """Whether ``name`` has the form of a PIG song name (gym id or ``pig-NNN``)."""
    return bool(_GYM_RE.match(name) or _ID_RE.match(name))


def _find(name: str, index: dict[str, Any]) -> dict[str, Any] | None:
    pieces = index["pieces"]
    gym = _GYM_RE.match(name)
    if gym:
        suite, plain = gym.groups()
        if suite == "etude-12" and plain not in ETUDE_12:
            return None
        name = plain
    numbered = _ID_RE.match(name)
    if numbered:
        piece_id, version = int(numbered.group(1)), numbered.group(2)
        for piece in pieces:
            if piece["id"] == piece_id and (
                piece["version"] == int(version) if version else piece["name"] is not None
            ):
                return piece
        return None
    return next((p for p in pieces if p["name"] == name), None)


def find_pig_song(name: str, dest: Path | None = None) -> Path | None:
    """Path of the imported PIG song ``name``, or None (not a PIG name, or not imported)."""
    index = _load_index(dest)
    if index is None:
        return None
    piece = _find(name, index)
    if piece is None:
        return None
    return (dest if dest is not None else pig_data_dir()) / piece["file"]


def load_pig_song(name: str, dest: Path | None = None) -> Song:
    """Load imported PIG song ``name`` (warns with its problems if it has known ones).

    Raises:
        PigDatasetError: PIG has not been imported (the message says how), or ``name`` is
            not one of its pieces.
    """
    index = _load_index(dest)
    if index is None:
        if dest is not None:
            raise PigDatasetError(f"{name!r}: no imported PIG dataset in {dest}")
        raise PigDatasetError(_not_imported(f"{name!r} is a PIG piece, which cannot be shipped"))
    piece = _find(name, index)
    if piece is None:
        raise UnknownSongError(f"{name!r} is not a piece of the imported PIG dataset")
    folder = dest if dest is not None else pig_data_dir()
    song = read_pig(folder / piece["file"])
    if piece.get("problems"):
        warnings.warn(
            f"PIG piece {piece.get('name') or piece['file']}: " + "; ".join(piece["problems"]),
            UserWarning,
            stacklevel=2,
        )
    return Song(song.notes, song.sustain, name=piece.get("name") or Path(piece["file"]).stem)


def list_pig_songs(suite: str = "repertoire-150", dest: Path | None = None) -> list[str]:
    """Names of the imported pieces of ``suite`` ("etude-12" or "repertoire-150").

    Raises:
        PigDatasetError: PIG has not been imported.
        ValueError: unknown suite.
    """
    if suite not in PIG_SUITES:
        raise ValueError(f"unknown PIG suite {suite!r}; use one of {', '.join(PIG_SUITES)}")
    index = _load_index(dest)
    if index is None:
        if dest is not None:
            raise PigDatasetError(f"suite {suite}: no imported PIG dataset in {dest}")
        raise PigDatasetError(_not_imported(f"suite {suite} needs the PIG dataset"))
    names = [p["name"] for p in index["pieces"] if p["name"]]
    if suite == "etude-12":
        return [n for n in ETUDE_12 if n in names]
    return names


def pig_dataset_imported() -> bool:
    """Whether an imported PIG dataset is found where songs are looked up."""
    return (pig_data_dir() / INDEX_NAME).is_file()


def pig_piece_info(name: str, dest: Path | None = None) -> dict[str, Any] | None:
    """The index entry (id, version, title, composer, problems, ...) of ``name``, or None."""
    index = _load_index(dest)
    return None if index is None else _find(name, index)


__all__ = [
    "ETUDE_12",
    "PIG_DIR_ENV",
    "PIG_SUITES",
    "PigDatasetError",
    "PigImportReport",
    "PigPiece",
    "find_pig_song",
    "import_pig",
    "is_pig_name",
    "list_pig_songs",
    "load_pig_song",
    "pig_data_dir",
    "pig_dataset_imported",
    "pig_piece_info",
    "piece_name",
    "user_data_dir",
]
