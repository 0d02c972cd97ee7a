"""The reach ceiling (every frame on its own, two hands anywhere) and a plan's coverage."""

import itertools

import numpy as np
import pytest

from pianist.control.planner import ENV_OPTIONS, IKPlanner
from pianist.control.planner.coverage import (
    ceiling_scores,
    frame_ceiling,
    plan_coverage,
    playable_mask,
)
from pianist.control.planner.hand_split import HandReach
from pianist.env import PianoEnv
from pianist.eval.metrics import precision_recall_f1
from pianist.eval.session import play
from pianist.music import Note, Song

PITCH_M = 0.0235  # one white key
KEY_Y = np.arange(88) * PITCH_M - 1.0  # 88 keys a white key apart (only their y matters)
NO_BLACK = np.zeros(88, dtype=bool)
# The right Shadow hand's reach (key y - slide, m) per finger, as the planner samples it.
FULL = np.array([[64, 116], [110, 124], [133, 145], [154, 168], [173, 193]], dtype=float) / 1000
SPAN_M = FULL.max() - FULL.min()


def _hands(root=0.15, black_thumb=True, slide=(-1.5, 1.5)):
    right = np.stack([FULL, FULL], axis=1)  # (5, 2, 2): white, black
    if not black_thumb:
        right[0, 1] = right[0, 1].mean()  # a single point: the sampling never got there
    left = -right[..., ::-1]
    return HandReach(right, right, root, slide), HandReach(left, left, -root, slide)


def _frames(*chords):
    keys = np.zeros((len(chords), 88), dtype=bool)
    for t, chord in enumerate(chords):
        keys[t, list(chord)] = True
    return keys


def _ceiling(keys, separation=0.0, **hands):
    return frame_ceiling(keys, KEY_Y, NO_BLACK, *_hands(**hands), separation)


def test_a_melody_and_a_chord_in_each_hand_lose_nothing():
    keys = _frames([40], [41], [10, 12, 70, 72], [])
    np.testing.assert_array_equal(_ceiling(keys), [0, 0, 0, 0])


def test_three_keys_each_beyond_a_hand_from_the_others_lose_one():
    far = round(2 * SPAN_M / PITCH_M)
    keys = _frames([20, 20 + far, 20 + 2 * far], [20, 20 + far])
    np.testing.assert_array_equal(_ceiling(keys), [1, 0])


def test_two_hands_kept_apart_cannot_share_a_close_chord():
    # A chord over 1.5 spans: two hands play it side by side, unless their forearms must
    # stay further apart than the chord is wide.
    width = round(1.5 * SPAN_M / PITCH_M)
    keys = _frames(range(40, 40 + width + 1, 2))
    assert _ceiling(keys)[0] == 0
    assert _ceiling(keys, separation=0.6)[0] > 0


def test_a_finger_the_sampling_never_brought_to_a_colour_reaches_none_of_it():
    black = NO_BLACK.copy()
    black[40] = True
    # Only the thumb's sampled reach covers a key this far below the index finger.
    right, left = _hands(black_thumb=False)
    keys = _frames([40, 40 + 5])
    far_left = HandReach(left.full_reach, left.reach, -0.15, (-5.0, -4.9))  # reaches none
    lost = frame_ceiling(keys, KEY_Y, black, right, far_left, 0.0, tolerance_m=0.005)
    assert lost[0] == 1
    lost = frame_ceiling(keys, KEY_Y, NO_BLACK, right, far_left, 0.0, tolerance_m=0.005)
    assert lost[0] == 0


def _brute_force(ids, right, left, step):
    """For each separation: the fewest keys lost over every pair of grid positions, every
    split and every order-keeping assignment of keys to fingers (small chords only)."""
    ids = sorted(ids, key=lambda k: KEY_Y[k])

    def most(hand, keys, position):
        lo, hi = hand.full_reach[:, 0, 0], hand.full_reach[:, 0, 1]
        order = np.argsort(lo).tolist()  # fingers across the keyboard, lowest first
        for n in range(len(keys), 0, -1):
            for subset in itertools.combinations(keys, n):
                y = KEY_Y[list(subset)] - position
                for fingers in itertools.combinations(order, n):
                    f = list(fingers)
                    if np.all((y >= lo[f] - 1e-9) & (y <= hi[f] + 1e-9)):
                        return n
        return 0

    grids = [np.arange(h.slide_range[0], h.slide_range[1] + step / 2, step) for h in (right, left)]
    gap = (right.root_y + grids[0])[:, None] - (left.root_y + grids[1])[None, :]
    played = []  # per split: (PR, PL) keys played
    for s in range(len(ids) + 1):
        r = np.array([most(right, ids[s:], p) for p in grids[0]])
        q = np.array([most(left, ids[:s], p) for p in grids[1]])
        played.append(r[:, None] + q[None, :])
    return {
        separation: len(ids) - max(int(v[gap >= separation].max(initial=0)) for v in played)
        for separation in (0.0, 0.15)
    }


@pytest.mark.parametrize("seed", range(4))
def test_the_ceiling_matches_a_brute_force_search(seed):
    rng = np.random.default_rng(seed)
    step = 0.008
    # Narrow slide ranges around the keys keep the brute force small.
    right, left = _hands(slide=(-0.35, 0.05))
    ids = sorted(rng.choice(np.arange(30, 50), size=4, replace=False).tolist())
    expected = _brute_force(ids, right, left, step)
    for separation, lost in expected.items():
        got = frame_ceiling(_frames(ids), KEY_Y, NO_BLACK, right, left, separation, step_m=step)
        assert got[0] == lost


def test_a_plans_coverage_accounts_for_every_due_key_frame():
    # A chord over three octaves and a half: no two hands press all of it.
    chord = (36, 48, 60, 72, 84, 79)
    fingers = (9, 5, 0, 2, 4, 3)
    notes = [Note(p, 0.5, 1.5, finger=f) for p, f in zip(chord, fingers, strict=True)]
    notes.append(Note(64, 1.6, 2.0, finger=1))
    env = PianoEnv(Song(tuple(notes), name="wide"), physics="fast", **ENV_OPTIONS)
    planner = IKPlanner()
    env.reset(seed=0)
    planner.reset(env, seed=0)
    coverage = plan_coverage(planner)
    assert coverage.due == int(env.goal.keys.sum())
    parts = coverage.left_out + coverage.in_shift + coverage.out_of_reach + coverage.playable
    assert parts == coverage.due
    frames = int(env.goal.keys[:, 36 - 21].sum())
    # Six keys spread over both hands' spans: at least one lost per frame of the chord with
    # the wrists turned (the whole hand's ceiling), two with them straight.
    assert coverage.ceiling_lost >= frames
    assert coverage.straight_ceiling_f1 < coverage.ceiling_f1
    assert coverage.left_out + coverage.in_shift + coverage.out_of_reach >= coverage.ceiling_lost
    assert 0.0 < coverage.ceiling_recall < 1.0
    assert coverage.ceiling_recall < coverage.ceiling_f1 < 1.0
    # The plan's F1 is the metric of a player that sounds exactly its playable key-frames,
    # which no plan of these hands can make better than the ceiling.
    playable = playable_mask(planner)
    assert int(playable.sum()) == coverage.playable
    assert not (playable & ~env.goal.keys).any()
    assert coverage.plan_f1 == pytest.approx(precision_recall_f1(playable, env.goal.keys)["f1"])
    assert coverage.plan_f1 < coverage.ceiling_f1 + 1e-9


def test_the_ceiling_scores_are_the_metrics_of_a_player_missing_only_the_lost_keys():
    rng = np.random.default_rng(0)
    keys = rng.random((50, 88)) < 0.05
    keys[10:15] = False  # steps with nothing due count as the metrics count them
    due = keys.sum(axis=1)
    lost = rng.integers(0, np.maximum(due, 0) + 1)
    pressed = keys.copy()
    for t in range(len(keys)):
        pressed[t, np.flatnonzero(keys[t])[: lost[t]]] = False
    expected = precision_recall_f1(pressed, keys)
    recall, f1 = ceiling_scores(keys, lost)
    assert recall == pytest.approx(expected["recall"])
    assert f1 == pytest.approx(expected["f1"])
    assert expected["precision"] == 1.0


def test_a_played_episode_reports_the_ceiling_and_stays_below_it():
    # The chord over three octaves and a half again, played: metrics carry the ceiling of
    # these hands, and the episode's own recall and F1 stay below it.
    notes = (
        Note(36, 0.5, 1.5, finger=9),
        Note(60, 0.5, 1.5, finger=0),
        Note(84, 0.5, 1.5, finger=4),
    )
    song = Song(notes, name="three-hands")
    result = play(song, IKPlanner(), physics="fast", seed=0)
    metrics = result.metrics
    assert 0.0 < metrics["reach_ceiling_f1"] < 1.0
    assert metrics["recall"] <= metrics["reach_ceiling_recall"] + 1e-9
    assert metrics["f1"] <= metrics["reach_ceiling_f1"] + 1e-9
    assert metrics["plan_left_out_share"] > 0.0
    assert 0.0 < metrics["plan_f1"] <= metrics["reach_ceiling_f1"] + 1e-9
    # The F1 the left-out key costs, in the metric's unit: the episode's F1 were it sounding.
    left_out = result.episode.extra["left_out_keys"]
    pressed, goal = result.episode.active_keys, result.episode.goal_keys
    fixed = precision_recall_f1(pressed | (left_out & goal), goal)["f1"]
    assert left_out.any() and not (left_out & pressed).any()
    assert metrics["f1_lost_plan_left_out"] == pytest.approx(fixed - metrics["f1"])
    assert metrics["f1_lost_plan_left_out"] > 0.1
    assert metrics["f1_lost_never"] >= metrics["f1_lost_plan_left_out"] - 1e-9


def test_with_one_hand_the_other_reaches_nothing():
    notes = (
        Note(60, 0.5, 1.0, finger=0),
        Note(64, 0.5, 1.0, finger=2),
        Note(84, 0.5, 1.0, finger=4),
    )
    options = {**ENV_OPTIONS, "hands": "right"}
    env = PianoEnv(Song(notes, name="one-hand"), physics="fast", **options)
    planner = IKPlanner()
    env.reset(seed=0)
    planner.reset(env, seed=0)
    coverage = plan_coverage(planner)
    # Two of the three keys fit one hand; the third, two octaves up, is lost at every frame.
    frames = int(env.goal.keys[:, 84 - 21].sum())
    assert frames > 0
    assert coverage.ceiling_lost == frames
