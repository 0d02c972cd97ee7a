"""Note velocities from the keys' strike speeds, and the velocity error against the score."""

from __future__ import annotations

import numpy as np
import pytest

from pianist.media.dynamics import (
    KEY_LEVER_M,
    LOUDEST_SPEED_M_S,
    SOFTEST_SPEED_M_S,
    match_notes,
    speed_to_velocity,
    strike_speeds,
    velocity_metrics,
    with_velocities,
)
from pianist.music import Note, Song

DT = 0.05
THRESHOLD = np.full(88, 0.06)
C4, D4 = 60 - 21, 62 - 21


def _angles(steps: int) -> np.ndarray:
    return np.zeros((steps + 1, 88))


def test_a_faster_strike_gives_a_higher_velocity() -> None:
    angles = _angles(4)
    # Both keys start the step at rest and reach the bottom at the end of the step; C4 sounds
    # 10 ms into the step (fast), D4 40 ms into it (slow).
    angles[2:, [C4, D4]] = 0.07
    events = np.array([[0.06, C4, 1.0], [0.09, D4, 1.0], [0.15, C4, 0.0], [0.12, -1, 1.0]])
    speeds = strike_speeds(events, angles, DT, THRESHOLD)
    assert np.isnan(speeds[2]) and np.isnan(speeds[3])  # key-off and pedal rows
    np.testing.assert_allclose(speeds[:2], [0.06 / 0.01 * 0.15, 0.06 / 0.04 * 0.15])
    velocities = speed_to_velocity(speeds[:2])
    assert velocities[0] > velocities[1]


def test_a_key_that_went_down_in_the_previous_step_reads_fast() -> None:
    angles = _angles(4)
    angles[2, C4] = 0.059  # nearly at the threshold when the step began, sounds 5 ms later
    angles[3:, C4] = 0.07
    events = np.array([[0.105, C4, 1.0]])
    # The window from the previous step's start (0.05 s): 0.06 rad in 55 ms.
    np.testing.assert_allclose(strike_speeds(events, angles, DT, THRESHOLD), [0.06 / 0.055 * 0.15])


def test_black_keys_use_their_own_lever() -> None:
    cs4 = C4 + 1
    angles = _angles(2)
    angles[1:, [C4, cs4]] = 0.07
    events = np.array([[0.02, C4, 1.0], [0.02, cs4, 1.0]])
    speeds = strike_speeds(events, angles, DT, THRESHOLD)
    assert speeds[0] / speeds[1] == pytest.approx(KEY_LEVER_M[C4] / KEY_LEVER_M[cs4])


def test_velocity_curve_is_monotone_from_1_to_127() -> None:
    speeds = np.geomspace(1e-4, 10.0, 500)
    velocities = speed_to_velocity(speeds)
    assert np.all(np.diff(velocities) >= 0)
    assert velocities[0] == 1 and velocities[-1] == 127
    assert speed_to_velocity(SOFTEST_SPEED_M_S) == 1
    assert speed_to_velocity(LOUDEST_SPEED_M_S) == 127
    assert speed_to_velocity(np.nan) == 1 and speed_to_velocity(0.0) == 1
    middle = np.sqrt(SOFTEST_SPEED_M_S * LOUDEST_SPEED_M_S)  # halfway on the log scale
    assert speed_to_velocity(middle) == 64


def test_with_velocities_sets_each_note_from_its_key_on_event() -> None:
    events = np.array([[0.1, C4, 1.0], [0.3, C4, 0.0], [0.2, D4, 1.0], [0.4, D4, 0.0]])
    performance = Song(notes=(Note(60, 0.1, 0.3), Note(62, 0.2, 0.4)), name="p")
    out = with_velocities(performance, events, np.array([30, 0, 100, 0]))
    assert [n.velocity for n in out.notes] == [30, 100]


def test_match_notes_pairs_same_pitch_while_due_one_to_one() -> None:
    score = Song(notes=(Note(60, 1.0, 1.5), Note(60, 1.5, 2.0), Note(62, 1.0, 2.0)), name="s")
    performance = Song(
        notes=(
            Note(60, 0.95, 1.2, velocity=70),  # 50 ms early: matches the first C4
            Note(60, 1.7, 1.9, velocity=90),  # late but while the second C4 is due
            Note(64, 1.0, 1.5),  # no E4 in the score
            Note(62, 2.05, 2.2),  # after D4's offset: no match
        ),
        name="p",
    )
    pairs = match_notes(performance, score)
    assert [(p.onset_s, s.onset_s) for p, s in pairs] == [(0.95, 1.0), (1.7, 1.5)]
    metrics = velocity_metrics(performance, score)
    assert metrics["velocity_matched_notes"] == 2
    assert metrics["velocity_mae"] == pytest.approx((10 + 10) / 2)  # score velocity 80
    empty = velocity_metrics(Song(notes=(), name="none"), score)
    assert empty["velocity_mae"] is None and empty["velocity_matched_notes"] == 0


def test_rank_correlation_of_a_crescendo_played_in_order_reversed_and_flat() -> None:
    from pianist.media.dynamics import rank_correlation

    score = [40, 50, 60, 70, 80]
    assert rank_correlation([30, 41, 55, 90, 100], score) == pytest.approx(1.0)
    assert rank_correlation([100, 90, 55, 41, 30], score) == pytest.approx(-1.0)
    assert rank_correlation([64, 64, 64, 64, 64], score) is None  # no order to compare
    assert rank_correlation([1, 2], [3, 4]) is None  # too few notes
    with pytest.raises(ValueError):
        rank_correlation([1, 2, 3], [1, 2])


def test_velocity_metrics_of_a_hand_made_pair_of_midi_files(tmp_path) -> None:
    """A score with a crescendo, and a performance written as MIDI that plays its notes a
    little late, softer at first and then louder: matched by pitch and onset, the error and
    the rank correlation are the hand-computed ones."""
    from pianist.music import load_song, write_midi

    velocities = (40, 60, 80, 100)
    played = (50, 55, 85, 110)
    score = Song(
        notes=tuple(Note(60 + 2 * i, 0.5 * i, 0.5 * i + 0.4, velocity=v)
                    for i, v in enumerate(velocities)),
        name="crescendo",
    )  # fmt: skip
    performance = Song(
        notes=tuple(Note(60 + 2 * i, 0.5 * i + 0.03, 0.5 * i + 0.35, velocity=v)
                    for i, v in enumerate(played)),
        name="performance",
    )  # fmt: skip
    for song in (score, performance):
        write_midi(song, tmp_path / f"{song.name}.mid")
    read_score = load_song(str(tmp_path / "crescendo.mid"), fingering="none")
    read_performance = load_song(str(tmp_path / "performance.mid"), fingering="none")
    metrics = velocity_metrics(read_performance, read_score)
    assert metrics["velocity_matched_notes"] == 4
    assert metrics["velocity_mae"] == pytest.approx((10 + 5 + 5 + 10) / 4)
    assert metrics["velocity_rank_correlation"] == pytest.approx(1.0)
