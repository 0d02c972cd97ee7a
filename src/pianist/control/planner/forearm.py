"""Where each forearm is along the keyboard at every frame, and how its slide gets there.

Planned at reset, functions of the hand (:class:`~pianist.control.planner.hand.Hand`), its
poses (:class:`~pianist.control.planner.postures.HandPose`) and arrays (T frames; positions
are the forearm ``tx`` slide's, in m):

- :func:`frame_plan`, frame by frame with the song's fingering, or :func:`piece_plan`, over
  the whole piece (:func:`pianist.control.planner.hand_plan.plan_hand`; :func:`clearance`
  serves the sharing of keys between the hands): a
  :class:`~pianist.control.planner.hand_plan.HandPlan`, the position wanted at each frame
  (T,), ``busy`` (T,) bool (the hand has notes), ``skip`` (T, 88) bool (its keys it leaves
  out), ``fingers`` (T, 88) int (its finger 0-4 per key, or -1) and ``pose`` (T,) int;
- :func:`keep_forearms_apart`: the two hands' positions shifted so the forearms never touch;
- :func:`reach_model`: what the hand reaches
  (:class:`pianist.control.planner.hand_split.HandReach`);
- :func:`playable_mask`: the key-frames a plan leaves playable (to choose a plan);
- :func:`plan_commands`: the plan as the hand plays it
  (:class:`~pianist.control.planner.plans.HandPlanArrays`): the reference path ``tx_path``
  (T + 2, 2) (m, m/s at the end of each step), the shifts (``free`` (T,) bool: the fingers
  let go; ``shift_to`` (T,) int: the frame moved to; each shift timed to hold the keys
  before it when that loses less, ``_shift_delays``, and ``tx_held`` (T,) the plan so
  followed), and the pose commanded at each step (``pose_held``).

Each step :func:`command_forearm` writes the slide's command (m) into ``ctrl``, along the
path in closed loop through the slide's servo model (:class:`SlideServo`), and
:func:`command_height` the height slide's (when present), held at the playing height.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg

from pianist.control.planner.config import FINGERS_PER_HAND, PlannerConfig, PlannerState
from pianist.control.planner.hand import Hand
from pianist.control.planner.hand_plan import HandPlan, HandPlanCosts, move_frames, plan_hand
from pianist.control.planner.hand_split import HandReach
from pianist.control.planner.plans import HandPlanArrays
from pianist.control.planner.postures import HandPose
from pianist.sim import constants as C


class SlideServo:
    """A position-servo slide as the linear system ``M q'' = kp (u - q) - c q'``, discretised
    exactly over one control step (the command is held constant through the step)."""

    def __init__(self, m, actuator: int, dof: int, dt: float) -> None:
        kp = m.actuator_gainprm[actuator, 0]
        c = -m.actuator_biasprm[actuator, 2] + m.dof_damping[dof]
        mass = m.dof_M0[dof]
        # Augmented matrix exponential: the transition (2, 2) and the command's effect (2,).
        a = np.zeros((3, 3))
        a[0, 1] = 1.0
        a[1] = [-kp / mass, -c / mass, kp / mass]
        e = scipy.linalg.expm(a * dt)
        phi, gamma = e[:2, :2], e[:2, 2]
        self.phi2 = phi @ phi
        # Two steps' commands (u0, u1) -> state after them: phi gamma u0 + gamma u1.
        self.inverse = np.linalg.inv(np.stack([phi @ gamma, gamma], axis=1))
        self.low, self.high = m.actuator_ctrlrange[actuator]

    @classmethod
    def of(cls, m, hand: Hand, dt: float) -> SlideServo:
        """The model of ``hand``'s ``tx`` slide for control steps of ``dt`` s."""
        return cls(m, hand.tx_actuator, hand.tx_dof, dt)

    def command(self, state: np.ndarray, target: np.ndarray) -> float:
        """This step's command, shape (), to reach ``target`` (position m, velocity m/s) at the
        end of the next step from ``state``: the first of the two commands that get there
        exactly (re-solved every step from the measured state, so it corrects for contacts)."""
        u0, _ = self.inverse @ (target - self.phi2 @ state)
        return float(np.clip(u0, self.low, self.high))


def _note_onsets(keys: np.ndarray) -> np.ndarray:
    """(T, 88) int: the first frame of the note covering each due key (-1 where none)."""
    onset = np.full(keys.shape, -1)
    for t in range(keys.shape[0]):
        started = keys[t] & ~(keys[t - 1] if t else np.zeros_like(keys[t]))
        onset[t] = np.where(started, t, np.where(keys[t], onset[t - 1] if t else -1, -1))
    return onset


def clearance(
    hand: Hand, plan: HandPlan, other: Hand, cfg: PlannerConfig
) -> Callable[[np.ndarray], np.ndarray]:
    """Candidate slide positions of ``other`` (P,) -> (T, P) cost of coming closer than
    ``forearm_separation_m`` to ``hand``'s planned forearm (``plan``: they would collide)
    while ``hand`` plays (when it does not, it makes way: :func:`keep_forearms_apart`)."""
    sign = 1.0 if hand.side == "right" else -1.0  # this forearm's side of the other

    def cost(grid: np.ndarray) -> np.ndarray:
        gap = sign * ((plan.position[:, None] + hand.root_y) - (grid[None, :] + other.root_y))
        close = (gap < cfg.forearm.forearm_separation_m) & plan.busy[:, None]
        return np.where(close, cfg.plan.clearance_cost, 0.0)

    return cost


def piece_plan(
    hand: Hand,
    poses: Sequence[HandPose],
    goal,
    key_point: np.ndarray,
    dt: float,
    costs: HandPlanCosts,
    refinger: bool,
    take: np.ndarray | None = None,
    extra_cost: Callable[[np.ndarray], np.ndarray] | None = None,
    drop: np.ndarray | None = None,
    other_kept: np.ndarray | None = None,
    pose_change_s: float = 0.15,
) -> HandPlan:
    """The forearm slide position and the hand's pose at every frame from the whole-piece
    plan (:func:`pianist.control.planner.hand_plan.plan_hand`, over every pose of ``poses``),
    with its ``busy``, ``skip`` and ``fingers`` (T, 88), this hand's finger 0-4 of each due
    key (-1: none).

    ``take``: (T, 88) further keys (the other hand's) to play if the plan can (``refinger``
    only); ``drop``: (T, 88) keys of this hand the other plays (left out here);
    ``extra_cost``, ``other_kept``: see :func:`plan_hand`.
    """
    local = goal.fingers - hand.finger_offset
    local = np.where((local >= 0) & (local < FINGERS_PER_HAND), local, -1)
    if take is not None:
        local = np.where(take & (local < 0), 0, local)  # any finger: the plan chooses
    if drop is not None:
        local = np.where(drop, -1, local)
    return plan_hand(
        goal.keys,
        local,
        key_point[:, 1],
        C.BLACK_KEY_MASK,
        *plan_reaches(poses),
        np.stack([pose.tip_offset_y for pose in poses]),
        hand.slide_range,
        start=0.0,
        dt=dt,
        outer="top" if hand.side == "right" else "bottom",
        costs=costs,
        refinger=refinger,
        extra_cost=extra_cost,
        other_kept=other_kept,
        pose_frames=max(1, round(pose_change_s / dt)),
    )


def frame_plan(
    hand: Hand,
    pose: HandPose,
    goal,
    key_point: np.ndarray,
    lazy_m: float = 0.0,
    skip_out_of_reach: bool = False,
) -> HandPlan:
    """The forearm slide position wanted at every frame, shape (T,), in ``pose`` throughout
    (the home pose), with the song's fingering.

    The position that puts each assigned finger at its resting place over its key (the
    mean over the hand's due keys), moved as little as needed to bring every one of those
    keys within its finger's reach: a wide chord otherwise leaves the thumb pressing at
    the edge of its reach, where it slips off the key. With ``lazy_m`` > 0 the hand
    rather stays where it was while every finger still reaches from there (and it is at
    most ``lazy_m`` from that position). With ``skip_out_of_reach``, the keys of a chord
    no position covers are left out, as ``skip`` (T, 88) records (see ``PlannerConfig``).
    """
    T = goal.num_frames
    wanted = np.full(T, np.nan)
    # Keys of this hand it leaves out: a chord wider than the hand (an octave, say).
    skip = np.zeros((T, goal.keys.shape[1]), dtype=bool)
    onset = _note_onsets(goal.keys)
    previous = np.nan
    for t in range(T):
        keys = np.flatnonzero(goal.keys[t])
        fingers = goal.fingers[t, keys]
        mine = (fingers >= hand.finger_offset) & (fingers < hand.finger_offset + 5)
        if not mine.any():
            continue
        keys, local = keys[mine], fingers[mine] - hand.finger_offset
        y = key_point[keys, 1]
        reach = pose.reach[local, C.BLACK_KEY_MASK[keys].astype(int)]  # (n, 2)
        low, high = np.max(y - reach[:, 1]), np.min(y - reach[:, 0])
        centre = np.mean(y - pose.tip_offset_y[local])
        full = pose.full_reach[local, C.BLACK_KEY_MASK[keys].astype(int)]
        first, last = y - full[:, 1], y - full[:, 0]  # slide range each key allows
        if skip_out_of_reach and np.max(first) > np.min(last) and len(set(onset[t, keys])) == 1:
            # A chord struck together that no hand position covers: play the most of its
            # keys that one position reaches, the outer voice (the bass in the left hand,
            # the top in the right) among them, rather than none from halfway.
            outer = np.argmax(y) if hand.side == "right" else np.argmin(y)
            best = max(
                np.concatenate([first, last]),
                key=lambda p: (
                    np.sum((first <= p + 1e-9) & (p - 1e-9 <= last)),
                    first[outer] <= p <= last[outer],
                ),
            )
            kept = (first <= best + 1e-9) & (best - 1e-9 <= last)
            skip[t, keys[~kept]] = True
            keys, local, y, reach = keys[kept], local[kept], y[kept], reach[kept]
            low, high = np.max(y - reach[:, 1]), np.min(y - reach[:, 0])
            centre = np.mean(y - pose.tip_offset_y[local])
        # Out of reach together: halfway between what the two worst-off fingers need.
        wanted[t] = np.clip(centre, low, high) if low <= high else (low + high) / 2
        if lazy_m > 0 and low <= high and np.isfinite(previous):
            # Stay where the fingers still reach: every move costs frames.
            if max(low, centre - lazy_m) <= previous <= min(high, centre + lazy_m):
                wanted[t] = previous
        previous = wanted[t]
    # Between notes, hold the next note's position (go there early); after the last, stay.
    busy = ~np.isnan(wanted)
    known = np.flatnonzero(busy)
    if known.size == 0:
        wanted[:] = 0.0
    else:
        nxt = np.minimum(np.searchsorted(known, np.arange(T)), known.size - 1)
        fill = np.isnan(wanted)
        wanted[fill] = wanted[known[nxt[fill]]]
    local = goal.fingers - hand.finger_offset
    fingers = np.where(goal.keys & (local >= 0) & (local < FINGERS_PER_HAND) & ~skip, local, -1)
    return HandPlan(
        position=np.clip(wanted, *hand.tx_range),
        busy=busy,
        fingers=fingers,
        skip=skip,
        cost=0.0,
        pose=np.zeros(T, dtype=int),  # frame by frame: the home pose throughout
    )


def plan_reaches(poses: Sequence[HandPose]) -> tuple[np.ndarray, np.ndarray]:
    """(K, 5, 2, 2) twice: each pose's ``full_reach`` and ``reach`` as the plans take
    them. A reach pose (after the first) that does not push the forearm into the keys
    plays no black key: with the wrist turned the thumb reaches none, and octaves on
    black keys given to the index and little fingers at the edge of their reach failed
    (a Clara Schumann polonaise's bass, turned: 53 % of its keys lost against 31 %
    straight)."""
    full = np.stack([pose.full_reach for pose in poses])
    inner = np.stack([pose.reach for pose in poses])
    for k, pose in enumerate(poses[1:], start=1):
        if pose.ty <= 0.0:
            full[k, :, 1] = inner[k, :, 1] = (np.inf, -np.inf)  # an empty interval
    return full, inner


def reach_model(hand: Hand, poses: Sequence[HandPose], pose: int = 0) -> HandReach:
    """What ``hand`` reaches in pose ``pose`` of ``poses`` (the home pose by default), as the
    plans take it."""
    p = poses[pose]
    return HandReach(p.full_reach, p.reach, hand.root_y, hand.slide_range)


def playable_mask(
    planner: PlannerState, hand: Hand, plan: HandPlanArrays, poses: Sequence[HandPose]
) -> np.ndarray:
    """(T, 88) bool: the due keys of ``hand``'s plan that a finger can press at each frame:
    not skipped, not during a shift, and within the finger's reach (widened by
    ``playable_tolerance_m``) from the planned position in the planned pose."""
    goal = planner.goal
    frames, keys = np.nonzero(goal.keys & ~plan.skip & ~plan.free[:, None])
    finger = planner.fingers[frames, keys] - hand.finger_offset
    mine = (finger >= 0) & (finger < FINGERS_PER_HAND)
    frames, keys, finger = frames[mine], keys[mine], finger[mine]
    full = plan_reaches(poses)[0]
    lo, hi = full[plan.pose_plan[frames], finger, C.BLACK_KEY_MASK[keys].astype(int)].T
    relative = planner.key_point[keys, 1] - plan.tx_plan[frames]
    tolerance = planner.config.plan.playable_tolerance_m
    inside = (relative >= lo - tolerance) & (relative <= hi + tolerance)
    mask = np.zeros(goal.keys.shape, dtype=bool)
    mask[frames[inside], keys[inside]] = True
    return mask


def played_counts(
    fingers: np.ndarray, keys: np.ndarray, hand: Hand, skip: np.ndarray
) -> np.ndarray:
    """(T,) int: how many due keys (``keys`` (T, 88) bool) the plan gives ``hand``'s fingers
    at each frame (``fingers`` (T, 88) the finger 0-9 of each, not in ``skip`` (T, 88))."""
    finger = fingers - hand.finger_offset
    mine = (finger >= 0) & (finger < FINGERS_PER_HAND)
    return (keys & mine & ~skip).sum(axis=1)


def plan_commands(
    hand: Hand,
    course: HandPlan,
    dt: float,
    cfg: PlannerConfig,
    multi_step: bool,
    played: np.ndarray | None = None,
    other: tuple[Hand, np.ndarray] | None = None,
) -> HandPlanArrays:
    """The hand's plan as it plays it: ``course`` (its positions, poses, ``busy`` and
    ``skip``) with the forearm's reference path along the keyboard, ``tx_path`` (T + 2, 2):
    position and velocity wanted at the end of every step, its shifts and the pose commanded.

    With ``multi_step`` (the whole-piece plan), a jump takes the steps the slide needs
    (:func:`pianist.control.planner.hand_plan.move_frames`) on a minimum-jerk path, the fingers
    lifted for them; otherwise every move takes ``forearm_move_s``.

    The plan's steps become minimum-jerk moves of ``forearm_move_s`` that end
    ``press_lead_frames`` before the note starts (``shift_lead_frames`` for a shift the
    fingers let go for); :func:`command_forearm` then steers the slide's servo along that
    path in closed loop. Left alone, the critically damped servo needs ~0.45 s to cover 90 %
    of a jump, which makes the hand late for every shift (and for the first note, which the
    hands reach from their home position).

    A shift lets go of the keys the hand still holds while it moves. Given ``played``
    (T,) (:func:`played_counts`), each shift may leave up to ``shift_delay_max_frames``
    frames later when fewer of the hand's due key-frames fall in its moving window so
    (the held notes kept, the next notes' first frames lost instead), if the hand then
    stays clear of ``other``'s forearm (the other hand and its plan as followed, ``tx_held``
    (T,)) and of its own next shift. ``tx_held`` (T,) is the plan as followed, with each
    shift's old position held until it leaves.
    """
    plan = course.position
    pose_plan = course.pose
    T = len(plan)
    n = max(1, round(cfg.forearm.forearm_move_s / dt))
    # A pressed finger pins the hand to its key by friction: before a shift too large for
    # the fingers to absorb, the hand lets go of its keys for the move's duration.
    free = np.zeros(T, dtype=bool)
    shift_to = np.zeros(T, dtype=int)  # during a move: the frame of the note it is for
    # Moves end ``press_lead_frames`` before the note, so that fingers press a still hand;
    # shifts ``shift_lead_frames`` before it, so that the keys before them are held longer.
    lead = cfg.fingers.press_lead_frames
    if not 0 <= cfg.forearm.shift_lead_frames <= lead:
        raise ValueError("shift_lead_frames must be between 0 and press_lead_frames")
    # A change of pose is a shift too: the wrist turns with the fingers lifted.
    turns = np.diff(pose_plan) != 0
    # The whole-piece plan was made knowing which moves it makes with the fingers on the keys.
    threshold = np.full(
        len(turns), cfg.plan.hand_plan.shift_m if multi_step else cfg.forearm.shift_threshold_m
    )
    if multi_step and cfg.plan.hand_plan.reach_pose_shift_m is not None:
        # Moves within a reach pose may be larger (``HandPlanCosts.reach_pose_shift_m``).
        turned = (pose_plan[1:] > 0) & ~turns
        threshold[turned] = cfg.plan.hand_plan.reach_pose_shift_m
    shifts = np.flatnonzero((np.abs(np.diff(plan)) > threshold) | turns) + 1
    delay = lead - cfg.forearm.shift_lead_frames
    # Steps each shift takes: a long jump needs more than one (the slide's servo has a
    # limited force); the whole-piece plan knows this and has paid for the frames.
    if multi_step:
        need = move_frames(
            plan[shifts] - plan[shifts - 1], dt, cfg.plan.hand_plan.slide_acceleration_m_s2
        )
        turn_frames = max(1, round(cfg.poses.pose_change_s / dt))
        need = np.where(turns[shifts - 1], np.maximum(need, turn_frames), need)
    else:
        need = np.full(len(shifts), n)
    delays = np.full(len(shifts), delay)
    # Only the whole-piece plan's shifts: each is one jump whose duration the plan knows
    # (a frame plan moves in one-step pieces, whose frames in between play nothing).
    if multi_step and played is not None and cfg.forearm.shift_delay_max_frames > 0:
        delays += _shift_delays(hand, plan, shifts, need, lead - delay, played, other, cfg)
    # The pose commanded: each change from the start of its shift's window.
    pose_held = pose_plan.copy()
    for k, steps, d in zip(shifts.tolist(), need.tolist(), delays.tolist(), strict=True):
        window = slice(max(0, k - steps - lead + d), max(0, k - lead + d))
        free[window] = True
        shift_to[window] = k
        if pose_plan[k] != pose_plan[k - 1]:
            pose_held[window.start : k] = pose_plan[k]
            pose_held[k : window.start] = pose_plan[k - 1]
    held = plan
    if delays.any():
        # The path below ends every move ``lead`` frames early: hold the old position
        # ``delays`` frames longer before each shift (later shifts first, so that a shift
        # that follows another keeps its own start).
        held = plan.copy()
        for k, d in zip(shifts[::-1].tolist(), delays[::-1].tolist(), strict=True):
            held[k : min(T, k + d)] = plan[k - 1]
    s = (np.arange(n) + 0.5) / n
    weights = s**2 * (1 - s) ** 2  # minimum-jerk velocity profile
    weights /= weights.sum()
    padded = np.concatenate([held, np.full(n + 3 + lead, held[-1])])
    # y[t]: where the forearm should be at the end of step t (two steps past the end too).
    y = np.array([weights @ padded[t + 1 + lead : t + 1 + lead + n] for t in range(T + 2)])
    if multi_step:
        # A jump that takes several steps follows a minimum-jerk path over them, arriving
        # when a one-step move would (not starting before the previous shift has ended):
        # its first step is small, so the fingers are off the keys before the hand flies.
        previous = 0
        for k, steps, d in zip(shifts.tolist(), need.tolist(), delays.tolist(), strict=True):
            arrive = k + d - 1 - lead  # the first step whose end is at the new place
            begin = max(previous, arrive - steps + 1)
            if arrive - begin >= 1:
                u = (np.arange(begin, arrive + 1) - begin + 1) / (arrive - begin + 1)
                start, end = y[begin - 1] if begin else y[0], y[arrive]
                y[begin : arrive + 1] = start + (end - start) * (10 * u**3 - 15 * u**4 + 6 * u**5)
            previous = arrive + 1
    ext = np.concatenate([[y[0]], y, [y[-1]]])
    return HandPlanArrays(
        tx_plan=plan,
        tx_held=held,
        busy=course.busy,
        skip=course.skip,
        free=free,
        shift_to=shift_to,
        tx_path=np.stack([y, (ext[2:] - ext[:-2]) / (2 * dt)], axis=1),
        pose_plan=pose_plan,
        pose_held=pose_held,
    )


def _shift_delays(
    hand: Hand,
    plan: np.ndarray,
    shifts: np.ndarray,
    need: np.ndarray,
    early: int,
    played: np.ndarray,
    other: tuple[Hand, np.ndarray] | None,
    cfg: PlannerConfig,
) -> np.ndarray:
    """(S,) int: frames each shift of ``hand``'s ``plan`` (T,) leaves later than planned (0
    to ``shift_delay_max_frames``): the delay whose moving window holds the fewest of the
    hand's due key-frames (``played`` (T,)), each frame of delay charged
    ``shift_delay_cost``, the earliest of equals. ``early``: frames
    before its note a shift ends when not delayed. A delay may not reach the next
    shift's window nor bring the held forearm within ``forearm_separation_m`` of
    ``other``'s (the other hand, and its plan as followed so far, ``tx_held``)."""
    T = len(played)
    sign = 1.0 if hand.side == "right" else -1.0
    out = np.zeros(len(shifts), dtype=int)
    for i, (k, steps) in enumerate(zip(shifts.tolist(), need.tolist(), strict=True)):
        start, end = max(0, k - steps - early), max(0, k - early)
        # The next shift's window (not delayed) bounds this one's.
        limit = T
        if i + 1 < len(shifts):
            limit = max(0, int(shifts[i + 1] - need[i + 1] - early))
        best, lost = 0, float(played[start:end].sum())
        for d in range(1, cfg.forearm.shift_delay_max_frames + 1):
            if end + d > limit:
                break
            if other is not None:
                # Held at its old place through frame k + d at most (the path ends each
                # move up to a frame early and holds the old place that much longer).
                other_hand, other_held = other
                there = other_hand.root_y + other_held[k : min(T, k + d + 1)]
                gap = sign * (hand.root_y + plan[k - 1] - there)
                if (gap < cfg.forearm.forearm_separation_m - 1e-9).any():
                    break
            # Lost: the delayed window, and any frames from the note on before it (the
            # hand still at its old place, the keys there planned for the new one).
            here = played[min(start + d, max(k, end)) : end + d].sum()
            here += cfg.forearm.shift_delay_cost * d
            if here < lost:
                best, lost = d, here
        out[i] = best
    return out


def command_forearm(
    ctrl: np.ndarray, data, hand: Hand, servo: SlideServo, tx_path: np.ndarray, t: int
) -> None:
    """Write the ``tx`` slide's command (m) for step ``t`` into ``ctrl`` (nu,): the servo
    steered to the path's next point (``tx_path`` (T + 2, 2), :func:`plan_commands`) from the
    slide's measured state in ``data``."""
    # The fingers are solved for where the forearm actually is (see ``forearm_lead_s``),
    # not for its plan: they then reach their keys even while it is still on its way.
    t = min(t, len(tx_path) - 3)
    state = np.array([data.qpos[hand.tx_qpos], data.qvel[hand.tx_dof]])
    ctrl[hand.tx_actuator] = servo.command(state, tx_path[t + 1])


def command_height(ctrl: np.ndarray, data, hand: Hand, raise_m: float, cfg: PlannerConfig) -> None:
    """Write the height slide's command (m) into ``ctrl``, when the scene has one: the
    playing height raised by ``raise_m`` (the pose's), stiffened against the keys' push."""
    if hand.tz_actuator is not None:
        assert hand.tz_qpos is not None and hand.tz_range is not None  # set with tz_actuator
        # The keys push the hand up (about a centimetre under a chord): pressing harder the
        # further it has risen stiffens the slide's servo against them.
        height = cfg.forearm.hand_height_m + raise_m
        rise = data.qpos[hand.tz_qpos] - height
        command = height - cfg.forearm.height_feedback * rise
        ctrl[hand.tz_actuator] = np.clip(command, *hand.tz_range)


def keep_forearms_apart(
    hands: Sequence[Hand], plans: Sequence[HandPlan], separation: float
) -> list[HandPlan]:
    """The two hands' plans with their positions shifted so that the right forearm stays
    ``separation`` m right of the left (in the order given).

    The hand whose next note comes later yields to the other (a hand with nothing to play
    to one that plays; of two idle hands, the one that waits longer); when both play, both
    give way equally.
    """
    r = 0 if hands[0].side == "right" else 1
    right, left = hands[r], hands[1 - r]
    right_plan, left_plan = plans[r], plans[1 - r]
    y_right = right_plan.position + right.root_y
    y_left = left_plan.position + left.root_y
    short = np.maximum(separation - (y_right - y_left), 0.0)
    # Of two idle hands the one that waits longer yields: sharing the way, a hand resting a
    # frame between two notes is pushed off its keys by the other's waiting place and comes
    # back, a shift each time (Schoenberg op. 19/2: 100 frames).
    wait_right = _frames_to_next_note(right_plan.busy)
    wait_left = _frames_to_next_note(left_plan.busy)
    right_share = np.where(wait_right < wait_left, 0.0, np.where(wait_left < wait_right, 1.0, 0.5))
    moved = [
        dataclasses.replace(
            right_plan,
            position=np.clip(right_plan.position + short * right_share, *right.tx_range),
        ),
        dataclasses.replace(
            left_plan,
            position=np.clip(left_plan.position - short * (1 - right_share), *left.tx_range),
        ),
    ]
    return moved if r == 0 else moved[::-1]


def _frames_to_next_note(busy: np.ndarray) -> np.ndarray:
    """(T,) frames from each frame to the hand's next busy frame (0 when busy; inf after its
    last note)."""
    T = busy.shape[0]
    known = np.flatnonzero(busy)
    nxt = np.searchsorted(known, np.arange(T))
    wait = np.full(T, np.inf)
    ok = nxt < known.size
    wait[ok] = known[nxt[ok]] - np.arange(T)[ok]
    return wait
