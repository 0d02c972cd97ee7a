"""Generated etudes: deterministic, every figure written, the hands apart, playable."""

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pianist.music import assign_fingering, check_playability, read_pig
from pianist.music.etudes import (
    LEFT_FIGURES,
    LEFT_REGISTER,
    RIGHT_FIGURES,
    RIGHT_REGISTER,
    generate_etude,
)

ROOT = Path(__file__).resolve().parents[1]


def test_an_etude_is_the_same_for_the_same_seed_and_differs_between_seeds():
    assert generate_etude(3) == generate_etude(3)
    assert generate_etude(3).notes != generate_etude(4).notes


@pytest.mark.parametrize(("right", "left"), list(itertools.product(RIGHT_FIGURES, LEFT_FIGURES)))
def test_every_pair_of_figures_is_written_in_its_registers_and_is_playable(right, left):
    song = generate_etude(7, right=right, left=left)
    assert song.name == f"etude-7-{right}-{left}"
    by_hand = {h: [n for n in song.notes if n.hand == h] for h in ("right", "left")}
    assert by_hand["right"] and by_hand["left"] and all(n.finger is None for n in song.notes)
    for hand, (low, high) in (("right", RIGHT_REGISTER), ("left", LEFT_REGISTER)):
        assert all(low <= n.pitch <= high for n in by_hand[hand]), hand
    # No key is held twice at once (within a hand, or by both: the registers do not meet).
    for a, b in itertools.combinations(song.notes, 2):
        if a.pitch == b.pitch:
            assert a.offset_s <= b.onset_s or b.offset_s <= a.onset_s, (a, b)
    assert check_playability(assign_fingering(song)) == []


def test_the_figures_are_what_they_say():
    stride = generate_etude(1, right="melody", left="stride")
    left = [n for n in stride.notes if n.hand == "left"]
    strikes = [[n.pitch for n in left if n.onset_s == t] for t in sorted({n.onset_s for n in left})]
    # The left hand leaps from a low bass note to a chord at least a sixth above it.
    leaps = [min(b) - a[0] for a, b in itertools.pairwise(strikes) if len(a) == 1 and len(b) > 1]
    assert len(leaps) >= 4 and min(leaps) >= 9, leaps
    polonaise = generate_etude(2, right="polonaise", left="held")
    first = sorted({n.onset_s for n in polonaise.notes if n.hand == "right"})[:3]
    beat = first[1] / 0.5  # an eighth, then two sixteenths
    np.testing.assert_allclose(np.diff(first), [0.5 * beat, 0.25 * beat])
    held = [n for n in polonaise.notes if n.hand == "left"]
    assert len({n.onset_s for n in held}) == 4  # one chord per measure, 3/4 time
    run = generate_etude(3, right="scale", left="walking")
    steps = np.diff([n.pitch for n in run.notes if n.hand == "right"])
    assert (np.abs(steps) <= 2).all()  # a scale: steps of a tone or a semitone


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="unknown figure"):
        generate_etude(0, right="fugue")
    with pytest.raises(ValueError, match="at least one measure"):
        generate_etude(0, measures=0)


def test_the_corpus_script_writes_fingered_playable_files(tmp_path):
    out = tmp_path / "etudes"
    command = [sys.executable, str(ROOT / "scripts" / "build_etude_corpus.py")]
    subprocess.run([*command, "--out", str(out), "--count", "12"], check=True)
    record = json.loads((out / "provenance.json").read_text())
    assert len(record["pieces"]) + len(record["skipped"]) == 12
    assert len(record["pieces"]) >= 10
    for piece in record["pieces"]:
        song = read_pig(out / piece["file"])
        assert song.has_full_fingering and check_playability(song) == []
        made = assign_fingering(generate_etude(piece["seed"])).notes
        assert [(n.pitch, n.finger) for n in song.notes] == [(n.pitch, n.finger) for n in made]
        np.testing.assert_allclose(
            [n.onset_s for n in song.notes], [n.onset_s for n in made], atol=1e-6
        )
