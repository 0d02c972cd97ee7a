"""Which hand plays which key: both hands planned together over a whole piece.

The whole-piece plan of one hand (:mod:`pianist.control.planner.hand_plan`) takes the song's hands
as given; where a chord is wider than the hand it drops keys, and only then offers them to
the other hand. Planned one after the other, the first hand cannot leave a key to the
other, which may have had it within reach (the tenor of a chorale under the right thumb
while the left hand has a finger free beside it), and the two forearms, which must stay
``separation_m`` apart, crowd each other.

Here the two hands are planned jointly, on a coarse grid of slide positions, by a Viterbi
over states (right position, left position):

- **Staying** costs, per frame, the weighted keys left unplayed by the best *split* of the
  frame's keys (ordered across the keyboard, the left hand takes the lowest ``s``, the right
  the rest) and each hand's best order-keeping assignment of its keys to fingers that reach
  them (:func:`pianist.control.planner.hand_plan.key_prefix_values`); a key played by the hand the
  song does not give it costs ``other_hand_cost`` (at a tie the song's hands win). Forearms
  closer than ``separation_m`` cost ``clearance_cost`` per frame.
- **Moving** costs what each hand's move costs in the one-hand plan (separately for the two
  hands): a small move, more per held key; a shift, the key-frames the hand (as the song
  gives them) loses while its slide travels.

The result is the split, (T, 88) which hand plays each due key; each hand's fine plan (and
fingering) is then made for its keys by :func:`pianist.control.planner.hand_plan.plan_hand`.
Arrays in, arrays out; lengths in m, times in frames (control steps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pianist.control.planner.hand_plan import HandPlanCosts, key_prefix_values, move_frames

RIGHT, LEFT = 0, 1


@dataclass(frozen=True)
class HandReach:
    """What one hand reaches, as the one-hand plan takes it (see :func:`plan_hand`)."""

    full_reach: np.ndarray
    """(5, 2, 2) per finger, white/black key: lowest and highest (key y - slide) it presses."""
    reach: np.ndarray
    """(5, 2, 2) the same without the edges where a finger slips."""
    root_y: float
    """Where the forearm's slide is 0, across the keyboard (m)."""
    slide_range: tuple[float, float]
    """Lowest and highest slide positions (m)."""


@dataclass(frozen=True)
class SplitCosts:
    """Weights of the joint plan, in lost key-frames (see the module docstring)."""

    grid_m: float = 0.012
    """Spacing of the candidate slide positions: coarse, the one-hand plans refine them."""
    fine_m: float = 0.003
    """Spacing at which what a hand reaches within each grid cell is sampled."""
    other_hand_cost: float = 0.05
    """A key played by the hand the song does not give it, per frame."""
    separation_m: float = 0.17
    """Closest the two forearm roots may come."""
    clearance_cost: float = 5.0
    """Per frame with the forearms closer than ``separation_m``."""
    hand: HandPlanCosts = HandPlanCosts()
    """The one-hand plan's weights (moves, shifts, edges, outer voice)."""


def split_hands(
    keys: np.ndarray,
    song_hand: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    right: HandReach,
    left: HandReach,
    dt: float,
    costs: SplitCosts | None = None,
) -> np.ndarray:
    """Which hand plays each due key over a piece (module docstring).

    Args:
        keys: (T, 88) bool, keys due at each frame.
        song_hand: (T, 88) int, the song's hand of each due key: 0 right, 1 left, -1 none.
        key_y: (88,) press point of each key across the keyboard (m).
        black: (88,) bool, black keys.
        right, left: the hands' reach (:class:`HandReach`).
        dt: control step (s).
        costs: the weights (:class:`SplitCosts`).
    Returns:
        (T, 88) int8: 0 the right hand plays the key, 1 the left, -1 where none is due.
        The split is by order across the keyboard, so a key neither hand reaches from the
        planned positions is still given to one; that hand's own plan leaves it out.
    """
    c = costs or SplitCosts()
    T = keys.shape[0]
    split = np.full(keys.shape, -1, dtype=np.int8)
    if not keys.any():
        return split
    due_y = key_y[np.flatnonzero(keys.any(axis=0))]
    grids = [_grid(hand, due_y, c.grid_m, c.separation_m) for hand in (right, left)]
    starts = np.flatnonzero(np.r_[True, (keys[1:] != keys[:-1]).any(axis=1)])
    lengths = np.diff(np.r_[starts, T])
    # Per segment: the weighted keys it leaves unplayed from every (right, left) state.
    stay, best_split = _segment_stay(keys, song_hand, key_y, black, right, left, grids, starts, c)
    gap = (right.root_y + grids[RIGHT][:, None]) - (left.root_y + grids[LEFT][None, :])
    stay += np.where(gap < c.separation_m, c.clearance_cost, 0.0)[None] * lengths[:, None, None]
    moves = [
        _MoveCosts(keys & (song_hand == side), grids[side], dt, c.hand) for side in (RIGHT, LEFT)
    ]
    path = _joint_viterbi(stay, moves, starts)
    for s, (t0, n) in enumerate(zip(starts.tolist(), lengths.tolist(), strict=True)):
        ids = np.flatnonzero(keys[t0])
        if ids.size == 0:
            continue
        ids = ids[np.argsort(key_y[ids], kind="stable")]
        cut = best_split[s][path[s][0], path[s][1]]
        hand = np.where(np.arange(ids.size) < cut, LEFT, RIGHT).astype(np.int8)
        split[t0 : t0 + n, ids] = hand
    return split


def _grid(hand: HandReach, due_y: np.ndarray, step: float, margin: float) -> np.ndarray:
    """(P,) candidate slide positions of a hand: those that bring some due key in reach, and
    ``margin`` beyond them (to make way for the other forearm)."""
    lo = float(due_y.min() - hand.full_reach[..., 1].max()) - step - margin
    hi = float(due_y.max() - hand.full_reach[..., 0].min()) + step + margin
    lo, hi = max(hand.slide_range[0], lo), min(hand.slide_range[1], hi)
    return np.arange(lo, hi + step / 2, step) if hi > lo else np.array([lo])


def _segment_stay(
    keys: np.ndarray,
    song_hand: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    right: HandReach,
    left: HandReach,
    grids: list[np.ndarray],
    starts: np.ndarray,
    c: SplitCosts,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """(S, PR, PL) cost of each segment from each state, and per segment (PR, PL) the best
    split (how many of the segment's keys, lowest first, the left hand takes)."""
    T = keys.shape[0]
    lengths = np.diff(np.r_[starts, T])
    PR, PL = len(grids[RIGHT]), len(grids[LEFT])
    stay = np.zeros((len(starts), PR, PL))
    splits: list[np.ndarray] = []
    cache: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}
    for s, t0 in enumerate(starts.tolist()):
        ids = np.flatnonzero(keys[t0])
        if ids.size == 0:
            splits.append(np.zeros((PR, PL), dtype=np.int64))
            continue
        ids = ids[np.argsort(key_y[ids], kind="stable")]
        hands = song_hand[t0, ids]
        signature = (*ids.tolist(), -1, *hands.tolist())
        if signature not in cache:
            cache[signature] = _frame_stay(ids, hands, key_y, black, right, left, grids, c)
        cost, cut = cache[signature]
        stay[s] = cost * lengths[s]
        splits.append(cut)
    return stay, splits


def _frame_stay(
    ids: np.ndarray,
    hands: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    right: HandReach,
    left: HandReach,
    grids: list[np.ndarray],
    c: SplitCosts,
) -> tuple[np.ndarray, np.ndarray]:
    """One frame's keys (ascending y, with the song's hands): (PR, PL) the weighted keys
    the best split leaves unplayed, and (PR, PL) that split."""
    n = ids.size
    weights = np.ones(n)
    weights[-1] = weights[0] = c.hand.outer_voice_weight  # the top and the bass
    # values[s, p]: the most the left hand makes of the lowest s keys from position p; the
    # right hand, of the highest s keys.
    low = _cell_values(ids, weights, key_y, black, left, grids[LEFT], c, "up")
    high = _cell_values(ids, weights, key_y, black, right, grids[RIGHT], c, "down")
    # Keys the split gives the hand the song does not: the left's among the lowest s keys
    # the song gives the right, and the other way round.
    to_left = np.r_[0, np.cumsum(hands == RIGHT)]  # (n + 1,)
    to_right = np.r_[0, np.cumsum((hands == LEFT)[::-1])][::-1]  # keys s.. given to the left
    penalty = c.other_hand_cost * (to_left + to_right)  # (n + 1,)
    total = (
        high[::-1][:, :, None] + low[:, None, :] - penalty[:, None, None]
    )  # (n + 1, PR, PL): split s
    cut = np.argmax(total, axis=0)
    return weights.sum() - np.max(total, axis=0), cut


def _cell_values(
    ids: np.ndarray,
    weights: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    hand: HandReach,
    grid: np.ndarray,
    c: SplitCosts,
    direction: str,
) -> np.ndarray:
    """(n + 1, P) :func:`key_prefix_values` of the best position within each grid cell
    (sampled every ``fine_m``): a chord's fingers may reach it only within a few mm, which a
    coarse grid would step over."""
    steps = max(1, round(c.grid_m / c.fine_m))
    offsets = (np.arange(steps) - (steps - 1) / 2) * (c.grid_m / steps)
    fine = (grid[:, None] + offsets[None, :]).ravel()
    values = key_prefix_values(
        ids, weights, key_y, black, hand.full_reach, hand.reach, fine, c.hand.edge_cost, direction
    )
    return values.reshape(len(ids) + 1, len(grid), steps).max(axis=2)


class _MoveCosts:
    """One hand's move costs into a segment from every candidate to every candidate."""

    def __init__(self, mine: np.ndarray, grid: np.ndarray, dt: float, c: HandPlanCosts) -> None:
        T = mine.shape[0]
        self.c = c
        distance = np.abs(grid[:, None] - grid[None, :])
        self.shift = distance > c.shift_m
        self.frames_needed = move_frames(distance, dt, c.slide_acceleration_m_s2)
        self.moved = distance > 1e-9
        self.small = np.where(self.moved, c.small_move_cost + c.small_move_cost_per_m * distance, 0)
        lost = np.zeros(T + 1)
        lost[1:] = np.cumsum(mine.sum(axis=1))
        self.lost = lost
        self.held = np.zeros(T)
        self.held[1:] = (mine[1:] & mine[:-1]).sum(axis=1)

    def into(self, t: int) -> np.ndarray:
        """(P, P) from -> to: the cost of moving into frame ``t``."""
        before = self.lost[t] - self.lost[np.maximum(t - self.frames_needed, 0)]
        held = self.small + self.moved * self.held[t] * self.c.held_move_cost
        return np.where(self.shift, before + self.c.shift_cost, held)


def _joint_viterbi(
    stay: np.ndarray, moves: list[_MoveCosts], starts: np.ndarray
) -> list[tuple[int, int]]:
    """The cheapest path of (right, left) candidate indices, one per segment.

    The two hands' move costs add, so the minimum over the previous state is taken one hand
    at a time: O(P^3) per segment instead of O(P^4).
    """
    S, PR, PL = stay.shape
    value = stay[0].copy()
    back_r = np.zeros((S, PR, PL), dtype=np.int32)
    back_l = np.zeros((S, PR, PL), dtype=np.int32)
    for s in range(1, S):
        t = int(starts[s])
        move_r, move_l = moves[RIGHT].into(t), moves[LEFT].into(t)
        # First the left hand: via[i, l] = min_j value[i, j] + move_l[j, l].
        through_l = value[:, :, None] + move_l[None, :, :]  # (PR, PL from, PL to)
        arg_l = np.argmin(through_l, axis=1)  # (PR, PL to)
        via = np.take_along_axis(through_l, arg_l[:, None, :], axis=1)[:, 0, :]
        # Then the right: value'[k, l] = min_i via[i, l] + move_r[i, k].
        through_r = via[:, None, :] + move_r[:, :, None]  # (PR from, PR to, PL)
        arg_r = np.argmin(through_r, axis=0)  # (PR to, PL)
        value = np.take_along_axis(through_r, arg_r[None], axis=0)[0] + stay[s]
        back_r[s] = arg_r
        back_l[s] = np.take_along_axis(arg_l, arg_r, axis=0)  # left's previous, given right's
    last = np.unravel_index(int(np.argmin(value)), value.shape)
    path = [(int(last[0]), int(last[1]))] * S
    for s in range(S - 1, 0, -1):
        r, l_ = path[s]
        path[s - 1] = (int(back_r[s, r, l_]), int(back_l[s, r, l_]))
    return path
