"""Errors by kind (pianist.eval.errors): hand-made cases, the classes adding up, and the F1
each class costs."""

from __future__ import annotations

import numpy as np
import pytest

from pianist.eval import error_masks, f1_lost, note_errors, precision_recall_f1


def _arrays(steps: int, due: dict[int, range], sounding: dict[int, list[int]]):
    goal = np.zeros((steps, 88), dtype=bool)
    pressed = np.zeros((steps, 88), dtype=bool)
    for key, frames in due.items():
        goal[list(frames), key] = True
    for key, frames in sounding.items():
        pressed[frames, key] = True
    return pressed, goal


def test_a_note_struck_a_frame_late_then_let_go_for_a_frame():
    # Key 40 due at frames 2-7; it sounds at 3, 4, 6, 7: one frame late, one dropped.
    pressed, goal = _arrays(10, {40: range(2, 8)}, {40: [3, 4, 6, 7]})
    errors = note_errors(pressed, goal)
    assert errors["notes"] == 1
    assert errors["notes_late_share"] == 1.0 and errors["notes_never_share"] == 0.0
    assert errors["onset_delay_mean_frames"] == 1.0
    assert errors["lost_late_share"] == pytest.approx(1 / 6)
    assert errors["lost_dropout_share"] == pytest.approx(1 / 6)
    assert errors["lost_never_share"] == 0.0


def test_a_note_never_sounding_and_one_on_time():
    pressed, goal = _arrays(8, {40: range(0, 3), 50: range(4, 8)}, {50: [4, 5, 6, 7]})
    errors = note_errors(pressed, goal)
    assert errors["notes"] == 2
    assert errors["notes_never_share"] == 0.5 and errors["notes_late_share"] == 0.0
    assert errors["onset_delay_mean_frames"] == 0.0  # over the notes that sound
    assert errors["lost_never_share"] == pytest.approx(3 / 7)


def test_two_notes_of_one_key_are_two_notes():
    # A re-struck key: due 1-3 and 5-7 with a frame's gap; held through the gap.
    pressed, goal = _arrays(9, {60: [1, 2, 3, 5, 6, 7]}, {60: [1, 2, 3, 4, 5, 6, 7]})
    errors = note_errors(pressed, goal)
    assert errors["notes"] == 2
    assert errors["false_held_share"] == pytest.approx(1 / 6)  # the gap, not let up
    assert errors["false_early_share"] == 0.0 and errors["false_other_share"] == 0.0


def test_false_key_frames_by_the_nearest_note_of_their_key():
    # Key 40 due at 4-5: sounding at 2 and 3 is early, at 6 and 7 held, at 9 neither;
    # key 41 never due: other.
    pressed, goal = _arrays(12, {40: range(4, 6)}, {40: [2, 3, 4, 5, 6, 7, 9], 41: [4]})
    errors = note_errors(pressed, goal, window=2)
    assert errors["false_early_share"] == pytest.approx(2 / 2)
    assert errors["false_held_share"] == pytest.approx(2 / 2)
    assert errors["false_other_share"] == pytest.approx(2 / 2)
    wide = note_errors(pressed, goal, window=4)
    assert wide["false_held_share"] == pytest.approx(3 / 2)  # frame 9 is 4 after the end
    assert wide["false_other_share"] == pytest.approx(1 / 2)


def test_the_missed_classes_add_up_to_the_missed_key_frames():
    rng = np.random.default_rng(0)
    goal = rng.random((200, 88)) < 0.05
    goal[1:] |= goal[:-1] & (rng.random((199, 88)) < 0.7)  # notes of several frames
    pressed = (goal & (rng.random(goal.shape) < 0.8)) | (rng.random(goal.shape) < 0.01)
    errors = note_errors(pressed, goal)
    due = goal.sum()
    missed = (goal & ~pressed).sum()
    false = (pressed & ~goal).sum()
    lost = sum(errors[f"lost_{k}_share"] for k in ("late", "dropout", "never"))
    assert lost * due == pytest.approx(missed)
    wrong = sum(errors[f"false_{k}_share"] for k in ("held", "early", "other"))
    assert wrong * due == pytest.approx(false)
    # A perfect player has no errors of any kind.
    perfect = note_errors(goal, goal)
    assert precision_recall_f1(goal, goal)["f1"] == 1.0
    assert all(v == 0.0 for k, v in perfect.items() if k != "notes")


def test_bad_input_is_refused():
    pressed, goal = _arrays(4, {40: range(1, 3)}, {})
    with pytest.raises(ValueError, match="window"):
        note_errors(pressed, goal, window=0)
    with pytest.raises(ValueError, match="same shape"):
        note_errors(pressed[:, :10], goal)
    silent = note_errors(pressed, np.zeros_like(goal))
    assert silent["notes"] == 0.0 and silent["false_other_share"] == 0.0


def test_the_masks_partition_the_wrong_key_frames():
    rng = np.random.default_rng(1)
    goal = rng.random((120, 88)) < 0.05
    goal[1:] |= goal[:-1] & (rng.random((119, 88)) < 0.7)
    pressed = (goal & (rng.random(goal.shape) < 0.8)) | (rng.random(goal.shape) < 0.01)
    masks = error_masks(pressed, goal)
    missed = masks["late"].astype(int) + masks["dropout"] + masks["never"]
    false = masks["held"].astype(int) + masks["early"] + masks["other"]
    assert np.array_equal(missed, (goal & ~pressed).astype(int))  # disjoint, and all of them
    assert np.array_equal(false, (pressed & ~goal).astype(int))
    errors = note_errors(pressed, goal)
    assert errors["lost_late_share"] == pytest.approx(masks["late"].sum() / goal.sum())


def test_f1_lost_counts_in_the_metrics_unit():
    # Steps 0-3: one key due (40), steps 4-7: a chord of four (50-53). The single key is
    # missed at step 0, one key of the chord at step 4, and a wrong key sounds at step 6.
    pressed, goal = _arrays(
        8,
        {40: range(0, 4), 50: range(4, 8), 51: range(4, 8), 52: range(4, 8), 53: range(4, 8)},
        {
            40: [1, 2, 3],
            50: [5, 6, 7],
            51: [4, 5, 6, 7],
            52: [4, 5, 6, 7],
            53: [4, 5, 6, 7],
            60: [6],
        },
    )
    masks = error_masks(pressed, goal)
    base = precision_recall_f1(pressed, goal)["f1"]
    lost = f1_lost(pressed, goal, {"late": masks["late"], "other": masks["other"]})
    # One missed key-frame each: the lone key costs its step's whole F1 (1 of 8 steps), the
    # chord's key 1 - 2*3/7 of its step, the wrong key 1 - 8/9 of its step.
    assert masks["late"].sum() == 2
    assert lost["late"] == pytest.approx((1.0 + (1 - 6 / 7)) / 8)
    assert lost["other"] == pytest.approx((1 - 8 / 9) / 8)
    # Putting every wrong key-frame right gives F1 1.
    everything = {"all": (goal & ~pressed) | (pressed & ~goal)}
    assert base + f1_lost(pressed, goal, everything)["all"] == pytest.approx(1.0)
    # A class wider than its wrong key-frames counts only those.
    wide = f1_lost(pressed, goal, {"wide": goal})
    assert wide["wide"] == pytest.approx(lost["late"])
    with pytest.raises(ValueError, match="shape"):
        f1_lost(pressed, goal, {"bad": goal[:, :10]})
