"""Where a hand is along the keyboard over a whole piece, chosen before the first step.

A dynamic programme over the piece's frames and a grid of candidate forearm slide positions
(Viterbi): each frame's cost is what a hand at that position loses, and each move between
frames costs what the move loses. The cheapest path over the whole piece is the plan.

- **Staying** at position p for frame t costs, for each key due then for this hand, 1 if its
  finger cannot press it from p at all (the key-frame is lost), ``edge_cost`` if it can only
  at the edge of its reach (where fingers slip), plus a small ``comfort_cost`` that grows with
  the distance from where the fingers rest over their keys.
- **Moving** from p to q between frames t-1 and t: a move of up to ``shift_m`` (in a reach
  pose ``reach_pose_shift_m``) is made with the fingers on the keys and costs a little, more
  for every key held through it; a larger one (a shift) lifts the hand's fingers for the
  frames the slide needs to get there (from its servo's measured speed, :func:`move_frames`),
  so it costs the hand's key-frames due in those frames before t, plus ``shift_cost``.
- **Poses** (given the reach of K poses): every candidate is a position in a pose; a change
  of pose (the wrist turned) is a shift of at least the wrist's frames, and a pose other
  than the first is counted to lose a share of the hand's keys (``reach_pose_loss`` where
  a chord struck together wants it, ``reach_pose_idle_loss`` elsewhere) and is a candidate
  only near such chords (``reach_pose_window``).
- **Counting** (``HandPlanCosts.objective``): a lost key costs its weight (``key_frames``),
  or the F1 it takes from its frame's step (``step_f1``, :func:`step_f1_costs`), the unit
  of the metric, which averages each step's F1: a key lost from a step with one key due
  costs far more than one of a chord.

So the plan stays put while every key is reachable, moves during rests when it can, starts
long jumps early enough for the slide to arrive, and, where a chord is wider than the hand,
keeps the most keys (the outer voice weighted higher), which :func:`skipped_keys` reports.
Everything here is arrays in, arrays out; lengths in m, times in frames (control steps).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

#: What the plan counts a lost key as (:attr:`HandPlanCosts.objective`).
Objective = Literal["key_frames", "step_f1"]

#: Worth of keeping a held key's finger on it, against 1 for playing a key at all.
HELD_BONUS = 0.5

#: Average acceleration of a forearm slide's servo over a stop-to-stop move, m/s^2, fitted to
#: the arrival times measured in closed loop (kp 300, ~3.8 kg, command range ~1.2 m): within
#: ~8 mm after 2 steps of 0.05 s for 5 cm, 3 for 10 cm, 4 for 20 cm, 6 for 40 cm.
SLIDE_ACCELERATION_M_S2 = 20.0


@dataclass(frozen=True)
class HandPlanCosts:
    """Weights of the hand-position programme, in lost key-frames (see the module docstring)."""

    grid_m: float = 0.004
    """Spacing of the candidate slide positions (the alignment tolerance is ~9 mm)."""
    edge_cost: float = 0.25
    """A key its finger reaches only at the edge of its reach, per frame."""
    outer_voice_weight: float = 1.5
    """Weight of the outer voice's keys (top of the right hand, bass of the left)."""
    comfort_cost: float = 0.005
    """Per frame, per (cm from the fingers' resting places over their keys)^2 ..."""
    comfort_cap: float = 0.05
    """... capped at this per frame."""
    shift_m: float = 0.015
    """Largest move made with the fingers on the keys."""
    reach_pose_shift_m: float | None = None
    """``shift_m`` within a pose other than the first (None: the same). A hand turned for
    octaves moves a white key (23.5 mm) at a time; with the fingers lifted for each such
    move it loses two frames of every note (the plan that turns for spans moves up to
    0.03 m on the keys, :data:`~pianist.control.planner.config.TURN_FOR_SPANS`)."""
    small_move_cost: float = 0.2
    """Cost of a move made with the fingers on the keys ..."""
    small_move_cost_per_m: float = 10.0
    """... plus this per metre ..."""
    held_move_cost: float = 1.0
    """... plus this per key held through it (a move drags the held keys' fingers, and
    may give a held key to another finger, which lets it up)."""
    shift_cost: float = 0.3
    """Cost of a shift on top of the key-frames it loses."""
    pose_change_cost: float = 0.5
    """Cost of a change of the hand's pose (a reach pose, the wrist turned; see ``poses``
    in :func:`plan_hand`) on top of a shift's: the hand lands less surely after a turn."""
    reach_pose_loss: float = 0.02
    """The share of a hand's keys a pose other than the first (the wrist turned) is counted
    to lose at every frame where it is wanted: a chord struck together that the first pose
    covers from no position (a block octave: one key of two lost straight, against 2 x this
    turned) ..."""
    reach_pose_idle_loss: float = 1.0
    """... and at every other frame (keys held from earlier among them, or a chord the first
    pose covers): fingers at the edge of the turned hand's reach land less surely, and in
    moving passages they lost more than the keys the straight hand gives up."""
    reach_pose_edge_cost: float | None = None
    """``edge_cost`` in a pose other than the first (None: the same). A reach pose is
    wanted for chords at the edge of what it reaches (an octave's thumb and little finger
    both are), where the first pose's edge cost would rather leave a key out than play it."""
    reach_pose_window: int = 3
    """Frames before and after a chord that wants a reach pose in which the plan may keep
    a hand in it (elsewhere the pose is not a candidate, so a piece without such chords
    is planned as fast as with one pose)."""
    reach_pose_for: Literal["chords", "spans"] = "chords"
    """What wants a reach pose: ``chords`` struck together that the first pose cannot
    cover from any position, or also (``spans``) a hand's keys within ``reach_pose_window``
    frames of each other spanning wider than the first pose reaches and no wider than a
    reach pose does (broken octaves: one key at a time, an octave apart)."""
    objective: Objective = "key_frames"
    """What a lost key costs. ``key_frames``: its weight, the same in every frame.
    ``step_f1``: what it takes from the frame's F1, the metric's unit (F1 per step, averaged
    over steps): the one key of a frame costs the whole step, one key of a six-key chord
    (both hands' keys counted) about a tenth of one; times ``step_f1_scale``."""
    step_f1_scale: float = 20.0
    """With ``objective="step_f1"``: key-frames' worth of one step's F1, the exchange rate
    against the costs above that are not lost keys (comfort, moves, shifts), which stay in
    key-frames."""
    slide_acceleration_m_s2: float = SLIDE_ACCELERATION_M_S2
    """The slide's acceleration the plan counts its moves' frames by (:func:`move_frames`);
    the servo that plays the plan is not changed by it. Other values are what-ifs
    (``benchmarks/bench_coverage.py --plan-variants``: moves that take no time)."""
    step_f1_move_scale: float = 4.0
    """With ``objective="step_f1"``, the move, shift and held-key costs times this: a hand
    that moves loses more in execution (late landings, a swing of the wrist) than the
    key-frames the plan counts, and against keys counted at ``step_f1_scale`` a plan with
    cheap moves moves too often."""


def move_frames(
    distance_m: np.ndarray | float, dt: float, acceleration_m_s2: float = SLIDE_ACCELERATION_M_S2
) -> np.ndarray:
    """Control steps a slide needs for a stop-to-stop move of ``distance_m`` (at least 1).

    Bang-bang at ``acceleration_m_s2`` (default :data:`SLIDE_ACCELERATION_M_S2`):
    t = 2 sqrt(d / a).
    """
    if not acceleration_m_s2 > 0:
        raise ValueError(f"a slide's acceleration must be > 0 m/s^2, not {acceleration_m_s2}")
    seconds = 2.0 * np.sqrt(np.abs(np.asarray(distance_m, dtype=float)) / acceleration_m_s2)
    return np.maximum(1, np.ceil(seconds / dt - 1e-9)).astype(int)


@dataclass(frozen=True)
class HandPlan:
    """The plan of one hand over a piece of T frames.

    Attributes:
        position: (T,) slide position (m) at every frame; frames without notes hold the next
            note's position (the hand goes there as early as it can).
        busy: (T,) whether the hand has a key due at the frame.
        fingers: (T, 88) the finger (0 thumb .. 4 little) that presses each of the hand's due
            keys, -1 where none: the song's own, or with ``refinger`` the plan's.
        skip: (T, 88) keys of this hand that the plan leaves unplayed (out of reach from the
            planned position: a chord wider than the hand).
        cost: the plan's total cost (lost key-frames and penalties).
        pose: (T,) int, the hand's pose at every frame (index into the reaches given; 0,
            the first, with one reach); held like ``position`` between notes.
    """

    position: np.ndarray
    busy: np.ndarray
    fingers: np.ndarray
    skip: np.ndarray
    cost: float
    pose: np.ndarray


def plan_hand(
    keys: np.ndarray,
    fingers: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    full_reach: np.ndarray,
    reach: np.ndarray,
    rest_offset: np.ndarray,
    slide_range: tuple[float, float],
    start: float,
    dt: float,
    outer: str,
    costs: HandPlanCosts | None = None,
    refinger: bool = False,
    extra_cost: Callable[[np.ndarray], np.ndarray] | None = None,
    other_kept: np.ndarray | None = None,
    pose_frames: int = 1,
) -> HandPlan:
    """The cheapest slide positions (and poses) over a piece for one hand (module docstring).

    With the reaches of K poses (``full_reach`` (K, 5, 2, 2)), every candidate is a
    position in a pose: the plan chooses the pose with the position, a change of pose
    costing a shift of at least ``pose_frames`` frames plus ``pose_change_cost``, and the
    hand starts in pose 0.

    Args:
        keys: (T, 88) bool, keys due at each frame.
        fingers: (T, 88) int, the finger of each due key *in this hand* (0 thumb .. 4
            little), -1 for keys of the other hand or none.
        key_y: (88,) press point of each key across the keyboard (m).
        black: (88,) bool, black keys.
        full_reach: (5, 2, 2) per finger, white (0) / black (1) key: the lowest and highest
            (key y - slide position) at which the finger can press the key; or (K, 5, 2, 2),
            one per pose.
        reach: (5, 2, 2) or (K, 5, 2, 2) the same, without the edges where a finger slips.
        rest_offset: (5,) or (K, 5) key y - slide position that puts each finger at its
            resting place.
        slide_range: (low, high) slide positions (m).
        start: the slide's position before the first frame (m).
        dt: control step (s).
        outer: "top" (right hand) or "bottom" (left hand): the voice kept first.
        costs: the weights (:class:`HandPlanCosts`).
        refinger: choose the fingers too: at every position, each key goes to a finger that
            reaches it from there, in order across the hand (the most keys, the outer voice
            first); ``fingers`` then only says which keys are this hand's.
        extra_cost: candidate positions (P,) -> (T, P) further cost of each (e.g. coming too
            close to the other forearm).
        other_kept: (T,) with ``objective="step_f1"``, the keys the other hand's plan keeps
            at each frame (None: all the due keys that are not this hand's).
        pose_frames: frames a change of pose takes (the wrist's servos), >= 1.
    Returns:
        The :class:`HandPlan`.
    """
    c = costs or HandPlanCosts()
    T = keys.shape[0]
    full_k, reach_k = np.asarray(full_reach), np.asarray(reach)
    rest_k = np.asarray(rest_offset)
    if full_k.ndim == 3:
        full_k, reach_k, rest_k = full_k[None], reach_k[None], rest_k[None]
    K = full_k.shape[0]
    mine = keys & (fingers >= 0)
    busy = np.asarray(mine.any(axis=1))
    skip = np.zeros(keys.shape, dtype=bool)
    if not busy.any():
        held_fingers = np.where(mine, fingers, -1)
        no_pose = np.zeros(T, dtype=int)
        return HandPlan(np.full(T, float(start)), busy, held_fingers, skip, 0.0, no_pose)
    frames, key_ids = np.nonzero(mine)
    offset = key_y[key_ids]
    colour = black[key_ids].astype(int)
    grid = _candidate_positions(offset, full_k, slide_range, c.grid_m)
    P = len(grid)
    weights = _voice_weights(frames, offset, T, outer, c.outer_voice_weight)
    # Every candidate is a position in a pose: (T, K * P), pose-major.
    # The hand moves only where its keys change: frames with the same keys form one segment.
    starts = np.flatnonzero(np.r_[True, (mine[1:] != mine[:-1]).any(axis=1)])
    segment = np.cumsum(np.isin(np.arange(T), starts)) - 1  # (T,) each frame's segment
    stays: list[np.ndarray] = []
    centres: list[np.ndarray] = []
    for q in range(K):
        if q == 1:
            # A reach pose is wanted for a chord struck together that the first pose cannot
            # cover, and is a candidate only in the segments near such chords (its costs
            # are needed nowhere else).
            wanted = _struck_together(mine) & (stays[0].min(axis=1) >= 0.5)
            w = c.reach_pose_window
            if c.reach_pose_for == "spans":
                span = _window_span(mine, key_y, w)
                wanted |= (span > _span(full_k[:1])) & (span <= _span(full_k[1:]))
            near = np.convolve(wanted, np.ones(2 * w + 1))[w : w + T] > 0  # within w frames
            near = np.isin(segment, segment[near])
        keep = slice(None) if q == 0 else near[frames]
        cq = c if q == 0 else _pose_costs(c)
        if refinger:
            stays.append(
                _matching_costs(
                    frames[keep],
                    key_ids[keep],
                    key_y,
                    black,
                    weights[keep],
                    full_k[q],
                    reach_k[q],
                    grid,
                    T,
                    cq,
                )
            )
            centres.append(np.full(len(frames), rest_k[q][rest_k.shape[1] // 2]))
        else:
            finger_ids = fingers[frames, key_ids]
            lo, hi = full_k[q][finger_ids, colour].T  # (n,) each
            lo_in, hi_in = reach_k[q][finger_ids, colour].T
            stays.append(_stay_costs(frames, offset, lo, hi, lo_in, hi_in, weights, grid, T, cq))
            centres.append(rest_k[q][finger_ids])
    if K == 1:
        wanted = near = np.zeros(T, dtype=bool)
    frame_cost = np.zeros(T)  # what losing all the hand's keys at a frame costs
    np.add.at(frame_cost, frames, weights)
    stay = np.concatenate(stays, axis=1)
    loss = np.where(wanted, c.reach_pose_loss, c.reach_pose_idle_loss)
    stay[:, P:] += (loss * frame_cost)[:, None]
    if c.objective == "step_f1":
        stay, frame_cost = step_f1_costs(keys, mine, stay, other_kept, c.step_f1_scale)
        k = c.step_f1_move_scale
        c = replace(
            c,
            small_move_cost=k * c.small_move_cost,
            small_move_cost_per_m=k * c.small_move_cost_per_m,
            held_move_cost=k * c.held_move_cost,
            shift_cost=k * c.shift_cost,
            pose_change_cost=k * c.pose_change_cost,
        )
    stay += np.concatenate(
        [_comfort_costs(frames, offset - centre, grid, T, c) for centre in centres], axis=1
    )
    if extra_cost is not None:
        stay += np.tile(extra_cost(grid), (1, K))
    lost = np.r_[0.0, np.cumsum(frame_cost)]  # lost[t]: the cost of frames before t lost
    held = np.zeros(T)  # keys of the hand due at both t - 1 and t
    held[1:] = (mine[1:] & mine[:-1]).sum(axis=1)
    path, total = _viterbi(stay, lost, held, starts, grid, K, start, dt, c, pose_frames, near)
    position, pose = grid[path % P], path // P
    # Frames without notes hold the next note's place; after the last note, stay.
    known = np.flatnonzero(busy)
    nxt = np.minimum(np.searchsorted(known, np.arange(T)), known.size - 1)
    position = np.where(busy, position, position[known[nxt]])
    pose = np.where(busy, pose, pose[known[nxt]])
    if refinger:
        planned = _assign_fingers(
            mine,
            key_y,
            black,
            position,
            pose,
            full_k,
            reach_k,
            outer,
            c.outer_voice_weight,
            (c.edge_cost, _pose_costs(c).edge_cost),
        )
    else:
        planned = np.where(mine, fingers, -1)
        relative = offset - position[frames]
        lo, hi = full_k[pose[frames], fingers[frames, key_ids], colour].T
        skip[frames, key_ids] = ~_reachable(relative, lo, hi)
    skip |= mine & (planned < 0)
    return HandPlan(position, busy, planned, skip, total, pose)


def _span(full_reach: np.ndarray) -> float:
    """(m) The widest a hand spans in any of the poses ``full_reach`` (K, 5, 2, 2): from the
    lowest key y any finger reaches to the highest, relative to the slide."""
    return float(full_reach[..., 1].max() - full_reach[..., 0].min())


def _window_span(mine: np.ndarray, key_y: np.ndarray, w: int) -> np.ndarray:
    """(T,) m: how far apart the hand's due keys (``mine`` (T, 88)) within ``w`` frames of
    each frame lie along the keyboard (0 where there are none)."""
    T = mine.shape[0]
    low = np.where(mine, key_y, np.inf).min(axis=1)
    high = np.where(mine, key_y, -np.inf).max(axis=1)
    pad = np.full(w, np.inf)
    lows = np.lib.stride_tricks.sliding_window_view(np.r_[pad, low, pad], 2 * w + 1)
    highs = np.lib.stride_tricks.sliding_window_view(np.r_[-pad, high, -pad], 2 * w + 1)
    span = highs.max(axis=1)[:T] - lows.min(axis=1)[:T]
    return np.where(np.isfinite(span), span, 0.0)


def _pose_costs(c: HandPlanCosts) -> HandPlanCosts:
    """The costs of a pose other than the first (its own ``edge_cost``)."""
    if c.reach_pose_edge_cost is None:
        return c
    return replace(c, edge_cost=c.reach_pose_edge_cost)


def _struck_together(mine: np.ndarray) -> np.ndarray:
    """(T,) bool: frames whose due keys (``mine`` (T, 88)) all began at the same frame (a
    chord struck together, none held from before it); False where none is due. Keys in
    their last frame are not counted while others go on (a legato step from one chord to
    the next overlaps them by a frame)."""
    T = mine.shape[0]
    began = mine & ~np.vstack([np.zeros((1, mine.shape[1]), dtype=bool), mine[:-1]])
    going_on = mine & np.vstack([mine[1:], np.zeros((1, mine.shape[1]), dtype=bool)])
    counted = np.where(going_on.any(axis=1)[:, None], going_on, mine)
    # Each due key's note began at the last frame it began at (or before): its start frame.
    start = np.where(began, np.arange(T)[:, None], -1)
    start = np.maximum.accumulate(start, axis=0)
    first = np.where(counted, start, np.iinfo(np.int64).max).min(axis=1)
    last = np.where(counted, start, -1).max(axis=1)
    return mine.any(axis=1) & (first == last)


def _candidate_positions(
    offset: np.ndarray, full_reach: np.ndarray, slide_range: tuple[float, float], step: float
) -> np.ndarray:
    """(P,) candidate slide positions (m): every one, ``step`` apart, that brings some key
    (``offset`` (n,) its y) within some finger's reach in the first pose, extended by whole
    steps to those of the other poses (``full_reach`` (K, 5, 2, 2)); the first pose's
    candidates are the same whatever the other poses."""
    lo_key, hi_key = float(np.min(offset)), float(np.max(offset))

    def bounds(reach: np.ndarray) -> tuple[float, float]:
        low = max(slide_range[0], lo_key - float(np.max(reach[..., 1])) - step)
        high = min(slide_range[1], hi_key - float(np.min(reach[..., 0])) + step)
        return low, high

    low, high = bounds(full_reach[0])
    grid = np.arange(low, high + step / 2, step) if high > low else np.array([low])
    low_all, high_all = bounds(full_reach)
    below = max(0, int(np.ceil((low - low_all) / step - 1e-9)))
    above = max(0, int(np.ceil((high_all - grid[-1]) / step - 1e-9)))
    return np.concatenate(
        [
            grid[0] - step * np.arange(below, 0, -1),
            grid,
            grid[-1] + step * np.arange(1, above + 1),
        ]
    )


def finger_order(full_reach: np.ndarray) -> np.ndarray:
    """(5,) the fingers in order across the keyboard (ascending y): by their white-key reach's
    centre (thumb first for a right hand, little finger first for a left)."""
    return np.argsort(full_reach[:, 0].mean(axis=1), kind="stable")


def _monotone_matching(can: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best order-keeping assignment of n keys (ascending y) to 5 fingers (ascending y).

    Args:
        can: (n, 5, P) whether finger j (in order) can press key i from candidate p.
        value: (n, 5, P) what pressing key i with finger j from p is worth.
    Returns:
        best (n + 1, 6, P): the best total value of the first i keys with the first j fingers;
        and took (n, 5, P) bool: whether the best used the pair (i, j).
    """
    n, F, P = can.shape
    best = np.zeros((n + 1, F + 1, P))
    took = np.zeros((n, F, P), dtype=bool)
    for i in range(1, n + 1):
        for j in range(1, F + 1):
            pair = best[i - 1, j - 1] + np.where(can[i - 1, j - 1], value[i - 1, j - 1], -np.inf)
            skip_key = best[i - 1, j]
            skip_finger = best[i, j - 1]
            take = pair > np.maximum(skip_key, skip_finger)
            took[i - 1, j - 1] = take
            best[i, j] = np.where(take, pair, np.maximum(skip_key, skip_finger))
    return best, took


def key_prefix_values(
    ids: np.ndarray,
    weights: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    full_reach: np.ndarray,
    reach: np.ndarray,
    positions: np.ndarray,
    edge_cost: float,
    direction: str,
) -> np.ndarray:
    """(n + 1, P) the most one hand makes, from each of P positions, of the lowest
    (``direction="up"``) or highest (``"down"``) s of a frame's n keys (ascending y, with
    their ``weights`` (n,)): the best order-keeping assignment of those keys to fingers that
    reach them, each worth its weight (less ``edge_cost`` at the edge of a finger's reach)."""
    order = finger_order(full_reach)
    if direction == "down":
        ids, weights, order = ids[::-1], weights[::-1], order[::-1]
    can, value = _frame_pairs(ids, key_y, black, full_reach, reach, order, positions, edge_cost)
    best, _ = _monotone_matching(can, value * weights[:, None, None])
    return best[:, -1, :]


def _frame_pairs(
    key_ids: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    full_reach: np.ndarray,
    reach: np.ndarray,
    order: np.ndarray,
    positions: np.ndarray,
    c_edge: float,
) -> tuple[np.ndarray, np.ndarray]:
    """For one frame's keys (sorted by y) at P positions: whether each finger (in order
    across the hand) can press each key, (n, 5, P), and what it is worth, (n, 5, P): 1, less
    ``c_edge`` at the edge of the finger's reach."""
    relative = key_y[key_ids][:, None, None] - positions[None, None, :]  # (n, 1, P)
    colour = black[key_ids].astype(int)
    full = full_reach[order][:, colour].transpose(1, 0, 2)  # (n, 5, 2)
    inner = reach[order][:, colour].transpose(1, 0, 2)
    can = _reachable(relative, full[..., 0, None], full[..., 1, None])
    edge = can & ~_reachable(relative, inner[..., 0, None], inner[..., 1, None])
    value = 1.0 - c_edge * edge
    return can, value


def _matching_costs(
    frames: np.ndarray,
    key_ids: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    weights: np.ndarray,
    full_reach: np.ndarray,
    reach: np.ndarray,
    grid: np.ndarray,
    T: int,
    c: HandPlanCosts,
) -> np.ndarray:
    """(T, P) weighted key-frames each candidate loses when the plan picks the fingers."""
    order = finger_order(full_reach)
    stay = np.zeros((T, len(grid)))
    if frames.size == 0:
        return stay
    cache: dict[tuple[int, ...], np.ndarray] = {}
    bounds = np.flatnonzero(np.diff(frames)) + 1
    for group in np.split(np.arange(len(frames)), bounds):
        ids = key_ids[group]
        sorting = np.argsort(key_y[ids], kind="stable")
        ids, w = ids[sorting], weights[group][sorting]
        signature = (*ids.tolist(), *np.round(w, 3).tolist())
        if signature not in cache:
            can, value = _frame_pairs(
                ids, key_y, black, full_reach, reach, order, grid, c.edge_cost
            )
            best, _ = _monotone_matching(can, value * w[:, None, None])
            cache[signature] = w.sum() - best[-1, -1]
        stay[frames[group[0]]] = cache[signature]
    return stay


def _assign_fingers(
    mine: np.ndarray,
    key_y: np.ndarray,
    black: np.ndarray,
    position: np.ndarray,
    pose: np.ndarray,
    full_reach: np.ndarray,
    reach: np.ndarray,
    outer: str,
    outer_weight: float,
    edge_costs: tuple[float, float],
) -> np.ndarray:
    """(T, 88) the finger of each of the hand's due keys at the planned positions and poses
    (``pose`` (T,) into ``full_reach`` / ``reach`` (K, 5, 2, 2)); -1: none.

    A key keeps the finger that struck it while it is held and that finger still reaches it
    (a finger that changed mid-note would let the key up).
    """
    out = np.full(mine.shape, -1)
    for t in np.flatnonzero(mine.any(axis=1)).tolist():
        ids = np.flatnonzero(mine[t])
        ids = ids[np.argsort(key_y[ids], kind="stable")]
        held = (t > 0) & mine[t - 1, ids] & (out[t - 1, ids] >= 0)
        same_place = t > 0 and position[t] == position[t - 1] and pose[t] == pose[t - 1]
        if same_place and held.all():
            out[t, ids] = out[t - 1, ids]
            continue
        k = int(pose[t])
        order = finger_order(full_reach[k])
        extreme = np.argmax(key_y[ids]) if outer == "top" else np.argmin(key_y[ids])
        w = np.ones(len(ids))
        w[extreme] = outer_weight  # the outer voice first
        can, value = _frame_pairs(
            ids,
            key_y,
            black,
            full_reach[k],
            reach[k],
            order,
            position[t : t + 1],
            edge_costs[min(k, 1)],
        )
        value = value * w[:, None, None]
        if t > 0:
            # A held key is worth more with the finger already on it.
            previous = np.where(mine[t - 1, ids], out[t - 1, ids], -1)
            value += HELD_BONUS * (order[None, :] == previous[:, None])[..., None]
        pairs = _best_matching(can[..., 0].tolist(), value[..., 0].tolist())
        for i, j in pairs:
            out[t, ids[i]] = order[j]
    return out


def _best_matching(can: list[list[bool]], value: list[list[float]]) -> list[tuple[int, int]]:
    """:func:`_monotone_matching` for one position, in plain Python (a few keys and five
    fingers: NumPy's per-call overhead would dominate); returns the (key, finger) pairs."""
    n, F = len(can), len(can[0]) if can else 0
    best = [[0.0] * (F + 1) for _ in range(n + 1)]
    took = [[False] * F for _ in range(n)]
    for i in range(1, n + 1):
        row, previous = best[i], best[i - 1]
        for j in range(1, F + 1):
            other = max(previous[j], row[j - 1])
            if can[i - 1][j - 1] and previous[j - 1] + value[i - 1][j - 1] > other:
                row[j] = previous[j - 1] + value[i - 1][j - 1]
                took[i - 1][j - 1] = True
            else:
                row[j] = other
    pairs = []
    i, j = n, F
    while i > 0 and j > 0:
        if took[i - 1][j - 1]:
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif best[i - 1][j] >= best[i][j - 1]:
            i -= 1
        else:
            j -= 1
    return pairs


def _voice_weights(
    frames: np.ndarray, offset: np.ndarray, T: int, outer: str, weight: float
) -> np.ndarray:
    """(n,) weight of each due key: ``weight`` for the frame's outer voice, else 1."""
    extreme = np.full(T, -np.inf if outer == "top" else np.inf)
    if outer == "top":
        np.maximum.at(extreme, frames, offset)
    else:
        np.minimum.at(extreme, frames, offset)
    return np.where(offset == extreme[frames], weight, 1.0)


def step_f1_costs(
    keys: np.ndarray,
    mine: np.ndarray,
    lost: np.ndarray,
    other_kept: np.ndarray | None,
    scale: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Lost keys as the per-step F1 they cost (:attr:`HandPlanCosts.objective`).

    A step's F1 with k of its n due keys pressed and nothing else is 2k / (k + n); a key
    lost from a frame with few keys costs more of it than one from a full chord.

    Args:
        keys: (T, 88) bool, all the keys due (both hands).
        mine: (T, 88) bool, this hand's.
        lost: (T, P) the (weighted) keys of this hand each candidate position loses.
        other_kept: (T,) the keys the other hand keeps (None: all its keys).
        scale: key-frames' worth of one step's F1.
    Returns:
        (T, P) ``scale`` x the step's F1 below the F1 with all this hand's keys kept, for
        each position; and (T,) the same for losing all of them (the frame in a shift).
    """
    due = keys.sum(axis=1).astype(float)
    own = mine.sum(axis=1).astype(float)
    other = due - own if other_kept is None else np.minimum(other_kept, due - own)

    def f1(kept: np.ndarray, due: np.ndarray) -> np.ndarray:
        return np.where(due > 0, 2.0 * kept / np.maximum(kept + due, 1e-9), 1.0)

    full = f1(own + other, due)
    kept = np.maximum(own[:, None] - lost, 0.0) + other[:, None]
    position_cost = scale * (full[:, None] - f1(kept, due[:, None]))
    return position_cost, scale * (full - f1(other, due))


def _reachable(relative: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return (relative >= lo - 1e-9) & (relative <= hi + 1e-9)


def _stay_costs(
    frames: np.ndarray,
    offset: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    lo_in: np.ndarray,
    hi_in: np.ndarray,
    weights: np.ndarray,
    grid: np.ndarray,
    T: int,
    c: HandPlanCosts,
) -> np.ndarray:
    """(T, P) cost of each frame's keys from each candidate position."""
    relative = offset[:, None] - grid[None, :]  # (n, P)
    out_of_reach = ~_reachable(relative, lo[:, None], hi[:, None])
    at_edge = ~out_of_reach & ~_reachable(relative, lo_in[:, None], hi_in[:, None])
    per_key = weights[:, None] * (out_of_reach + c.edge_cost * at_edge)
    stay = np.zeros((T, len(grid)))
    np.add.at(stay, frames, per_key)
    return stay


def _comfort_costs(
    frames: np.ndarray, wanted: np.ndarray, grid: np.ndarray, T: int, c: HandPlanCosts
) -> np.ndarray:
    """(T, P) cost of each candidate's distance from the frame's resting position (the mean
    over its keys of where each key's finger rests over it)."""
    total = np.zeros(T)
    count = np.zeros(T)
    np.add.at(total, frames, wanted)
    np.add.at(count, frames, 1.0)
    busy = count > 0
    centre = np.where(busy, total / np.maximum(count, 1.0), 0.0)
    off_cm = (grid[None, :] - centre[:, None]) / 0.01
    return np.where(busy[:, None], np.minimum(c.comfort_cost * off_cm**2, c.comfort_cap), 0.0)


def _viterbi(
    stay: np.ndarray,
    lost: np.ndarray,
    held: np.ndarray,
    starts: np.ndarray,
    grid: np.ndarray,
    poses: int,
    start: float,
    dt: float,
    c: HandPlanCosts,
    pose_frames: int,
    reach_frames: np.ndarray,
) -> tuple[np.ndarray, float]:
    """The cheapest path of candidate indices (T,) and its cost; the hand may move only at
    the ``starts`` of segments (frame indices, the first 0). Candidate i is position
    ``grid[i % P]`` in pose ``i // P`` (``stay`` (T, poses * P)); the hand starts in pose 0,
    and poses other than 0 are candidates only in segments that hold a ``reach_frames``
    (T,) bool frame.

    A change of pose is made with the fingers lifted, like a shift, in the wrist's
    ``pose_frames``; the slide moves meanwhile, as far as it gets in those frames (a longer
    jump with a turn is not a candidate)."""
    T, Q = stay.shape
    P = len(grid)
    distance = np.abs(grid[:, None] - grid[None, :])  # (from, to), within a pose
    shift = distance > c.shift_m
    reach_shift_m = c.shift_m if c.reach_pose_shift_m is None else c.reach_pose_shift_m
    shift_turned = distance > reach_shift_m
    frames_needed = move_frames(distance, dt, c.slide_acceleration_m_s2)  # (P, P)
    moved = distance > 1e-9
    small = np.where(moved, c.small_move_cost + c.small_move_cost_per_m * distance, 0.0)
    # The slide's reach in the frames a turn takes, in grid steps either way.
    turn_reach_m = 0.25 * c.slide_acceleration_m_s2 * (pose_frames * dt) ** 2
    half = int(np.floor(turn_reach_m / (grid[1] - grid[0]) + 1e-9)) if P > 1 else 0
    # The hand comes from its start position: until the slide can have got to a candidate,
    # being there plays none of the frame's keys. (Q,): the first frame it can be there.
    arrival = move_frames(np.abs(grid - start), dt, c.slide_acceleration_m_s2)
    arrival = np.concatenate([arrival, *[np.maximum(arrival, pose_frames)] * (poses - 1)]) - 1
    every_key = lost[1:] - lost[:-1]  # (T,) weight of all the keys due at each frame
    early = np.arange(T)[:, None] < arrival[None, :]
    stay = np.where(early, every_key[:, None], stay)
    segment_stay = np.add.reduceat(stay, starts, axis=0)  # (S, Q)
    S = len(starts)
    # The poses that are candidates in each segment: all where a reach pose may be wanted,
    # else pose 0 (the others cost infinitely much there).
    reach_segment = np.add.reduceat(reach_frames.astype(int), starts) > 0
    count = np.where(reach_segment, poses, 1)
    value = segment_stay[0].copy()
    value[count[0] * P :] = np.inf
    back = np.zeros((S, Q), dtype=np.int32)
    # The (P, P) costs of moves made with the fingers on the keys, per count of held keys,
    # and each shift's frames as an index into the frames before a segment (made once: the
    # loop below runs once per segment, and its (P, P) passes are the plan's cost).
    on_keys: dict[float, np.ndarray] = {}
    needed = frames_needed.max(initial=1)
    for s in range(1, S):
        t = starts[s]
        # Key-frames a shift into frame t loses: those of the frames it needs before t.
        shift_lost = lost[t] - lost[np.maximum(t - np.arange(needed + 1), 0)] + c.shift_cost
        keep = on_keys.get(held[t])
        if keep is None:
            keep = on_keys[held[t]] = small + moved * held[t] * c.held_move_cost
        move = np.where(shift, shift_lost[frames_needed], keep)
        move_turned = move
        if count[s] > 1 and reach_shift_m != c.shift_m:
            move_turned = np.where(shift_turned, shift_lost[frames_needed], keep)
        turn_cost = lost[t] - lost[max(t - pose_frames, 0)] + c.shift_cost + c.pose_change_cost
        new = np.full(Q, np.inf)
        for b in range(count[s]):
            here = slice(b * P, (b + 1) * P)
            total = value[here, None] + (move if b == 0 else move_turned)  # staying in pose b
            best = np.argmin(total, axis=0)
            new[here] = total[best, np.arange(P)]
            back[s, here] = best + b * P
            for a in range(count[s - 1]):
                if a == b:
                    continue
                # Turning from pose a: the cheapest candidate of a within the slide's reach.
                padded = np.pad(value[a * P : (a + 1) * P], half, constant_values=np.inf)
                windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
                source = np.argmin(windows, axis=1)  # (P,) offset within each window
                turned = windows[np.arange(P), source] + turn_cost
                better = turned < new[here]
                new[here] = np.where(better, turned, new[here])
                origin = a * P + np.arange(P) + source - half
                back[s, here] = np.where(better, origin, back[s, here])
            new[here] += segment_stay[s, here]
        value = new
    choice = np.empty(S, dtype=np.int64)
    choice[-1] = int(np.argmin(value))
    for s in range(S - 1, 0, -1):
        choice[s - 1] = back[s, choice[s]]
    lengths = np.diff(np.r_[starts, T])
    return np.repeat(choice, lengths), float(value[choice[-1]])
