"""The whole-piece hand plan on small synthetic pieces (pure arrays, no simulation)."""

import numpy as np
import pytest

from pianist.control.planner.hand_plan import (
    HandPlanCosts,
    finger_order,
    move_frames,
    plan_hand,
    step_f1_costs,
)
from pianist.eval.metrics import per_step_precision_recall_f1

DT = 0.05
PITCH_M = 0.0235  # one white key
# A keyboard of 88 white keys 23.5 mm apart (the plan only needs each key's y).
KEY_Y = np.arange(88) * PITCH_M - 1.0
BLACK = np.zeros(88, dtype=bool)
# The right Shadow hand's reach (key y - slide, m) per finger on white / black keys, as the
# planner samples it: the thumb spans ~5 cm, each other finger ~1.5 cm.
FULL = np.array([[64, 116], [110, 124], [133, 145], [154, 168], [173, 193]], dtype=float) / 1000
FULL_REACH = np.stack([FULL, FULL], axis=1)  # (5, 2, 2)
REACH = FULL_REACH + np.array([0.003, -0.003])
REST = FULL.mean(axis=1)


def _plan(notes, T, refinger=False, start=0.0, **costs):
    """notes: (key, first frame, end frame (excl.), finger)."""
    keys = np.zeros((T, 88), dtype=bool)
    fingers = np.full((T, 88), -1)
    for key, first, end, finger in notes:
        keys[first:end, key] = True
        fingers[first:end, key] = finger
    plan = plan_hand(
        keys,
        fingers,
        KEY_Y,
        BLACK,
        FULL_REACH,
        REACH,
        REST,
        (-1.5, 1.5),
        start=start,
        dt=DT,
        outer="top",
        costs=HandPlanCosts(**costs),
        refinger=refinger,
    )
    return keys, plan


def _reaches(plan, key, frame, finger):
    relative = KEY_Y[key] - plan.position[frame]
    low, high = FULL_REACH[finger, 0]
    return low - 1e-9 <= relative <= high + 1e-9


def test_move_frames_follow_the_slide_servo():
    # Measured in closed loop (benchmark of the slide): 5 cm in 2 steps, 40 cm in 6.
    assert move_frames(0.01, DT) == 1
    assert move_frames(0.05, DT) == 2
    assert move_frames(0.2, DT) == 4
    assert move_frames(0.4, DT) == 6


def test_move_frames_at_another_slide_acceleration():
    # Four times the acceleration halves a move's time; a slide that is never slow moves in
    # a step; no acceleration is refused.
    assert move_frames(0.4, DT, 80.0) == 3
    assert move_frames(0.4, DT, 1e6) == 1
    with pytest.raises(ValueError, match="acceleration"):
        move_frames(0.4, DT, 0.0)


def test_a_plan_with_instant_moves_loses_no_frames_to_a_jump():
    # The jump without a rest below, planned as if the slide moved in a step: it costs the
    # one frame of the shift instead of the frames the real slide needs.
    notes = [(40, 0, 18, 0), (57, 18, 30, 0)]
    # Both start where the first note is played, so no frames go to getting there.
    start = _plan(notes, T=30)[1].position[0]
    _, real = _plan(notes, T=30, start=start)
    _, instant = _plan(notes, T=30, start=start, slide_acceleration_m_s2=1e6)
    weight = HandPlanCosts().outer_voice_weight
    steps = move_frames(17 * PITCH_M, DT)
    assert steps > 1
    assert real.cost - instant.cost == pytest.approx((steps - 1) * weight, abs=0.01)


def test_a_long_jump_is_made_in_the_rest_before_it():
    # A note, a rest of 8 frames, then a note 40 cm away (the slide needs 6 steps).
    start_key, far_key = 40, 40 + 17
    keys, plan = _plan([(start_key, 0, 10, 0), (far_key, 18, 30, 0)], T=30)
    assert _reaches(plan, start_key, 5, 0) and _reaches(plan, far_key, 18, 0)
    # The hand holds the far note's position from the end of the first note: it sets off
    # as early as it can, so it is there when the note starts.
    assert np.all(plan.position[10:30] == plan.position[18])
    assert not plan.skip.any()


def test_a_jump_without_a_rest_costs_the_frames_the_slide_needs():
    # The same jump with no rest: the shift loses the first note's last frames.
    _, plan = _plan([(40, 0, 18, 0), (57, 18, 30, 0)], T=30)
    _, relaxed = _plan([(40, 0, 10, 0), (57, 18, 30, 0)], T=30)
    # Both shift once; without the rest the fingers are off the first note for the frames
    # the move needs (a lone note is its hand's outer voice, weighted as such).
    lost = move_frames(17 * PITCH_M, DT) * HandPlanCosts().outer_voice_weight
    assert plan.cost == pytest.approx(relaxed.cost + lost, abs=0.01)  # comfort terms differ
    assert np.flatnonzero(np.diff(plan.position)).tolist() == [17]


def test_the_hand_stays_put_while_its_fingers_reach():
    # Five notes under the five fingers, one after the other: no move at all.
    notes = [(40 + i, 4 * i, 4 * i + 4, i) for i in range(5)]
    _, plan = _plan(notes, T=20)
    assert np.ptp(plan.position) == 0 and not plan.skip.any()


def test_a_chord_wider_than_the_hand_keeps_its_top_voice():
    # An octave (C, C') with thumb and little finger: no position reaches both.
    _, plan = _plan([(40, 0, 10, 0), (47, 0, 10, 4)], T=10)
    assert not plan.skip[:, 47].any()  # the top (the melody) is kept
    assert plan.skip[:, 40].all()
    # With a third under the thumb the two lower keys outweigh the top one.
    _, plan = _plan([(40, 0, 10, 0), (42, 0, 10, 2), (47, 0, 10, 4)], T=10)
    assert plan.skip[:, 47].all() and not plan.skip[:, [40, 42]].any()


def test_refingering_fits_the_hand_and_keeps_held_keys_on_their_finger():
    # A melody the song fingers with one finger throughout (impossible without moving),
    # and a long note held under it.
    notes = [(40, 0, 24, 0)] + [(41 + i % 3, 4 * i, 4 * i + 4, 1) for i in range(6)]
    keys, plan = _plan(notes, T=24, refinger=True)
    assert not plan.skip.any()
    held = plan.fingers[:, 40]
    assert np.all(held == held[0]) and held[0] >= 0  # the held key never changes finger
    for t in range(24):  # every key has its own finger, which reaches it
        due = np.flatnonzero(keys[t])
        assigned = plan.fingers[t, due]
        assert len(set(assigned.tolist())) == len(due)
        assert all(_reaches(plan, k, t, f) for k, f in zip(due, assigned, strict=True))


def test_finger_order_runs_across_the_hand():
    assert finger_order(FULL_REACH).tolist() == [0, 1, 2, 3, 4]
    assert finger_order(-FULL_REACH[:, :, ::-1]).tolist() == [4, 3, 2, 1, 0]


def test_the_plan_is_deterministic():
    rng = np.random.default_rng(0)
    notes = [
        (int(k), int(s), int(s) + 5, int(f))
        for k, s, f in zip(
            rng.integers(30, 60, 30), rng.integers(0, 200, 30), rng.integers(0, 5, 30), strict=True
        )
    ]
    _, a = _plan(notes, T=210, refinger=True)
    _, b = _plan(notes, T=210, refinger=True)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.fingers, b.fingers)
    assert a.cost == b.cost


def test_step_f1_costs_are_what_the_metric_loses():
    # Random frames of both hands' keys; each candidate loses the first `lost` of this
    # hand's keys, the other hand keeps some of its own: the costs are the F1 the metric
    # takes off those steps, scaled.
    rng = np.random.default_rng(1)
    T, scale = 60, 3.0
    keys = rng.random((T, 88)) < 0.06
    mine = keys & (np.arange(88) >= 44)
    other_keeps = keys & ~mine & (rng.random((T, 88)) < 0.7)
    lost = np.minimum(rng.integers(0, 4, (T, 2)), mine.sum(axis=1)[:, None])
    cost, frame_cost = step_f1_costs(keys, mine, lost.astype(float), other_keeps.sum(1), scale)

    def f1(pressed):
        return per_step_precision_recall_f1(pressed, keys)[2]

    best = f1(other_keeps | mine)
    for p in range(2):
        pressed = other_keeps.copy()
        for t in range(T):
            pressed[t, np.flatnonzero(mine[t])[lost[t, p] :]] = True
        np.testing.assert_allclose(cost[:, p], scale * (best - f1(pressed)), atol=1e-12)
    np.testing.assert_allclose(frame_cost, scale * (best - f1(other_keeps)), atol=1e-12)


def test_the_step_f1_objective_keeps_steps_not_key_frames():
    # A four-key chord for 2 frames, then at once a note 30 cm away for 4 (the slide needs
    # 5 frames for it): one of the two is lost. Counted in key-frames the chord is worth
    # more (4 keys x 2 frames); counted as the metric does, in steps, the note (4 steps).
    chord = [(40 + i, 10, 12, i) for i in range(4)]
    far = [(53, 12, 16, 0)]
    assert move_frames(KEY_Y[53] - KEY_Y[40], DT) > 4
    _, by_keys = _plan(chord + far, T=16, objective="key_frames")
    assert not by_keys.skip[10:12].any()
    assert all(_reaches(by_keys, 40 + i, 10, i) for i in range(4))
    assert not _reaches(by_keys, 53, 12, 0)
    _, by_steps = _plan(chord + far, T=16, objective="step_f1")
    assert by_steps.skip[10:12, 40:44].any()
    assert all(_reaches(by_steps, 53, t, 0) for t in range(12, 16))
