"""Importing a PIG-format dataset (written here, never the real one) and resolving its names."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from pianist.cli import main
from pianist.music import (
    MusicError,
    PigDatasetError,
    UnknownSongError,
    import_pig,
    list_songs,
    load_song,
    user_data_dir,
)
from pianist.music.errors import PigFormatError
from pianist.music.pig_dataset import ETUDE_12, list_pig_songs, piece_name, pig_piece_info

HEADER = "//Version: PianoFingering_v170101\n"
SCALE = [("C4", 1), ("D4", 2), ("E4", 3), ("F4", 1), ("G4", 2)]


def _rows(notes: list[tuple[str, int]], channel: int = 0, start: float = 0.0) -> str:
    lines = []
    for i, (name, finger) in enumerate(notes):
        onset = start + 0.5 * i
        sign = finger if channel == 0 else -finger
        lines.append(f"{i}\t{onset:.4f}\t{onset + 0.5:.4f}\t{name}\t64\t80\t{channel}\t{sign}")
    return "\n".join(lines) + "\n"


def _dataset(root: Path, with_ids: bool = True) -> Path:
    """A tiny PIG layout: FingeringFiles/ and List.csv, three pieces, one with two versions."""
    files = root / "FingeringFiles"
    files.mkdir(parents=True)
    (files / "001-1_fingering.txt").write_text(HEADER + _rows(SCALE))
    (files / "001-2_fingering.txt").write_text(HEADER + _rows(SCALE[:3]))
    # Piece 2: a left-hand line plus a crowded right hand (six keys held, sustain baked in).
    crowded = "".join(
        f"{10 + i}\t0.0\t2.0\t{name}\t64\t80\t0\t{min(i + 1, 5)}\n"
        for i, name in enumerate(["C5", "D5", "E5", "F5", "G5", "A5"])
    )
    (files / "002-1_fingering.txt").write_text(HEADER + _rows(SCALE, channel=1) + crowded)
    (files / "003-1_fingering.txt").write_text(HEADER + _rows(SCALE[:2]) + "\n")
    (files / "notes.txt").write_text("not a fingering file")
    if with_ids:
        text = "Id,Composer,Piece\n1,Bach,French Suite No.1 Allemande\n2,Chopin,Nocturne No.1\n"
        text += "3,Debussy,Golliwogg's Cakewalk\n"
    else:
        text = "Composer,Piece\nBach,French Suite No.1 Allemande\nChopin,Nocturne No.1\n"
        text += "Debussy,Golliwogg's Cakewalk\n"
    (root / "List.csv").write_text(text)
    return root


@pytest.fixture
def data_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    home = tmp_path / "data"
    monkeypatch.setenv("PIANIST_DATA", str(home))
    monkeypatch.delenv("PIANIST_PIG", raising=False)
    return home


def test_piece_names_follow_robopianist() -> None:
    assert piece_name("French Suite No.1 Allemande") == "FrenchSuiteNo1Allemande"
    assert piece_name("Piano Sonata No.23 2nd mov") == "PianoSonataNo232NdMov"
    assert piece_name("Golliwogg's Cakewalk") == "GolliwoggsCakewalk"
    assert piece_name("Piano Sonata K.279 in C major 1st mov") == "PianoSonataK279InCMajor1StMov"


def test_user_data_dir_precedence(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv("PIANIST_DATA", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert user_data_dir() == tmp_path / "xdg" / "pianist"
    monkeypatch.delenv("XDG_DATA_HOME")
    assert user_data_dir() == Path.home() / ".local" / "share" / "pianist"
    monkeypatch.setenv("PIANIST_DATA", str(tmp_path / "mine"))
    assert user_data_dir() == tmp_path / "mine"


def test_before_import_names_explain_what_to_do(data_home: Path) -> None:
    with pytest.raises(PigDatasetError, match=f"in {data_home / 'pig'}.*PIANIST_PIG=D"):
        load_song("FrenchSuiteNo1Allemande")
    with pytest.raises(UnknownSongError, match="import-pig.*PIANIST_PIG=D"):
        load_song("NocturneNo1")  # not an etude-12 name: unknown, with the hint
    with pytest.raises(PigDatasetError, match="import-pig"):
        load_song("RoboPianist-etude-12-FrenchSuiteNo1Allemande-v0")
    with pytest.raises(PigDatasetError, match="import-pig"):
        load_song("FrenchSuiteNo1Allemande")
    with pytest.raises(PigDatasetError, match="import-pig"):
        list_songs("etude-12")


@pytest.mark.parametrize("with_ids", [True, False])
def test_import_round_trip(tmp_path: Path, data_home: Path, with_ids: bool) -> None:
    src = _dataset(tmp_path / "PianoFingeringDataset_v1.2", with_ids=with_ids)
    report = import_pig(src)
    assert report.dest_dir == data_home / "pig"
    assert [(p.id, p.version) for p in report.pieces] == [(1, 1), (1, 2), (2, 1), (3, 1)]
    assert [p.name for p in report.named] == [
        "FrenchSuiteNo1Allemande",
        "NocturneNo1",
        "GolliwoggsCakewalk",
    ]
    assert set(report.missing_etude) == set(ETUDE_12) - {
        "FrenchSuiteNo1Allemande",
        "GolliwoggsCakewalk",
    }
    assert "etude-12: 2/12" in report.summary()

    song = load_song("FrenchSuiteNo1Allemande")
    assert song.has_full_fingering and song.num_notes == 5
    assert [n.finger for n in song.notes] == [0, 1, 2, 0, 1]
    assert load_song("RoboPianist-etude-12-FrenchSuiteNo1Allemande-v0") == song
    assert load_song("RoboPianist-repertoire-150-FrenchSuiteNo1Allemande-v0") == song
    assert load_song("pig-001") == song
    assert load_song("pig-001-2").num_notes == 3
    assert list_songs("etude-12") == ["FrenchSuiteNo1Allemande", "GolliwoggsCakewalk"]
    assert list_songs("repertoire-150") == [
        "FrenchSuiteNo1Allemande",
        "NocturneNo1",
        "GolliwoggsCakewalk",
    ]
    with pytest.raises(UnknownSongError):
        load_song("RoboPianist-etude-12-NocturneNo1-v0")  # not an etude-12 piece
    with pytest.raises(UnknownSongError):
        load_song("pig-099")


def test_broken_pieces_are_reported_and_warn(tmp_path: Path, data_home: Path) -> None:
    report = import_pig(_dataset(tmp_path / "pig"))
    broken = {p.name: p.problems for p in report.with_problems}
    assert list(broken) == ["NocturneNo1"]
    text = " ".join(broken["NocturneNo1"])
    assert "more than five keys" in text and "wrong tempo" in text
    assert "warning: NocturneNo1" in report.summary()
    assert pig_piece_info("NocturneNo1")["problems"] == broken["NocturneNo1"]
    with pytest.warns(UserWarning, match="more than five keys"):
        load_song("NocturneNo1")


def test_fingering_files_folder_and_custom_destination(tmp_path: Path) -> None:
    src = _dataset(tmp_path / "pig")
    dest = tmp_path / "out"
    report = import_pig(src / "FingeringFiles", dest)  # List.csv found in the parent
    assert (dest / "index.json").is_file() and len(report.pieces) == 4
    assert list_pig_songs("etude-12", dest) == ["FrenchSuiteNo1Allemande", "GolliwoggsCakewalk"]
    with pytest.raises(ValueError, match="unknown PIG suite"):
        list_pig_songs("etude-13", dest)


def test_wrong_directories(tmp_path: Path) -> None:
    with pytest.raises(PigDatasetError, match="no such directory"):
        import_pig(tmp_path / "missing", tmp_path / "out")
    (tmp_path / "file.zip").write_bytes(b"PK")
    with pytest.raises(PigDatasetError, match="not a directory"):
        import_pig(tmp_path / "file.zip", tmp_path / "out")
    (tmp_path / "empty").mkdir()
    with pytest.raises(PigDatasetError, match="no PIG fingering files"):
        import_pig(tmp_path / "empty", tmp_path / "out")
    src = _dataset(tmp_path / "nolist")
    (src / "List.csv").unlink()
    with pytest.raises(PigDatasetError, match="List.csv not found"):
        import_pig(src, tmp_path / "out")
    (src / "List.csv").write_text("Composer,Title\nBach,x\n")
    with pytest.raises(PigDatasetError, match="no 'Piece' column"):
        import_pig(src, tmp_path / "out")


def test_malformed_file(tmp_path: Path) -> None:
    src = _dataset(tmp_path / "bad")
    (src / "FingeringFiles" / "004-1_fingering.txt").write_text(
        HEADER + "0\t0.0\t0.5\tH9\t64\t80\t0\t1\n"
    )
    with pytest.raises(PigFormatError, match=r"004-1_fingering.txt:2"):
        import_pig(src, tmp_path / "out")
    assert not list((tmp_path / "out").iterdir())  # a failed import writes nothing
    # Over a good import, a failed one leaves it as it was (files and index alike).
    good = import_pig(_dataset(tmp_path / "good"), tmp_path / "kept")
    for song in (tmp_path / "kept").glob("*.txt"):  # marked: a rewrite would drop the mark
        song.write_bytes(song.read_bytes() + b"// the earlier import\n")
    before = {p.name: p.read_bytes() for p in (tmp_path / "kept").iterdir()}
    with pytest.raises(PigFormatError):
        import_pig(src, tmp_path / "kept")
    assert {p.name: p.read_bytes() for p in (tmp_path / "kept").iterdir()} == before
    assert len(good.pieces) == 4
    report = import_pig(src, tmp_path / "out", strict=False)
    assert len(report.pieces) == 4 and len(report.skipped) == 1
    assert "004-1_fingering.txt:2" in report.skipped[0]
    (tmp_path / "out" / "index.json").write_text("{broken")
    with pytest.raises(MusicError, match="import-pig"):
        list_pig_songs("etude-12", tmp_path / "out")


def _pianist(*args: str, data: Path, **env: str) -> subprocess.CompletedProcess:
    """The command line as a user runs it, with ``data`` as $PIANIST_DATA."""
    environ = {k: v for k, v in os.environ.items() if k != "PIANIST_PIG"}
    environ.update(PIANIST_DATA=str(data), **env)
    return subprocess.run(
        [sys.executable, "-m", "pianist.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=environ,
    )


def test_cli_turns_a_broken_piece_warning_into_one_line(tmp_path: Path) -> None:
    """The command line says a flagged piece's problems in its own words (info's warning lines,
    a "pianist: warning:" line for play), never as a Python warning with a source line."""
    data = tmp_path / "data"
    import_pig(_dataset(tmp_path / "pig"), data / "pig")
    info = _pianist("info", "NocturneNo1", data=data)
    assert info.returncode == 0 and info.stderr == ""
    assert "warning:    PIG piece NocturneNo1:" in info.stdout and "wrong tempo" in info.stdout
    assert info.stdout.count("more than five keys") == 1  # not again from check_playability
    out = tmp_path / "played"
    args = ("play", "NocturneNo1", "--controller", "zero", "--physics", "fast", "--no-audio")
    play = _pianist(*args, "--out", str(out), data=data)
    assert play.returncode == 0, play.stderr
    lines = play.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pianist: warning: PIG piece NocturneNo1:")
    assert "UserWarning" not in play.stderr and ".py:" not in play.stderr


def test_songs_marks_broken_pieces(
    tmp_path: Path, data_home: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import_pig(_dataset(tmp_path / "pig"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing may escape as a warning
        assert main(["songs", "--suite", "repertoire-150"]) == 0
    captured = capsys.readouterr()
    rows = {line.split()[0]: line for line in captured.out.splitlines()}
    assert rows["NocturneNo1"].endswith(" !") and not rows["GolliwoggsCakewalk"].endswith("!")
    assert "!: known problems" in captured.out.splitlines()[-1]
    assert captured.err == ""


def test_an_import_elsewhere_is_used_through_pianist_pig(
    tmp_path: Path,
    data_home: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`import-pig --dest D` says how to use D; with PIANIST_PIG=D every command finds it."""
    src, dest = _dataset(tmp_path / "pig"), tmp_path / "elsewhere"
    monkeypatch.chdir(tmp_path)
    assert main(["import-pig", str(src), "--dest", "elsewhere"]) == 0
    summary = capsys.readouterr().out
    assert f"songs are looked up in {data_home / 'pig'}" in summary
    assert summary.splitlines()[-1] == f"  export PIANIST_PIG={dest.resolve()}"
    assert main(["songs", "--suite", "etude-12"]) == 1
    assert "set PIANIST_PIG=D" in capsys.readouterr().err

    monkeypatch.setenv("PIANIST_PIG", str(dest))
    assert main(["songs", "--suite", "etude-12"]) == 0
    assert "FrenchSuiteNo1Allemande" in capsys.readouterr().out
    assert main(["info", "RoboPianist-etude-12-FrenchSuiteNo1Allemande-v0"]) == 0
    assert "notes:      5" in capsys.readouterr().out
    # Importing again without --dest writes where PIANIST_PIG points: nothing more to set.
    assert main(["import-pig", str(src)]) == 0
    assert "PIANIST_PIG" not in capsys.readouterr().out
    assert not (data_home / "pig").exists()
