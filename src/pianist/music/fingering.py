"""Automatic hand assignment and fingering: any song becomes playable by the two hands.

Two passes, both dynamic programmes (Viterbi) over the whole piece, deterministic:

1. **Hands** (:func:`assign_hands`). Notes that already name a hand (a finger label, a PIG
   channel, a MIDI track hint) keep it. The others are split by pitch, slice by slice (notes
   struck together form a slice): the state is how many of the slice's free notes, lowest
   first, go to the left hand. Costs: each hand's reach over its new and still-held notes,
   more than five notes in a hand, hands crossing, each hand's jump from where it last
   played (continuity), and a weak register prior.
2. **Fingers** (:func:`assign_fingering`), per hand. The state of a slice is an assignment of
   fingers to its notes in pitch order (thumb lowest on the right hand, highest on the left),
   restricted to the fingers a file already gives. Costs: stretch between fingers against
   the real distance between the keys of *this* piano (white keys 23.5 mm apart, black keys
   over the gaps), with separate limits for notes played together (the robot's fingers are
   ~19 mm wide) and one after another; thumb crossings (cheap) and other crossings (dear);
   the same finger on two different keys in a row; thumb and little finger on black keys;
   fingers still holding a key; and the hand's movement.

Distances are in white-key pitches (``WHITE_KEY_PITCH_M``, 23.5 mm). The keyboard geometry is
restated here because :mod:`pianist.music` imports nothing else of the package; a test checks
it against :mod:`pianist.sim.constants`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from typing import Literal

from pianist.music.errors import MusicError
from pianist.music.notes import LEFT, RIGHT, Note, Song
from pianist.music.pitch import LOWEST_PITCH, NUM_KEYS

# --- Keyboard geometry (same rule as pianist.sim.constants) ----------------------------------

#: Centre-to-centre spacing of white keys (22.5 mm key + 1 mm gap), metres.
WHITE_KEY_PITCH_M = 0.0235
# Counting from A (key 0), the black keys of an octave are A#, C#, D#, F#, G#.
_BLACK_OFFSETS = frozenset({1, 4, 6, 9, 11})


def _key_geometry() -> tuple[tuple[float, ...], tuple[bool, ...]]:
    positions, black = [], []
    white_rank = -1
    for key in range(NUM_KEYS):
        is_black = key % 12 in _BLACK_OFFSETS
        if not is_black:
            white_rank += 1
        # A black key sits over the gap above its white neighbour below.
        positions.append(white_rank + (0.5 if is_black else 0.0))
        black.append(is_black)
    return tuple(positions), tuple(black)


# Positions in white-key pitches, which is what the cost tables are written in. They are
# multiples of 0.5, exact in binary, so distances compare exactly against the limits.
_KEY_W, KEY_IS_BLACK = _key_geometry()
#: Position of each key's centre along the keyboard (m) relative to A0's, shape (88,).
KEY_Y_M = tuple(w * WHITE_KEY_PITCH_M for w in _KEY_W)


def key_position_w(pitch: int) -> float:
    """Position of ``pitch``'s key along the keyboard in white-key pitches (A0 = 0)."""
    return _KEY_W[pitch - LOWEST_PITCH]


# --- Cost tables -------------------------------------------------------------------------------

# Limits per finger pair (i < j, 0 = thumb .. 4 = little) on the signed distance
# d = position(j) - position(i) in white-key pitches, in the hand's own direction (towards the
# little finger). Six numbers: practical minimum, comfortable minimum, relaxed minimum,
# relaxed maximum, comfortable maximum, practical maximum. Shaped after Parncutt et al.'s
# (1997) span table, converted to this keyboard's distances, then narrowed for the robot.
Limits = tuple[float, float, float, float, float, float]

# One note after the other: the thumb may pass under the fingers (negative d).
_SEQ_LIMITS: dict[tuple[int, int], Limits] = {
    (0, 1): (-3.0, -1.5, 0.5, 3.0, 4.5, 5.5),
    (0, 2): (-2.5, -1.0, 1.0, 4.0, 5.5, 6.5),
    (0, 3): (-2.0, -0.5, 2.0, 5.0, 6.0, 7.0),
    (0, 4): (-0.5, 0.5, 3.0, 6.0, 7.0, 7.5),
    (1, 2): (0.5, 0.5, 1.0, 1.5, 2.0, 3.0),
    (1, 3): (0.5, 1.0, 1.5, 2.5, 3.0, 4.2),
    (1, 4): (1.0, 1.5, 2.5, 3.5, 4.5, 5.8),
    (2, 3): (0.5, 0.5, 1.0, 1.3, 1.8, 2.5),
    (2, 4): (0.5, 1.0, 1.5, 2.5, 3.0, 4.2),
    (3, 4): (0.5, 0.5, 1.0, 1.5, 2.0, 3.0),
}
# Notes sounding together: neighbouring robot fingers cannot come closer than their ~19 mm
# width (0.8 white keys), and the whole hand reaches a little over an octave (7 white keys)
# from thumb to little finger.
_CHORD_LIMITS: dict[tuple[int, int], Limits] = {
    (0, 1): (-1.0, 0.5, 1.0, 3.0, 4.5, 5.5),
    (0, 2): (0.5, 1.0, 1.5, 4.0, 5.5, 6.5),
    (0, 3): (1.0, 1.5, 2.5, 5.0, 6.0, 7.0),
    (0, 4): (1.5, 2.5, 3.5, 6.0, 7.0, 7.6),
    (1, 2): (0.8, 0.9, 1.0, 1.5, 2.0, 3.0),
    (1, 3): (1.6, 1.8, 2.0, 3.0, 3.5, 4.2),
    (1, 4): (2.4, 2.6, 3.0, 4.0, 5.0, 5.8),
    (2, 3): (0.8, 0.9, 1.0, 1.3, 1.8, 2.5),
    (2, 4): (1.6, 1.8, 2.0, 2.8, 3.5, 4.2),
    (3, 4): (0.8, 0.9, 1.0, 1.5, 2.0, 3.0),
}
W_RELAXED = 1.0  # per white key outside the relaxed range
W_COMFORT = 2.0  # per white key further, outside the comfortable range
W_PRACTICAL = 10.0  # once, beyond the practical limit (plus 2 * W_COMFORT per white key)
W_THUMB_CROSS = 1.0  # the thumb passes under a finger or a finger over the thumb
W_THUMB_CROSS_BLACK = 1.0  # ... with the thumb on a black key and the other on a white one
W_OTHER_CROSS = 8.0  # two fingers other than the thumb cross
W_SAME_FINGER = 3.0  # the same finger on two different keys one after the other
# The Shadow thumb cannot press a black key at all (no sampled posture reaches one; see
# pianist.control.planner): a thumb on a black key costs more than an overstretch, less than a
# finger that is still busy. (1.0, a human cost, left 261 of the open library's 2827 notes on a
# black key under the thumb; the planner then missed them.)
W_THUMB_BLACK = 20.0
W_LITTLE_BLACK = 0.5
W_RING = 0.3  # the ring finger is the weakest and least independent: use it when it helps
W_REPEAT_CHANGE = 0.5  # a repeated key struck by another finger (the hand must shift)
W_FINGER_BUSY = 50.0  # a finger still holding a key is asked to play another one
W_HAND_MOVE = 0.2  # per white key the (implied) hand position moves
#: Where each finger rests relative to the middle finger, white keys (thumb .. little).
REST_OFFSET_W = (-3.0, -1.0, 0.0, 1.0, 2.0)

# Hand split.
#: Widest comfortable reach of one hand over keys sounding together, white keys (an octave).
HAND_REACH_W = 7.0
#: Widest reach at all: an octave and a white key (~19 cm on this keyboard).
HAND_MAX_REACH_W = 8.0
W_SPLIT_REACH = 1.0  # per white key beyond 5 white keys
W_SPLIT_OVERREACH = 15.0  # per white key beyond HAND_REACH_W
W_SPLIT_CROWD = 20.0  # per note beyond five in one hand
W_SPLIT_CROSS = 6.0  # once, plus per white key of overlap, when the hands cross
W_SPLIT_JUMP = 0.4  # per white key a hand jumps from where it played last
W_SPLIT_REGISTER = 0.05  # per white key a hand plays on the other side of middle C
W_SPLIT_WAKE = 0.5  # a hand starts playing after resting 1.5 s or more (less if shorter)
# Where the hands wait before their first note: C3 and G4 (melodies sit mostly in the treble).
_HOME_W = {LEFT: key_position_w(48), RIGHT: key_position_w(67)}
_MIDDLE_C_W = key_position_w(60)

#: Notes whose onsets are this close (s) are struck together (one slice).
CHORD_TOLERANCE_S = 0.03
_EPS_S = 1e-6
FingeringMode = Literal["auto", "file", "robot", "none"]


def _span_cost(limits: Limits, d: float) -> float:
    """Cost of distance ``d`` (white keys) against the six limits of a finger pair."""
    min_prac, min_comf, min_rel, max_rel, max_comf, max_prac = limits
    if d < min_rel:
        cost = (min_rel - max(d, min_comf)) * W_RELAXED
        if d < min_comf:
            cost += (min_comf - d) * W_COMFORT
        if d < min_prac:
            cost += W_PRACTICAL + (min_prac - d) * 2 * W_COMFORT
        return cost
    if d > max_rel:
        cost = (min(d, max_comf) - max_rel) * W_RELAXED
        if d > max_comf:
            cost += (d - max_comf) * W_COMFORT
        if d > max_prac:
            cost += W_PRACTICAL + (d - max_prac) * 2 * W_COMFORT
        return cost
    return 0.0


def _pair_cost(
    table: dict[tuple[int, int], Limits], fa: int, ua: float, fb: int, ub: float
) -> float:
    """Stretch of fingers ``fa`` at ``ua`` and ``fb`` at ``ub`` (hand coordinates, fa != fb)."""
    if fa < fb:
        return _span_cost(table[(fa, fb)], ub - ua)
    return _span_cost(table[(fb, fa)], ua - ub)


# --- Slices --------------------------------------------------------------------------------------


def _slices(indices: Sequence[int], notes: Sequence[Note]) -> list[list[int]]:
    """Group note indices (sorted by onset) into slices struck together; a pitch at most once."""
    groups: list[list[int]] = []
    start = -math.inf
    pitches: set[int] = set()
    for i in indices:
        note = notes[i]
        if groups and note.onset_s - start <= CHORD_TOLERANCE_S and note.pitch not in pitches:
            groups[-1].append(i)
            pitches.add(note.pitch)
        else:
            groups.append([i])
            start = note.onset_s
            pitches = {note.pitch}
    return groups


# --- Hand assignment -----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _HandContext:
    """What the best path into a split state leaves behind for one hand."""

    position: float  # white keys, mean of its last slice
    last_onset_s: float
    held: tuple[tuple[float, float], ...]  # (position w, offset s) of keys still down


def _reach_cost(positions: Sequence[float]) -> float:
    if len(positions) < 2:
        return 0.0
    span = max(positions) - min(positions)
    cost = max(0.0, span - 5.0) * W_SPLIT_REACH
    cost += max(0.0, span - HAND_REACH_W) * W_SPLIT_OVERREACH
    cost += max(0, len(positions) - 5) * W_SPLIT_CROWD
    return cost


def _split_slice_cost(
    onset: float,
    new: dict[str, list[float]],
    contexts: dict[str, _HandContext],
) -> float:
    cost = 0.0
    together: dict[str, list[float]] = {}
    for hand in (LEFT, RIGHT):
        ctx = contexts[hand]
        held = [w for w, end in ctx.held if end > onset + _EPS_S]
        together[hand] = new[hand] + held
        cost += _reach_cost(together[hand])
        if new[hand]:
            centre = sum(new[hand]) / len(new[hand])
            rest_s = max(0.0, onset - ctx.last_onset_s)
            cost += W_SPLIT_JUMP * abs(centre - ctx.position) / (1.0 + rest_s)
            if not held:
                cost += W_SPLIT_WAKE * min(1.0, max(0.0, rest_s - 0.5))
            if hand == RIGHT:
                cost += W_SPLIT_REGISTER * sum(max(0.0, _MIDDLE_C_W - w) for w in new[hand])
            else:
                # Half a white key lower than the right hand's bound: middle C goes right.
                cost += W_SPLIT_REGISTER * sum(max(0.0, w - _MIDDLE_C_W + 0.5) for w in new[hand])
    if together[LEFT] and together[RIGHT]:
        overlap = max(together[LEFT]) - min(together[RIGHT])
        if overlap > 0:
            cost += W_SPLIT_CROSS * (1.0 + overlap)
    return cost


def _advance(ctx: _HandContext, onset: float, new: list[tuple[float, float]]) -> _HandContext:
    """Context after the hand plays ``new`` (position, offset) notes at ``onset``."""
    held = tuple(h for h in ctx.held if h[1] > onset + _EPS_S)
    if not new:
        return dataclasses.replace(ctx, held=held)
    centre = sum(w for w, _ in new) / len(new)
    return _HandContext(centre, onset, held + tuple(new))


def assign_hands(song: Song, hints: Sequence[str | None] | None = None) -> Song:
    """Give every note a hand ("left"/"right"), keeping the hands the song already has.

    Args:
        song: any song; notes with a ``hand`` (or finger) keep it.
        hints: optional, one entry per note of ``song.notes`` (same order): a hand for notes
            that have none (e.g. from MIDI tracks, see :func:`pianist.music.parts`), or None.
    Returns:
        A copy of ``song`` in which every note has a hand; fingers are unchanged.

    Raises:
        MusicError: ``hints`` has the wrong length or an entry other than left/right/None.
    """
    notes = song.notes
    fixed = _hand_labels(song, hints)
    if all(h is not None for h in fixed):
        return _with_hands(song, fixed)  # type: ignore[arg-type]

    slices = _slices(range(len(notes)), notes)
    start = {
        # A hand that has not played yet counts as having rested since the song began.
        hand: _HandContext(_HOME_W[hand], 0.0, ())
        for hand in (LEFT, RIGHT)
    }
    # Viterbi with path-carried context: each state keeps the hand contexts of its best path.
    beam: list[tuple[float, dict[str, _HandContext]]] = [(0.0, start)]
    history: list[list[tuple[int, int]]] = []  # per slice: (best previous state, split k)
    for group in slices:
        onset = notes[group[0]].onset_s
        free = sorted((i for i in group if fixed[i] is None), key=lambda i: notes[i].pitch)
        base = {LEFT: [], RIGHT: []}  # type: dict[str, list[int]]
        for i in group:
            if fixed[i] is not None:
                base[fixed[i]].append(i)  # type: ignore[index]
        options = []
        back = []
        for k in range(len(free) + 1):
            members = {LEFT: base[LEFT] + free[:k], RIGHT: base[RIGHT] + free[k:]}
            new_w = {h: [key_position_w(notes[i].pitch) for i in members[h]] for h in members}
            best: tuple[float, int] | None = None
            for p, (total, contexts) in enumerate(beam):
                cost = total + _split_slice_cost(onset, new_w, contexts)
                if best is None or cost < best[0] - 1e-12:
                    best = (cost, p)
            assert best is not None
            cost, p = best
            contexts = beam[p][1]
            advanced = {
                h: _advance(
                    contexts[h],
                    onset,
                    [(key_position_w(notes[i].pitch), notes[i].offset_s) for i in members[h]],
                )
                for h in (LEFT, RIGHT)
            }
            options.append((cost, advanced))
            back.append((p, k))
        beam = options
        history.append(back)

    # Backtrack the cheapest path (ties: the lowest state index, so the result is stable).
    state = min(range(len(beam)), key=lambda s: (beam[s][0], s))
    hands = list(fixed)
    for group, back in zip(reversed(slices), reversed(history), strict=True):
        previous, k = back[state]
        free = sorted((i for i in group if fixed[i] is None), key=lambda i: notes[i].pitch)
        for rank, i in enumerate(free):
            hands[i] = LEFT if rank < k else RIGHT
        state = previous
    return _with_hands(song, hands)  # type: ignore[arg-type]


def _hand_labels(song: Song, hints: Sequence[str | None] | None) -> list[str | None]:
    labels: list[str | None] = [n.hand for n in song.notes]
    if hints is None:
        return labels
    if len(hints) != len(song.notes):
        raise MusicError(f"song {song.name!r}: {len(hints)} hand hints for {len(song.notes)} notes")
    for i, hint in enumerate(hints):
        if hint not in (None, LEFT, RIGHT):
            raise MusicError(f"hand hint {hint!r} is not 'left', 'right' or None")
        if labels[i] is None:
            labels[i] = hint
    return labels


def _with_hands(song: Song, hands: Sequence[str]) -> Song:
    notes = tuple(
        n if n.hand == h else dataclasses.replace(n, hand=h)
        for n, h in zip(song.notes, hands, strict=True)
    )
    return dataclasses.replace(song, notes=notes)


# --- Finger assignment ---------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Slice:
    indices: tuple[int, ...]  # note indices, in hand order (thumb side first)
    u: tuple[float, ...]  # positions in the hand's coordinate (white keys)
    black: tuple[bool, ...]
    offsets: tuple[float, ...]
    onset_s: float
    states: tuple[tuple[int, ...], ...]  # finger (0-4) per note, candidates
    static: tuple[float, ...]  # cost of each state on its own
    positions: tuple[float, ...]  # implied hand position of each state (white keys)


def _candidate_states(n: int, given: Sequence[int | None]) -> list[tuple[int, ...]]:
    """Finger tuples for ``n`` notes in hand order that agree with the ``given`` fingers."""
    if n <= 5:
        states = [
            c
            for c in itertools.combinations(range(5), n)
            if all(g is None or g == f for g, f in zip(given, c, strict=True))
        ]
        if states:
            return states
        # The file's fingers are not in hand order (a crossed chord): keep them, and try every
        # order of the free fingers for the other notes.
        used = {g for g in given if g is not None}
        free_fingers = [f for f in range(5) if f not in used]
        gaps = [i for i, g in enumerate(given) if g is None]
        found: list[tuple[int, ...]] = []
        for perm in itertools.permutations(free_fingers, len(gaps)):
            fill = dict(zip(gaps, perm, strict=True))
            found.append(tuple(fill[i] if g is None else g for i, g in enumerate(given)))
        if found:
            return found
        # The same finger twice in a file's chord: nothing to choose.
        return [tuple(g if g is not None else 0 for g in given)]
    # More than five notes in one hand cannot be played as written: spread the fingers
    # (neighbouring notes share a finger) so that every note still gets one.
    return [
        tuple(g if g is not None else min(4, round(i * 4 / (n - 1))) for i, g in enumerate(given))
    ]


def _static_cost(state: tuple[int, ...], u: Sequence[float], black: Sequence[bool]) -> float:
    cost = 0.0
    for f, is_black in zip(state, black, strict=True):
        if f == 3:
            cost += W_RING
        if is_black:
            if f == 0:
                cost += W_THUMB_BLACK
            elif f == 4:
                cost += W_LITTLE_BLACK
    for a in range(len(state)):
        for b in range(a + 1, len(state)):
            if state[a] == state[b]:
                cost += W_FINGER_BUSY
            else:
                cost += _pair_cost(_CHORD_LIMITS, state[a], u[a], state[b], u[b])
    return cost


def _hand_position(state: Sequence[int], u: Sequence[float]) -> float:
    return sum(x - REST_OFFSET_W[f] for f, x in zip(state, u, strict=True)) / len(state)


def _transition_matrix(prev: _Slice, cur: _Slice, cache: dict) -> list[list[float]]:
    """Transition costs (states of ``prev`` x states of ``cur``), memoised.

    The costs depend only on the fingers, the distances between the keys, their colours and
    the time between the slices, so repeated figures (most of most music) reuse a matrix.
    """
    base = prev.u[0]
    gap = round(cur.onset_s - prev.onset_s, 3)
    key = (
        prev.states,
        tuple(x - base for x in prev.u),
        prev.black,
        cur.states,
        tuple(x - base for x in cur.u),
        cur.black,
        gap,
    )
    matrix = cache.get(key)
    if matrix is None:
        matrix = [
            [
                _transition_cost(prev, sa, cur, sb, gap, pa, pb)
                for sb, pb in zip(cur.states, cur.positions, strict=True)
            ]
            for sa, pa in zip(prev.states, prev.positions, strict=True)
        ]
        cache[key] = matrix
    return matrix


def _transition_cost(
    prev: _Slice,
    sa: tuple[int, ...],
    cur: _Slice,
    sb: tuple[int, ...],
    gap: float,
    position_a: float,
    position_b: float,
) -> float:
    """Cost of playing ``cur`` with ``sb`` right after ``prev`` with ``sa``, ``gap`` s later."""
    cost = 0.0
    pairs = 0.0
    for fa, ua, ba in zip(sa, prev.u, prev.black, strict=True):
        for fb, ub, bb in zip(sb, cur.u, cur.black, strict=True):
            if fa == fb:
                if ua != ub:
                    # The finger must lift, travel and land: worse the less time it has
                    # (full cost up to 0.2 s, a fifth of it from 1 s on).
                    urgency = min(1.0, max(0.2, 1.2 - gap))
                    pairs += W_SAME_FINGER * (1.0 + abs(ub - ua) / 2) * urgency
                continue
            if ua == ub:
                pairs += W_REPEAT_CHANGE
                continue
            pairs += _pair_cost(_SEQ_LIMITS, fa, ua, fb, ub)
            low, high = (fa, fb) if fa < fb else (fb, fa)
            u_low, u_high = (ua, ub) if fa < fb else (ub, ua)
            if u_high < u_low:  # the lower-numbered finger plays above the higher one
                if low == 0:
                    cost += W_THUMB_CROSS
                    thumb_black = ba if fa == 0 else bb
                    other_black = bb if fa == 0 else ba
                    if thumb_black and not other_black:
                        cost += W_THUMB_CROSS_BLACK
                else:
                    cost += W_OTHER_CROSS
    # Chords: the pairwise rules are averaged so that a chord change costs like one step.
    cost += pairs / max(len(sa), len(sb))
    cost += W_HAND_MOVE * abs(position_b - position_a)
    return cost


def _held_costs(held: Sequence[tuple[int, float, float]], cur: _Slice, cache: dict) -> list[float]:
    """:func:`_held_cost` of every state of ``cur``, memoised on the relative geometry."""
    base = cur.u[0]
    key = (
        "held",
        tuple((f, u - base) for f, u, _ in held),
        cur.states,
        tuple(u - base for u in cur.u),
    )
    costs = cache.get(key)
    if costs is None:
        costs = [_held_cost(held, cur, sb) for sb in cur.states]
        cache[key] = costs
    return costs


def _held_cost(held: Sequence[tuple[int, float, float]], cur: _Slice, sb: tuple[int, ...]) -> float:
    """Keys still held (finger, position, offset) when ``cur`` is struck with ``sb``."""
    cost = 0.0
    for f_h, u_h, _ in held:
        for fb, ub in zip(sb, cur.u, strict=True):
            if fb == f_h:
                cost += W_FINGER_BUSY
            else:
                cost += _pair_cost(_CHORD_LIMITS, f_h, u_h, fb, ub)
    return cost


def _finger_hand(
    notes: Sequence[Note], indices: Sequence[int], hand: str, keep_existing: bool
) -> dict[int, int]:
    """Fingers (0-4 within the hand) for the notes ``indices`` of one hand."""
    sign = 1.0 if hand == RIGHT else -1.0
    offset = 0 if hand == RIGHT else 5
    slices: list[_Slice] = []
    for group in _slices(indices, notes):
        ordered = sorted(group, key=lambda i: sign * key_position_w(notes[i].pitch))
        u = tuple(sign * key_position_w(notes[i].pitch) for i in ordered)
        black = tuple(KEY_IS_BLACK[notes[i].pitch - LOWEST_PITCH] for i in ordered)
        fingers = [notes[i].finger for i in ordered]
        given = [f - offset if keep_existing and f is not None else None for f in fingers]
        states = tuple(_candidate_states(len(ordered), given))
        slices.append(
            _Slice(
                indices=tuple(ordered),
                u=u,
                black=black,
                offsets=tuple(notes[i].offset_s for i in ordered),
                onset_s=notes[ordered[0]].onset_s,
                states=states,
                static=tuple(_static_cost(s, u, black) for s in states),
                positions=tuple(_hand_position(s, u) for s in states),
            )
        )
    if not slices:
        return {}

    # Viterbi. Each state also carries the keys its best path still holds down (an
    # approximation that keeps the state small: long notes constrain later slices).
    first = slices[0]
    totals = list(first.static)
    helds: list[tuple[tuple[int, float, float], ...]] = [
        tuple(zip(s, first.u, first.offsets, strict=True)) for s in first.states
    ]
    backs: list[list[int]] = []
    cache: dict = {}
    for prev, cur in itertools.pairwise(slices):
        matrix = _transition_matrix(prev, cur, cache)
        onset = cur.onset_s + _EPS_S
        still = [tuple(h for h in held if h[2] > onset) for held in helds]
        new_totals, new_helds, back = [], [], []
        held_costs = [_held_costs(held, cur, cache) if held else None for held in still]
        for b, (sb, static) in enumerate(zip(cur.states, cur.static, strict=True)):
            best_cost, best_p = math.inf, 0
            for p in range(len(prev.states)):
                cost = totals[p] + matrix[p][b]
                extra = held_costs[p]
                if extra is not None:
                    cost += extra[b]
                if cost < best_cost - 1e-12:
                    best_cost, best_p = cost, p
            new_totals.append(best_cost + static)
            new_helds.append(still[best_p] + tuple(zip(sb, cur.u, cur.offsets, strict=True)))
            back.append(best_p)
        totals, helds = new_totals, new_helds
        backs.append(back)

    state = min(range(len(totals)), key=lambda s: (totals[s], s))
    result: dict[int, int] = {}
    for position in range(len(slices) - 1, -1, -1):
        chosen = slices[position].states[state]
        for i, f in zip(slices[position].indices, chosen, strict=True):
            result[i] = f + offset
        if position:
            state = backs[position - 1][state]
    return result


def assign_fingering(
    song: Song,
    *,
    keep_existing: bool = True,
    hands: Sequence[str | None] | None = None,
) -> Song:
    """Give every note of ``song`` a hand and a finger (0-4 right, 5-9 left).

    Args:
        song: any song; an empty song is returned unchanged.
        keep_existing: keep the fingers the song already has (human fingering) and estimate
            only the missing ones; False re-estimates every finger (hands are still kept).
        hands: optional per-note hand hints for notes without a hand (see
            :func:`assign_hands`).
    Returns:
        A fully fingered copy of ``song`` (same notes, times and sustain).

    The result is deterministic. Speed: see ``benchmarks/bench_fingering.py``.
    """
    if not song.notes:
        return song
    if not keep_existing:
        song = strip_fingering(song, keep_hands=True)
    handed = assign_hands(song, hands)
    notes = handed.notes
    fingers: dict[int, int] = {}
    for hand in (RIGHT, LEFT):
        indices = [i for i, n in enumerate(notes) if n.hand == hand]
        fingers.update(_finger_hand(notes, indices, hand, keep_existing=True))
    new_notes = tuple(
        n if n.finger == fingers[i] else dataclasses.replace(n, finger=fingers[i], hand=None)
        for i, n in enumerate(notes)
    )
    return dataclasses.replace(handed, notes=new_notes)


def strip_fingering(song: Song, *, keep_hands: bool = False) -> Song:
    """A copy of ``song`` without finger labels (and without hands unless ``keep_hands``)."""
    notes = tuple(
        dataclasses.replace(n, finger=None, hand=n.hand if keep_hands else None) for n in song.notes
    )
    return dataclasses.replace(song, notes=notes)


def ensure_fingering(song: Song, mode: FingeringMode = "auto") -> Song:
    """Apply a fingering policy to a loaded song (what ``pianist play --fingering`` selects).

    Args:
        song: a loaded song.
        mode: "auto" fingers the notes that have no finger (a file's own fingers are kept);
            "file" requires the file to finger every note; "robot" re-fingers every note for
            this robot hand (its thumb cannot press a black key, its span is short of an
            octave), keeping the song's hands; "none" returns the song as is (for the
            environment's ``fingering_reward="optimal"``, which needs no labels).

    Raises:
        MusicError: ``mode="file"`` and some notes have no finger; or an unknown mode.
    """
    if mode == "none":
        return song
    if mode == "file":
        if not song.has_full_fingering:
            missing = sum(n.finger is None for n in song.notes)
            raise MusicError(
                f"song {song.name or '(unnamed)'}: {missing} of {len(song.notes)} notes have "
                "no finger; use fingering 'auto' to estimate them"
            )
        return song
    if mode == "auto":
        return song if song.has_full_fingering else assign_fingering(song)
    if mode == "robot":
        return assign_fingering(song, keep_existing=False)
    raise MusicError(f"unknown fingering mode {mode!r}: use 'auto', 'file', 'robot' or 'none'")
