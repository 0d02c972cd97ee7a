"""How much of a piece two hands can play: a plan's coverage against the reach ceiling.

Both count a piece's due key-frames (a key due at a frame) with the hands' reach model: each
finger's sampled reach across the keyboard, white and black keys apart
(:attr:`pianist.control.planner.hand_split.HandReach.full_reach`).

- :func:`frame_ceiling`: per frame, the fewest due keys that *no* placement of the two hands
  lets a finger press. Every frame on its own: both hands anywhere in their slides' ranges
  (the forearm roots at least ``separation_m`` apart, the left on the left), the frame's
  keys split by order across the keyboard (the left hand takes the lowest), and each hand's
  keys matched in order to fingers whose reach covers them. With no travel time and no held
  keys, this bounds the recall of any controller that plays with these fingers' reach,
  whatever its plan, and its F1 (:func:`ceiling_scores`: per step, as the metrics count).
- :func:`planner_ceiling`: the same for a planner's piece and hands (after its reset).
- :func:`plan_coverage`: what a planner's plan (after its reset) makes of the same
  key-frames: left out (no finger sent: a chord wider than the hand), in a shift (the
  hand's fingers lifted while its slide travels), given a finger beyond its reach from the
  planned position, and playable; and the plan's own F1 (:func:`plan_f1`): the score of a
  player that sounds exactly the playable key-frames, what the plan leaves to execution.

``benchmarks/bench_coverage.py`` prints both per piece;
``docs/notes/2026-12-07-planner-plans.md`` reads them.
Arrays in, arrays out; lengths in m.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from pianist.control.planner.forearm import playable_mask as hand_playable_mask
from pianist.control.planner.forearm import reach_model
from pianist.control.planner.hand_plan import key_prefix_values
from pianist.control.planner.hand_split import HandReach
from pianist.control.scoring import step_f1
from pianist.sim import constants as C

if TYPE_CHECKING:
    from pianist.control.planner import IKPlanner

#: Spacing of the slide positions the ceiling tries (m): finer than any finger's reach
#: interval (the narrowest is ~6 mm), so a chord that fits only within a few mm is found.
CEILING_STEP_M = 0.001


def frame_ceiling(
    keys: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    right: HandReach | Sequence[HandReach],
    left: HandReach | Sequence[HandReach],
    separation_m: float,
    tolerance_m: float = 0.0,
    step_m: float = CEILING_STEP_M,
) -> np.ndarray:
    """(T,) int: per frame, the due keys no placement of the two hands plays (module docstring).

    Args:
        keys: (T, 88) bool, keys due at each frame.
        key_y: (88,) press point of each key across the keyboard (m).
        black: (88,) bool, black keys.
        right, left: each hand's reach and slide range (:class:`HandReach`), or its reach
            in each of its poses (a sequence, the same slide range): each hand then takes,
            frame by frame, the pose that plays the most of its keys.
        separation_m: closest the forearm roots may come (m); 0 lets them meet.
        tolerance_m: each finger's reach widened by this on both sides (m): the sampled
            reach is a little conservative, and a bound should not be.
        step_m: spacing of the slide positions tried (m).
    """
    if keys.ndim != 2 or keys.shape[1] != key_y.shape[0]:
        raise ValueError(f"keys must be (T, {key_y.shape[0]}), not {keys.shape}")
    rights, lefts = (
        [_widened(h, tolerance_m) for h in ([x] if isinstance(x, HandReach) else x)]
        for x in (right, left)
    )
    right, left = rights[0], lefts[0]
    grids = [
        np.arange(h.slide_range[0], h.slide_range[1] + step_m / 2, step_m) for h in (right, left)
    ]
    # Where each hand's forearm root is at each candidate, and for every right-hand position
    # the last left-hand position (ascending) that keeps the forearms apart (-1: none).
    right_root = right.root_y + grids[0]
    left_root = left.root_y + grids[1]
    last_left = np.searchsorted(left_root, right_root - separation_m, side="right") - 1
    lost = np.zeros(keys.shape[0], dtype=np.int64)
    cache: dict[tuple[int, ...], int] = {}
    for t in np.flatnonzero(keys.any(axis=1)).tolist():
        ids = np.flatnonzero(keys[t])
        ids = ids[np.argsort(key_y[ids], kind="stable")]
        signature = tuple(ids.tolist())
        if signature not in cache:
            cache[signature] = _fewest_lost(ids, key_y, black, rights, lefts, grids, last_left)
        lost[t] = cache[signature]
    return lost


def _fewest_lost(
    ids: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    rights: list[HandReach],
    lefts: list[HandReach],
    grids: list[np.ndarray],
    last_left: np.ndarray,
) -> int:
    """One frame's keys (ascending y): how many the best placement, poses and split leave
    unplayed."""
    # high[s, p]: how many of the highest s keys the right hand plays from position p in its
    # best pose for them; low[s, q] the same for the left hand and the lowest s keys (edges
    # count in full: edge cost 0).
    high = _prefix_values(ids, key_y, black, rights, grids[0], "down")
    low = _prefix_values(ids, key_y, black, lefts, grids[1], "up")
    # For each right-hand position, the best left-hand position that keeps clear of it.
    best_low = np.maximum.accumulate(low, axis=1)  # (n + 1, PL): best over q' <= q
    clear = last_left >= 0
    best = 0.0
    n = ids.size
    for s in range(n + 1):  # the left hand takes the lowest s keys
        if not clear.any():
            break
        total = high[n - s, clear] + best_low[s, last_left[clear]]
        best = max(best, float(total.max()))
    return int(round(n - best))


def _prefix_values(
    ids: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    poses: list[HandReach],
    grid: np.ndarray,
    direction: str,
) -> np.ndarray:
    """(n + 1, P): the most keys of the frame's n (``ids``, ascending y) one hand plays from
    each slide position of ``grid``, in its best pose of ``poses``, taking them from the top
    (``direction="down"``) or the bottom (``"up"``). Only the positions from which some
    finger reaches some of the keys are searched: elsewhere the hand plays none."""
    y = key_y[ids]
    lo = min(float(y.min() - h.full_reach[..., 1].max()) for h in poses)
    hi = max(float(y.max() - h.full_reach[..., 0].min()) for h in poses)
    first, last = np.searchsorted(grid, [lo - 1e-9, hi + 1e-9], side="left")
    out = np.zeros((ids.size + 1, grid.size))
    if last > first:
        ones = np.ones(ids.size)
        window = grid[first:last]
        out[:, first:last] = np.max(
            [
                key_prefix_values(
                    ids, ones, key_y, black, h.full_reach, h.full_reach, window, 0.0, direction
                )
                for h in poses
            ],
            axis=0,
        )
    return out


def _widened(hand: HandReach, tolerance_m: float) -> HandReach:
    """``hand`` with every finger's full reach widened by ``tolerance_m`` on both sides; a
    finger the sampling never brought to a key colour (the thumb on a black key, given a
    single point) reaches none of it."""
    full = hand.full_reach + np.array([-tolerance_m, tolerance_m])
    never = (hand.full_reach[..., 1] - hand.full_reach[..., 0]) < 1e-6
    # An empty interval (low above high) around the same point keeps the fingers' order.
    full[never] = hand.full_reach[never] + np.array([1e-3, -1e-3])
    return HandReach(full, full, hand.root_y, hand.slide_range)


def ceiling_scores(keys: np.ndarray, lost: np.ndarray) -> tuple[float, float]:
    """The episode recall and F1 (each the mean over the T steps, as the metrics take them)
    of a player that presses, at every frame, all the due keys but ``lost`` (T,) of them and
    nothing else: the most any controller scores when :func:`frame_ceiling` gives ``lost``
    (a step's F1 grows with its recall and its precision, here 1).
    """
    due = keys.sum(axis=1)
    recall = np.where(due > 0, (due - lost) / np.maximum(due, 1), 1.0)
    f1 = 2.0 * recall / (1.0 + recall)
    return float(recall.mean()), float(f1.mean())


@dataclass(frozen=True)
class Coverage:
    """A piece's due key-frames as a plan leaves them, and the ceiling (module docstring)."""

    due: int
    """Key-frames due in the piece."""
    left_out: int
    """Due with no finger of either hand sent (the plan leaves them out)."""
    in_shift: int
    """Given a finger of a hand that is shifting then (its fingers lifted)."""
    out_of_reach: int
    """Given a finger, the hand not shifting, but beyond the finger's reach from the planned
    position (by more than ``playable_tolerance_m``)."""
    playable: int
    """Given a finger that reaches the key from the planned position, the hand not shifting."""
    ceiling_lost: int
    """Due key-frames no placement of the two hands plays (:func:`frame_ceiling`)."""
    ceiling_recall: float
    """The episode recall no controller with these fingers' reach can pass
    (:func:`ceiling_scores`)."""
    ceiling_f1: float
    """The episode F1 no controller with these fingers' reach can pass."""
    straight_ceiling_f1: float
    """The same with each hand held in its home pose (the wrist straight): the ceiling of
    a planner that never turns the wrist, not of the hands."""
    plan_f1: float
    """The episode F1 of sounding exactly the plan's playable key-frames (:func:`plan_f1`)."""

    def share(self, field: str) -> float:
        """A count as a share of the due key-frames."""
        return float(getattr(self, field)) / max(self.due, 1)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


def planner_ceiling(
    planner: IKPlanner,
    able: Callable[[HandReach], HandReach] | None = None,
    reaches: dict[str, list[HandReach]] | None = None,
) -> np.ndarray:
    """:func:`frame_ceiling` of ``planner``'s piece and hands (after its reset), with its key
    points, forearm separation and ``playable_tolerance_m``; ``reaches``: each hand's reach
    per pose, by side (default: the home pose's, the wrist straight; the whole hand's is
    :meth:`IKPlanner.whole_hand_reaches`); ``able`` maps each reach to another (what if the
    hands could do more). A scene with one hand: the other reaches nothing and is never in
    the way."""
    cfg = planner.config
    reach = reaches or {
        hand.side: [reach_model(hand, poses)]
        for hand, poses in zip(planner.hands, planner.poses, strict=True)
    }
    nothing = np.zeros((5, 2, 2))
    right = reach.get("right", [HandReach(nothing, nothing, 1e3, (0.0, 0.0))])
    left = reach.get("left", [HandReach(nothing, nothing, -1e3, (0.0, 0.0))])
    if able is not None:
        right, left = [able(h) for h in right], [able(h) for h in left]
    return frame_ceiling(
        planner.goal.keys,
        planner.key_point[:, 1],
        C.BLACK_KEY_MASK,
        right,
        left,
        cfg.forearm.forearm_separation_m,
        tolerance_m=cfg.plan.playable_tolerance_m,
    )


def playable_mask(planner: IKPlanner) -> np.ndarray:
    """(T, 88) bool: the due keys ``planner``'s plan (after its reset) leaves playable at each
    frame, both hands (:func:`pianist.control.planner.forearm.playable_mask`)."""
    mask = np.zeros(planner.goal.keys.shape, dtype=bool)
    for hand, arrays, poses in zip(planner.hands, planner.plan.hands, planner.poses, strict=True):
        mask |= hand_playable_mask(planner, hand, arrays, poses)
    return mask


def plan_f1(planner: IKPlanner) -> float:
    """The episode F1 (mean of the per-step F1, as the metrics take it) of a player that
    sounds exactly the key-frames ``planner``'s plan leaves playable and nothing else: what
    the plan allows, all of which execution can still lose."""
    return float(step_f1(playable_mask(planner), planner.goal.keys).mean())


def plan_key_classes(planner: IKPlanner) -> tuple[np.ndarray, np.ndarray]:
    """The due key-frames ``planner``'s plan (after its reset) gives up, two (T, 88) bool
    masks: those it sends no finger to (left out: a chord wider than the hand, a key out of
    reach), and those of a hand whose fingers it lifts for a shift of the forearm."""
    keys = planner.goal.keys
    given = np.zeros_like(keys)
    in_shift = np.zeros_like(keys)
    for hand, arrays in zip(planner.hands, planner.plan.hands, strict=True):
        local = planner.fingers - hand.finger_offset
        mine = keys & ~arrays.skip & (local >= 0) & (local < 5)
        given |= mine
        in_shift |= mine & arrays.free[:, None]
    return keys & ~given, in_shift


def plan_coverage(planner: IKPlanner) -> Coverage:
    """What ``planner``'s plan makes of its piece's due key-frames, beside the ceiling.

    ``planner`` must have been reset on its environment (the plan and the hands' reach are
    made then).
    """
    keys = planner.goal.keys
    left_out_keys, shift_keys = plan_key_classes(planner)
    in_shift = int(shift_keys.sum())
    playable = int(playable_mask(planner).sum())
    lost = planner_ceiling(planner, reaches=planner.whole_hand_reaches())
    _, straight_f1 = ceiling_scores(keys, planner_ceiling(planner))
    due = int(keys.sum())
    left_out = int(left_out_keys.sum())
    recall, f1 = ceiling_scores(keys, lost)
    return Coverage(
        due=due,
        left_out=left_out,
        in_shift=in_shift,
        out_of_reach=due - left_out - in_shift - playable,
        playable=playable,
        ceiling_lost=int(lost.sum()),
        ceiling_recall=recall,
        ceiling_f1=f1,
        straight_ceiling_f1=straight_f1,
        plan_f1=plan_f1(planner),
    )
