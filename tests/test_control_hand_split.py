"""The joint plan of both hands (which hand plays which key) on small synthetic pieces."""

import numpy as np

from pianist.control.planner.hand_plan import HandPlanCosts
from pianist.control.planner.hand_split import LEFT, RIGHT, HandReach, SplitCosts, split_hands

DT = 0.05
PITCH_M = 0.0235  # one white key
KEY_Y = np.arange(88) * PITCH_M - 1.0  # 88 white keys (the plan only needs each key's y)
BLACK = np.zeros(88, dtype=bool)
# The right Shadow hand's reach (key y - slide, m) per finger, as the planner samples it, and
# the left hand's mirror image.
FULL = np.array([[64, 116], [110, 124], [133, 145], [154, 168], [173, 193]], dtype=float) / 1000
RIGHT_FULL = np.stack([FULL, FULL], axis=1)  # (5, 2, 2)
LEFT_FULL = -RIGHT_FULL[..., ::-1]
HAND_SPAN_M = FULL.max() - FULL.min()


def _hands(root=0.15):
    right = HandReach(RIGHT_FULL, RIGHT_FULL, root, (-1.5, 1.5))
    left = HandReach(LEFT_FULL, LEFT_FULL, -root, (-1.5, 1.5))
    return right, left


def _song(notes, T):
    """notes: (key, first frame, end frame (excl.), hand 0 right / 1 left)."""
    keys = np.zeros((T, 88), dtype=bool)
    hands = np.full((T, 88), -1)
    for key, first, end, hand in notes:
        keys[first:end, key] = True
        hands[first:end, key] = hand
    return keys, hands


def _split(keys, hands, **costs):
    return split_hands(keys, hands, KEY_Y, BLACK, *_hands(), DT, SplitCosts(**costs))


def test_a_chord_wider_than_the_hand_is_shared_with_the_free_hand():
    # Five keys over 9 white keys (21 cm), all given to the right hand; the left is free.
    chord = [40, 42, 44, 47, 49]
    keys, hands = _song([(k, 0, 20, RIGHT) for k in chord], 20)
    assert KEY_Y[chord[-1]] - KEY_Y[chord[0]] > HAND_SPAN_M  # one hand cannot play it all
    split = _split(keys, hands)
    frame = split[10, chord]
    assert set(frame.tolist()) == {LEFT, RIGHT}
    # Lowest keys to the left hand, and each hand's share within one hand's span.
    assert np.all(np.diff(frame) <= 0)
    for side in (LEFT, RIGHT):
        y = KEY_Y[np.array(chord)[frame == side]]
        assert y.max() - y.min() <= HAND_SPAN_M
    assert np.all(split[keys] >= 0) and np.all(split[~keys] == -1)


def test_the_songs_hands_are_kept_when_each_hand_plays_its_own():
    notes = [(52, 0, 10, RIGHT), (54, 0, 10, RIGHT), (30, 0, 10, LEFT), (32, 5, 15, LEFT)]
    keys, hands = _song(notes, 15)
    split = _split(keys, hands)
    np.testing.assert_array_equal(split[keys], hands[keys])


def test_forearms_kept_apart_give_close_keys_to_one_hand():
    # Three keys within one hand's span, split between the hands by the song. With the
    # forearms free the song's split is kept; forearms that must stay 40 cm apart cannot both
    # be there, so one hand takes all three.
    notes = [(40, 0, 10, LEFT), (42, 0, 10, RIGHT), (44, 0, 10, RIGHT)]
    keys, hands = _song(notes, 10)
    free = _split(keys, hands, separation_m=0.0)
    np.testing.assert_array_equal(free[keys], hands[keys])
    apart = _split(keys, hands, separation_m=0.4)
    assert len(set(apart[5, [40, 42, 44]].tolist())) == 1


def test_a_hand_busy_elsewhere_does_not_take_keys():
    # The left hand holds a bass far below; the right hand's wide chord keeps its top and
    # drops what it cannot reach rather than giving it to the busy left hand.
    chord = [60, 62, 64, 67, 69]
    notes = [(k, 0, 20, RIGHT) for k in chord] + [(5, 0, 20, LEFT)]
    keys, hands = _song(notes, 20)
    split = _split(keys, hands)
    assert split[10, 5] == LEFT
    assert split[10, 69] == RIGHT  # the top voice stays with the right hand


def test_the_split_is_deterministic_and_cheap_to_repeat():
    rng = np.random.default_rng(0)
    T = 60
    keys = np.zeros((T, 88), dtype=bool)
    for t0 in range(0, T, 6):
        keys[t0 : t0 + 6, rng.choice(np.arange(20, 70), 4, replace=False)] = True
    hands = np.where(keys, np.where(np.arange(88) >= 45, RIGHT, LEFT)[None, :], -1)
    a = _split(keys, hands)
    b = _split(keys, hands, hand=HandPlanCosts())
    np.testing.assert_array_equal(a, b)
    assert np.all(a[keys] >= 0)
