"""The one atomic writer: a file or folder appears whole or not at all."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from pianist.files import (
    FileWriteError,
    atomic_dir,
    atomic_path,
    save_npy_atomic,
    write_json_atomic,
    write_text_atomic,
)


def test_json_and_npy_round_trip_with_ordinary_permissions(tmp_path: Path) -> None:
    write_json_atomic({"f1": 0.5}, tmp_path / "m.json")
    save_npy_atomic(np.arange(6.0).reshape(2, 3), tmp_path / "a.npy")
    assert json.loads((tmp_path / "m.json").read_text()) == {"f1": 0.5}
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), np.arange(6.0).reshape(2, 3))
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "m.json").stat().st_mode & 0o777 == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npy", "m.json"]


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    path = tmp_path / "result.txt"
    write_text_atomic("old", path)
    path.chmod(0o640)
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_text("half of the new")
        raise RuntimeError("crash mid-write")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["result.txt"]
    write_text_atomic("new", path)
    assert path.read_text() == "new"
    assert path.stat().st_mode & 0o777 == 0o640  # a replaced file keeps its mode


def test_missing_folder_raises_the_callers_error_in_one_line(tmp_path: Path) -> None:
    class MyError(Exception):
        pass

    with pytest.raises(FileWriteError, match="cannot write"):
        write_text_atomic("x", tmp_path / "nope" / "f.txt")
    with (
        pytest.raises(MyError, match=r"cannot write .*f\.txt: No such file"),
        atomic_path(tmp_path / "nope" / "f.txt", error=MyError),
    ):
        pass


def test_atomic_dir_swaps_a_folder_in_whole(tmp_path: Path) -> None:
    run = tmp_path / "run"
    with atomic_dir(run) as tmp:
        (tmp / "a.txt").write_text("first")
        (tmp / "b.txt").write_text("first")
        assert not run.exists()  # nothing visible until the folder is complete
    with pytest.raises(RuntimeError), atomic_dir(run) as tmp:
        (tmp / "a.txt").write_text("second")
        raise RuntimeError("interrupted")
    assert {p.name: p.read_text() for p in run.iterdir()} == {"a.txt": "first", "b.txt": "first"}
    with atomic_dir(run) as tmp:
        (tmp / "a.txt").write_text("third")
    # The new folder replaces the old one whole: no file of the first write is left.
    assert {p.name: p.read_text() for p in run.iterdir()} == {"a.txt": "third"}
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
