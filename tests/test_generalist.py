"""The generalist shipped with the package: it loads, plays with NumPy alone, and plays."""

import json
import subprocess
import sys

import pytest

from pianist.agents.fingertip import load_policy
from pianist.agents.generalist import GENERALIST_DIR
from pianist.cli import main
from pianist.music import get_song, strip_fingering, write_midi

# A debug song the generalist never saw (it was trained on chorale segments and generated
# etudes). Measured (fast physics, seed 0): the shipped policy 0.957 (the joint-angle policy
# shipped before it 0.308); the zero controller 0.037, the random one 0.040.
SONG = "twinkle-twinkle"
FLOOR = 0.8


def test_the_shipped_weights_load_and_are_small():
    policy = load_policy(GENERALIST_DIR)
    # Trained on the chorale corpus, with DAgger.
    assert policy.info["songs"] > 100 and policy.info["rounds"] >= 1
    size = sum(p.stat().st_size for p in GENERALIST_DIR.iterdir())
    assert size < 4_000_000  # small enough to ship


@pytest.mark.parametrize("as_midi", [False, True])
def test_play_with_the_generalist_uses_no_jax_and_beats_the_floor(tmp_path, as_midi):
    song = SONG
    if as_midi:  # any MIDI file: fingered automatically
        song = str(tmp_path / "song.mid")
        write_midi(strip_fingering(get_song(SONG)), song)
    out = tmp_path / "run"
    code = (
        "import sys; from pianist.cli import main; "
        f"rc = main(['play', {song!r}, '--controller', 'generalist', '--out', {str(out)!r}, "
        "'--no-audio']); "
        "assert rc == 0; assert 'jax' not in sys.modules, 'jax was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["f1"] > FLOOR, metrics["f1"]


def test_a_missing_generalist_is_one_line(monkeypatch, tmp_path, capsys):
    import pianist.agents.generalist as generalist

    monkeypatch.setattr(generalist, "GENERALIST_DIR", tmp_path / "none")
    assert main(["play", SONG, "--controller", "generalist", "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "generalist" in err[0] and "reinstall" in err[0]


def test_the_generalist_spec_chooses_where_its_forearms_go():
    from pianist.control.registry import build_controller

    assert build_controller("generalist").forearm == "plan"
    assert build_controller("generalist:forearm=policy").forearm == "policy"
    with pytest.raises(ValueError, match="generalist option forearm needs one of plan, policy"):
        build_controller("generalist:forearm=sideways")
