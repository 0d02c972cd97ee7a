"""Tuning of the planner, the environment it plays in, and what its stages share.

- :class:`PlannerConfig`: every setting, lengths in m, times in s, angles in rad, in one
  group per stage (:class:`KeyPressConfig`, :class:`PoseConfig`, :class:`ForearmConfig`,
  :class:`FingerConfig`, :class:`StrikeConfig`, :class:`PlanConfig`, :class:`IKConfig`).
  Frozen and hashable: it keys the posture and plan caches.
- :data:`ENV_OPTIONS`: the :class:`pianist.env.PianoEnv` options the planner plays best with.
- :class:`PlannerState`: what the per-hand stages (forearm, targets) read of the planner
  during an episode, with shapes and units.
- ``FINGERS_PER_HAND`` and ``FINGER_PREFIXES``: a hand's fingers, thumb to little finger.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, Protocol

import numpy as np

from pianist.control.planner.hand_plan import HandPlanCosts, Objective

if TYPE_CHECKING:
    import mujoco

    from pianist.control.planner.strikes import StrikePlan
    from pianist.env.handle import ControlHandle
    from pianist.music import GoalFrames

FINGERS_PER_HAND = 5
FINGER_PREFIXES = ("TH", "FF", "MF", "RF", "LF")


class PlanKind(NamedTuple):
    """How a plan is made: ``kind`` ("frame" by frame, over the whole "piece", or "split"),
    whether the plan chooses the fingers (``refinger``), what the whole-piece plan counts
    (``objective``, ``HandPlanCosts.objective``), and whether it may turn a hand's wrist
    also for a hand's keys in turn that span wider than the straight hand (``turn``:
    :data:`TURN_FOR_SPANS`), not only for chords struck together that it cannot span."""

    kind: str
    refinger: bool
    objective: Objective
    turn: bool = False


#: The whole-piece plan's weights for a reach pose in the plan that turns for spans
#: (``PlanKind.turn``): a turned hand is counted to lose 5 % of its keys where no chord
#: wants it (against all of them otherwise) and a key at the edge of a reach pose's reach
#: 0.1 (against ``edge_cost`` 0.25: an octave's thumb and little finger both are), and a
#: turned hand moves up to 3 cm (a white key) with its fingers on the keys. Broken octaves
#: (one key at a time, an octave apart) are played turned this way; whether a turn pays in
#: a piece is left to the rehearsal, which measures it with the physics.
TURN_FOR_SPANS: dict[str, Any] = {
    "reach_pose_idle_loss": 0.05,
    "reach_pose_for": "spans",
    "reach_pose_edge_cost": 0.1,
    "reach_pose_shift_m": 0.03,
}

#: The plans ``hand_planning="best"`` may choose from, by name (:class:`PlanKind`).
PLAN_CANDIDATES: dict[str, PlanKind] = {
    "frame": PlanKind("frame", False, "key_frames"),
    "piece-song": PlanKind("piece", False, "key_frames"),
    "piece": PlanKind("piece", True, "key_frames"),
    "piece-f1": PlanKind("piece", True, "step_f1"),
    "piece-f1-turn": PlanKind("piece", True, "step_f1", turn=True),
}


class _Group:
    """A group of settings: lists given for its tuple fields are kept as tuples, so that the
    config stays hashable (it keys the posture and plan caches)."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if isinstance(value, (list, tuple)):
                object.__setattr__(self, f.name, _tuples(value))


def _tuples(value: Any) -> Any:
    """``value`` with every list in it a tuple."""
    return tuple(_tuples(v) for v in value) if isinstance(value, (list, tuple)) else value


@dataclass(frozen=True)
class KeyPressConfig(_Group):
    """Where on each key a finger presses, and how deep (the controller's key points)."""

    white_press_x_m: float = 0.045
    """Where along a white key (x from its centre, towards the player) a finger presses it,
    in front of the black keys."""
    thumb_white_press_x_m: float = 0.064
    """The same for the thumb, which reaches lowest near the front edge."""
    black_press_x_m: float = 0.01
    """Where along a black key (world x) a finger presses it, near its front end."""
    white_press_depth_m: float = 0.025
    """How far below a white key's top the fingertip is sent: past the key's travel, so the
    position servo keeps pushing it down."""
    black_press_depth_m: float = 0.045
    """The same for a black key (shorter lever, so it needs more force)."""
    thumb_extra_depth_m: float = 0.02
    """Added to the thumb's press depth: its servos are weak for the force a key needs."""


@dataclass(frozen=True)
class PoseConfig(_Group):
    """The hand's poses and the posture samples each is made of (postures.py): the wrist's
    angles, the reach read from the samples, the lifted posture."""

    samples: int = 4000
    """Sampled postures per finger for the nearest-posture start of the IK."""
    reach_margin: float = 0.3
    """Part of a finger's sampled reach (across the keys) left unused at each end when a chord
    forces a finger away from its resting place: a finger at the edge of its reach slips."""
    reach_depth_m: float = 0.008
    """How far below a key's top a sampled fingertip must go to count as reaching the key."""
    reach_x_tolerance_m: float = 0.012
    """How close (along the key) to the press point a sampled fingertip must be to count."""
    thumb_offset_m: float = 0.03
    """How far the thumb presses to the left (right hand; mirrored for the left) of the
    index finger's rest position: the thumb, without its rotation joint, reaches key depth
    only under the side of the palm."""
    lift_height_m: float = 0.035
    """Clearance above the white keys of a finger that is not due."""
    wrist_pose: tuple[float, float] = (0.0, 0.0)
    """WRJ2 and WRJ1, held constant, when the forearm has its height slide."""
    wrist_pose_without_tz: tuple[float, float] = (0.0, 0.25)
    """The same without it: the wrist flexed, else the fingers cannot reach a key's bottom
    from the home height."""
    reach_poses: tuple[tuple[float, float, float, float], ...] = ((-0.44, 0.28, 0.0, 0.0075),)
    """Hand poses besides the home one (``wrist_pose``, ``ty`` 0, not raised) that the
    whole-piece plan may put a hand in, each (WRJ2 rad, WRJ1 rad, forearm ty m, forearm
    raised m above ``hand_height_m``). The default turns the wrist towards the thumb and
    flexes it: the thumb's lowest white key to the little finger's highest spans 0.176 m,
    an octave (0.1645 m) and more, against 0.129 m straight. The 7.5 mm raise lets a
    little finger at the edge of that reach hover over its key instead of pressing the one
    below it.
    Each pose has its own posture samples and reach; the plan changes pose with the
    fingers lifted (``pose_change_s``; its weights in :class:`HandPlanCosts`). Empty: the
    wrist stays at its home pose throughout."""
    pose_change_s: float = 0.15
    """How long a change of pose takes: the wrist's servos (kp 10 and 8) turn it by 0.44 and
    0.28 rad to within 0.015 rad in 3 control steps of 0.05 s, in both physics presets."""
    wrist_feedback: tuple[float, float] = (2.0, 0.0)
    """Gains (WRJ2, WRJ1) of the wrist commands on how far each joint is off its pose. A
    forearm move swings the hand sideways on its soft wrist servo (kp 10): left alone, WRJ2
    is still ~0.04 rad off (4 mm at the fingertips) a step after a shift and then drifts a
    few mm, enough to land a finger beside its key; with the feedback it is back within
    ~0.01 rad. (Stiffening the flexion WRJ1 the same way leaves the thumb too high to sound
    its key.)"""

    def hand_poses(self, has_tz: bool) -> tuple[tuple[float, float, float, float], ...]:
        """Every pose a hand may take, (WRJ2 rad, WRJ1 rad, ty m, raised m): the home pose first
        (``wrist_pose``, or ``wrist_pose_without_tz`` in a scene without the height slide,
        where the reach poses are not used), then ``reach_poses``."""
        if not has_tz:
            return ((*self.wrist_pose_without_tz, 0.0, 0.0),)
        return ((*self.wrist_pose, 0.0, 0.0), *self.reach_poses)

    def __post_init__(self) -> None:
        super().__post_init__()
        for pose in self.reach_poses:
            if len(pose) != 4 or not all(np.isfinite(v) for v in pose):
                raise ValueError(
                    "each of reach_poses must be (WRJ2 rad, WRJ1 rad, ty m, raised m), "
                    f"not {pose!r}"
                )
        if not self.pose_change_s > 0:
            raise ValueError(f"pose_change_s must be > 0, not {self.pose_change_s}")


@dataclass(frozen=True)
class ForearmConfig(_Group):
    """Where the forearm goes and how its slides move (forearm.py): the frame-by-frame plan,
    shifts, the playing height."""

    skip_out_of_reach: bool = True
    """A chord struck together that no hand position covers (an octave is beyond the Shadow
    hand's span) is played without the keys that cannot be reached along with the most
    others, keeping the outer voice (the bass in the left hand, the top in the right); its
    fingers stay off. Otherwise the hand goes halfway and usually reaches none of them."""
    lazy_m: float = 0.02
    """The hand stays where it is for the next notes if every finger still reaches its key
    from there and it is at most this far from where those notes would put it (0: always
    re-centre). Every move costs the held keys frames; scales gain most."""
    forearm_separation_m: float = 0.17
    """Closest the two forearm roots may come along the keyboard (they touch below ~0.15)."""
    forearm_move_s: float = 0.05
    """Duration of the forearm's move to a new hand position, ending ``press_lead_frames``
    before the note (a shift: ``shift_lead_frames``): one control step (the slide is steered
    in closed loop, and the wrist held against the swing), so the fingers are off their keys
    as briefly as possible."""
    forearm_lead_s: float = 0.05
    """The fingers aim from where the forearm will be this much later at its current velocity
    (0: from where it is)."""
    shift_threshold_m: float = 0.015
    """A forearm move larger than this lifts the hand's fingers for its duration."""
    shift_lead_frames: int = 0
    """Frames before its note a shift (a move the fingers let go for, see
    ``shift_threshold_m``) ends, at most ``press_lead_frames``: 0, the hand arrives as the
    note's frame begins and its fingers press from the hover they travelled in. The keys
    before the shift are then held a frame longer."""
    shift_delay_max_frames: int = 8
    """Frames a shift of the whole-piece plan may leave later than planned, so that the hand
    holds its keys longer and the next notes lose their first frames instead, when fewer of
    its due key-frames fall in the moving window so
    (:func:`~pianist.control.planner.forearm.plan_commands`). 0: never."""
    shift_delay_cost: float = 0.5
    """Key-frames each frame of a shift's delay is charged besides those it loses: a hand
    that arrives later presses its next notes no sooner."""
    hand_height_m: float = -0.03
    """Height command of the forearm's ``tz`` slide (when the scene has one)."""
    height_feedback: float = 3.0
    """Gain of the forearm height command on how far the hand has risen above its height."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.shift_delay_max_frames < 0 or self.shift_delay_cost < 0:
            raise ValueError(
                "shift_delay_max_frames and shift_delay_cost must be >= 0, not "
                f"{self.shift_delay_max_frames} and {self.shift_delay_cost}"
            )


@dataclass(frozen=True)
class FingerConfig(_Group):
    """Each finger's press, hover and lift decisions every step (targets.py)."""

    press_lead_frames: int = 1
    """Frames ahead of the scored frame whose keys the fingers go for (servo lag)."""
    hover_lead_s: float = 0.25
    """How long before its note a finger comes to hover over its key."""
    hover_height_m: float = 0.01
    """Clearance above the key top of a finger that is due soon, or not yet over its key."""
    release_height_m: float = 0.003
    """Clearance above the key top a finger goes to between two strikes of one key."""
    transfer_height_m: float = 0.003
    """Clearance above the key top of a finger going straight from one key to the next (a
    chord change), lower than ``hover_height_m``: the key it leaves rises slowly and holds
    it by friction, so it lands ~1 step sooner from this low path."""
    align_tolerance_m: float = 0.009
    """How close (across the keys) to a white key's press point a finger must be before it
    presses: a finger that lands beside its key sticks to the neighbour by friction."""
    black_align_tolerance_m: float = 0.008
    """The same for a black key: not tighter, as a finger still settling from a move is then
    held back a frame (at 4.5 mm every black key of the D major scale sounded late)."""
    align_along_m: float = 0.02
    """How far behind the press point (x) a finger other than the thumb may be and press a
    white key (further back it would land on a black key). Along a black key there is no
    such limit: a finger that slid back on it still presses it."""
    black_front_m: float = 0.01
    """How far in front of a black key's press point (x, towards the player) a finger may be
    and press it: further forward it is over the white key before it, where it would press
    that key or stop against the black key's front; it hovers on until it is over the black
    key."""
    keep_pressing_ratio: float = 1.3
    """A pressing finger keeps pressing until it is this many tolerances off its key."""
    keep_sounding: bool = True
    """A finger that pressed its key last step and holds it sounding keeps pressing, however
    far its tip has slid across the keys (the thumb's tip slides ~18 mm sideways as it
    presses: re-aligning let the key go)."""
    stuck_frames: int = 2
    """Steps a finger may hover off its key without moving before it presses from there."""
    stuck_reach_m: float = 0.013
    """How far off its key (across) a stuck finger may be and still press from there."""
    unwedge: bool = True
    """A finger that hovers off its key without moving, its tip below the key's top (wedged
    against the key's side or between two keys), takes its lifted posture for a step to
    come free, instead of pushing sideways against the key for the rest of the note."""
    still_m: float = 0.0015
    """A fingertip that moved less than this in a step stands still."""
    hover_in_shift: bool = True
    """During a large forearm move the fingers of the note it is for hover over their keys
    (instead of taking their lifted posture)."""
    jump_lift_m: float = 0.03
    """...except a finger still low on the keys (within ``jump_low_m`` of the white keys' top)
    whose key is further than this across the keyboard: it takes its lifted posture for the
    move. Skimming towards a key it cannot reach yet, a finger is dragged across the keys and
    sticks to one (in the original's chord progression the right thumb, 9 cm from its next
    C4, caught F4 and held it, and the hand, through the whole last chord)."""
    jump_low_m: float = 0.01
    """Height above the white keys' top below which a finger counts as low (see above)."""
    hover_stops_at_shift: bool = True
    """Fingers hover only over keys due before the hand's next large move: the keys after it
    are out of reach from here, and a finger (the thumb above all) that strains towards one
    dips onto the keys on its way."""


@dataclass(frozen=True)
class StrikeConfig(_Group):
    """How fast each key is struck, from its note's velocity (strikes.py)."""

    push_below_velocity: int = 80
    """Notes softer than this MIDI velocity are *pushed* (:mod:`strikes`): their key is
    brought down along a planned descent at the speed their velocity maps to, each step's
    push chosen by predicting the key's angle with the simulator (:mod:`strike_prediction`).
    0: none; in a song of one velocity throughout none is pushed. Louder notes are struck
    (``predict_strikes``): a strike from above sounds ~80-95 at the least, so pushing notes
    of 80 or more gains no loudness and costs F1."""
    push_speed_scale: float = 1.0
    """The key speeds a push plans, as a share of those the velocities map to (its
    calibration, ``benchmarks/calibrate_strikes.py``)."""
    push_breakaway_share: tuple[float, float] = (0.68, 0.5)
    """The share of its key's press depth a pushing finger is sent to before its push offset,
    white and black keys: a finger resting on a white key starts moving it only at ~70 % of
    the press depth (18 mm of 25), on a black key at ~50 % (of 45 mm)."""
    push_lag_frames: int = 0
    """Frames before its note's frame a pushed key should sound (the servo's lag)."""
    push_grace_frames: int = 2
    """Steps after its planned sounding that a pushed note's finger is still not pushed
    harder for not sounding its key (``unsounded_push_rad``, ``restrike_push_rad``)."""
    push_offsets_rad: tuple[float, ...] = (-0.1, 0.0, 0.1, 0.2, 0.35, 0.5)
    """The push offsets tried at each step of a push (rad along the finger's descent
    direction from its breakaway posture), ascending: one simulated control step each."""
    predict_strikes: Literal["dynamics", "always", "never"] = "dynamics"
    """Where every note not pushed is struck with the force, out of ``strike_offsets_rad``,
    whose strike simulated two steps ahead sounds in the note's step nearest its velocity
    (:mod:`strike_prediction`): ``"dynamics"``, in a song whose notes' velocities differ (a
    song of one velocity plays as without); ``"always"``, in any song (the strikes that then
    sound on time add F1, at about twice the planner's time); ``"never"``, struck with the
    planner's own command."""
    strike_offsets_rad: tuple[float, ...] = (-0.6, -0.4, -0.2, 0.0, 0.2, 0.4)
    """The offsets tried at the first step of a strike (rad along the finger's
    descent direction from its press), as many as ``push_offsets_rad`` (they are simulated
    together): how far a strike's key has gone when the next step starts sets how loud it
    reads, ~80-110 from one finger's strikes."""
    push_rest_m: float = -0.008
    """Height above the key top a finger waiting for its push is sent: below it, as the
    finger's servo falls ~8 mm short of a target above the keys, so that the finger rests on
    the key and the key goes down from its push, not from its fall."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0 <= self.push_below_velocity <= 128:
            raise ValueError(
                "push_below_velocity must be a MIDI velocity from 0 (no pushes) to 128, "
                f"not {self.push_below_velocity}"
            )
        offsets = self.push_offsets_rad
        if len(offsets) < 2 or any(b <= a for a, b in zip(offsets, offsets[1:], strict=False)):
            raise ValueError(
                f"push_offsets_rad must be two or more ascending offsets, not {offsets}"
            )
        if self.predict_strikes not in ("dynamics", "always", "never"):
            raise ValueError(
                "predict_strikes must be 'dynamics', 'always' or 'never', "
                f"not {self.predict_strikes!r}"
            )
        if len(self.strike_offsets_rad) != len(offsets):
            raise ValueError(
                f"strike_offsets_rad must have as many offsets as push_offsets_rad "
                f"({len(offsets)}), not {len(self.strike_offsets_rad)}"
            )


@dataclass(frozen=True)
class PlanConfig(_Group):
    """Which hand plan is made and how one is chosen (controller.py, hand_plan.py, coverage.py)."""

    hand_planning: Literal["frame", "piece", "split", "best"] = "best"
    """How the hand positions are planned: ``frame`` by frame with the song's fingering,
    staying put within ``lazy_m``; over the whole ``piece``
    (:mod:`pianist.control.planner.hand_plan`) with the fingering ``refinger`` says; over the whole
    piece after a joint plan of both hands has ``split`` the keys between them anew
    (:mod:`pianist.control.planner.hand_split`; not among the candidates of ``best``: no
    better, and four times slower to plan); or the ``best`` of the
    plans named in ``best_candidates``, chosen as ``choose_plan`` says."""
    best_candidates: tuple[str, ...] = ("frame", "piece-f1", "piece-f1-turn")
    """The plans ``hand_planning="best"`` chooses from (:data:`PLAN_CANDIDATES`), in order
    of preference: ``frame`` by frame, or over the whole piece with the plan's fingering
    counting the per-step F1 the metric scores (``piece-f1``, ``HandPlanCosts.objective``),
    turning a hand's wrist for chords the straight hand cannot span, or wherever a turn
    helps (``piece-f1-turn``: broken octaves, a hand's notes an octave apart in turn).
    Also known: ``piece``, the same counting lost key-frames, and ``piece-song``, the
    whole-piece plan with the song's fingering: rehearsing them too costs most of an episode
    more per cold start for next to nothing."""
    choose_plan: Literal["rehearsal", "playable"] = "rehearsal"
    """How ``best`` chooses: by playing each candidate through once on a copy of the
    environment and keeping the best F1 (``rehearsal``, :mod:`rehearsal`; the first of
    equals; the performance then replays the winner's actions while it stays on their path),
    or by the key-frames each leaves playable (``playable``: a later plan is chosen only if
    it adds ``piece_plan_margin`` of the song's key-frames; no simulation, but blind to how a
    plan is executed)."""
    replay_tape: bool = True
    """With ``choose_plan="rehearsal"``, hand the winning rehearsal's recorded steps to the
    environment to play back (:meth:`pianist.env.PianoEnv.play_tape`) while the performance
    follows them, instead of simulating them again: the same episode, bit for bit, without
    the performance's physics (a cold start a quarter to a third faster)."""
    piece_plan_margin: float = 0.02
    """With ``choose_plan="playable"``, the share of the song's key-frames a later plan must
    add to be chosen (wide chords, jumps, a fingering the Shadow hand cannot span)."""
    playable_tolerance_m: float = 0.005
    """How far outside a finger's sampled reach a key still counts as playable when plans
    are compared (the sampled reach is a little conservative: the frame-by-frame plan's
    chords press keys a few mm beyond it)."""
    hand_plan: HandPlanCosts = HandPlanCosts()
    """Weights of the whole-piece plan."""
    share_keys: bool = True
    """With the plan's fingering, offer the keys one hand cannot reach to the other hand."""
    uncross_hands: bool = True
    """Plan with the song's hand crossings (a right-hand key below a left-hand one) given to
    the hand on that side (:func:`pianist.control.planner.hand_order.uncross_hands`): the forearms
    cannot cross, and a plan that sends one through the other loses both hands' keys."""
    clearance_cost: float = 5.0
    """Per frame, of a planned forearm position closer than ``forearm_separation_m`` to the
    other forearm's (in lost key-frames)."""
    refinger: bool = True
    """With ``hand_planning="piece"``, choose the fingers too (each key to a finger of its hand
    that reaches it from the planned position) instead of the song's: a pianist's fingering
    spans more than the Shadow hand, whose fingers other than the thumb each reach about one
    white key from a given hand position."""

    def __post_init__(self) -> None:
        super().__post_init__()
        unknown = [name for name in self.best_candidates if name not in PLAN_CANDIDATES]
        if not self.best_candidates or unknown:
            raise ValueError(
                f"best_candidates must be some of {', '.join(PLAN_CANDIDATES)}, "
                f"not {list(self.best_candidates)}"
            )


@dataclass(frozen=True)
class IKConfig(_Group):
    """Each finger's inverse kinematics and the pushes after it (ik.py)."""

    iterations: int = 3
    """Damped least-squares steps from the nearest sampled posture: the samples start each
    finger within a few mm of its target, and each step costs a kinematics pass per hand."""
    damping: float = 0.01
    """The steps' damping (m; its square is added to the normal equations' diagonal): a
    target out of reach makes small steps along the boundary instead of wild ones."""
    rest_weight: float = 1e-4
    """Pull towards the sampled start posture (per rad^2, against tip error in m^2)."""
    thumb_lateral_weight: float = 4.0
    """Weight of the thumb's error across the keys (y), against along them and up (x, z), in
    its inverse kinematics. A thumb pressing a white key aims past the key's travel at the
    edge of its reach, where its joints cannot put the tip both that deep and over the key:
    unweighted, the solution gave up ~8 mm across (the tip then pressed the crack between
    two keys, or slid off as it pressed); weighted, it gives up depth, which the key's bottom
    takes anyway. The other fingers keep equal weights."""
    hover_height_weight: float = 10.0
    """In a reach pose (``reach_poses``), the weight of a hovering finger's error in height
    (z), against across and along the keys. A finger hovering over a key at the edge of the
    turned hand's reach cannot be both that far out and that high: unweighted, the solution
    gave up height and the little finger of an octave pressed the key below its own for the
    six frames it hovered; weighted, it gives up reach and stays above the keys. The home
    pose keeps equal weights (its behaviour unchanged)."""
    step_limit_rad: float = 0.3
    """Largest change of one joint in one IK iteration."""
    bent_wrist_push: float = 0.0
    """Extra push of a pressing finger per radian the keys have bent the wrist up (rad/rad;
    WRJ1 measured against its pose). The keys of a chord bend the wrist up by 0.1-0.2 rad,
    which lifts the finger that comes last (often the little one) ~1 cm off its key: it
    presses level with the key's top without sounding it. Off by default: what it wins on
    real pieces it loses on the original's chord progression."""
    reach_bent_wrist_push: float = 2.0
    """``bent_wrist_push`` in a reach pose (the wrist turned and flexed, an octave's stretch),
    where the little finger holds its key at the edge of its reach: held chords bend the
    flexed wrist up by ~0.1 rad and the key rises out of sounding (more than 2 presses
    neighbouring keys)."""
    thumb_push_rad: float = 0.3
    """Extra command of a pressing thumb along the joint direction that lowers its tip."""
    finger_push_rad: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    """The same for the index, middle, ring and little fingers."""
    unsounded_push_rad: float = 0.3
    """Added for a finger that has pressed its key for ``unsounded_steps`` without sounding
    it: resting on the key's top, too weak to push it down (the little finger above all)."""
    unsounded_steps: int = 2
    """Control steps a finger presses its key without it sounding before it is pushed harder
    (``unsounded_push_rad``): a key going down normally sounds within one or two."""
    restrike_push_rad: tuple[float, float, float, float, float] = (0.0, 0.3, 0.3, 0.3, 0.3)
    """Extra push (thumb to little finger) of a finger pressing again, at the first step, the
    key it let up the step before (a re-strike: two notes of one key a frame apart). The key
    has that one step to go down again, and from where the finger rose (a median 7-12 mm
    above the key) the servo alone sounds it late. Not the thumb: pushed, it sounds the key
    beside it."""
    unsounded_latch: bool = True
    """Keep the push for the rest of the key's press once given (the key sounds only in the
    last 0.5 degrees of its travel: a finger easing off lets it flicker)."""


@dataclass(frozen=True)
class PlannerConfig:
    """Tuning of :class:`IKPlanner`, one group per stage; lengths in m, times in s, angles in
    rad. Frozen and hashable (it keys the posture and plan caches).

    Build it by groups (``PlannerConfig(fingers=FingerConfig(hover_height_m=0.005))``), or
    change fields by their own names, which are unique across the groups
    (``config.with_fields(hover_height_m=0.005)``)."""

    keys: KeyPressConfig = KeyPressConfig()
    poses: PoseConfig = PoseConfig()
    forearm: ForearmConfig = ForearmConfig()
    fingers: FingerConfig = FingerConfig()
    strikes: StrikeConfig = StrikeConfig()
    plan: PlanConfig = PlanConfig()
    ik: IKConfig = IKConfig()
    paper_embodiment: bool = False
    """Play in the paper's scene (forearm slides ``tx`` and ``ty`` only) instead of declaring
    the height slide (:data:`ENV_OPTIONS`): the thumb then cannot press a white key."""
    full_hand: bool = False
    """In the full action space (``reduced_action_space=False``), also move the joints the
    paper's reduced hand does without (THJ5, THJ1, LFJ5) and THJ2 below 0. Off, the planner
    holds them as the reduced hand has them (commanded 0; THJ2 in [0, 0.698] rad) and plays
    as it does there: every rule here was tuned on that hand."""

    def with_fields(self, **changes: Any) -> PlannerConfig:
        """A copy with the fields named changed, each by its own name in whichever group it
        is (``with_fields(hover_height_m=0.005, damping=0.02)``).

        Raises:
            ValueError: a name that is no field of any group.
        """
        groups: dict[str, dict[str, Any]] = {}
        top: dict[str, Any] = {}
        for name, value in changes.items():
            group = _GROUP_OF.get(name)
            if group is not None:
                groups.setdefault(group, {})[name] = value
            elif name in _TOP_FIELDS:
                top[name] = value
            else:
                raise ValueError(f"PlannerConfig has no field {name!r}")
        replaced = {g: dataclasses.replace(getattr(self, g), **v) for g, v in groups.items()}
        return dataclasses.replace(self, **replaced, **top)


#: Each group's field names, by the group's attribute on :class:`PlannerConfig`.
_GROUPS: dict[str, type] = {
    "keys": KeyPressConfig,
    "poses": PoseConfig,
    "forearm": ForearmConfig,
    "fingers": FingerConfig,
    "strikes": StrikeConfig,
    "plan": PlanConfig,
    "ik": IKConfig,
}
_GROUP_OF: dict[str, str] = {
    f.name: group for group, cls in _GROUPS.items() for f in dataclasses.fields(cls)
}
_TOP_FIELDS = {f.name for f in dataclasses.fields(PlannerConfig)} - set(_GROUPS)


#: The poses (WRJ2 rad, WRJ1 rad, forearm ty m, raised m) over which the whole hand's reach
#: ceiling is taken (``reach_ceiling_f1``; the planner plays in its own few, ``reach_poses``):
#: the wrist straight, turned towards the thumb and flexed (as far as it goes, and less),
#: each also with the forearm pushed 3 cm into the keys, which brings the thumb's tip to the
#: black keys' press points. Over open-etude-12 the ceiling is 0.994 with these (0.995 with
#: five more wrist angles, turned the other way among them), 0.978 without the push, 0.964
#: with the wrist straight.
WHOLE_HAND_POSES: tuple[tuple[float, float, float, float], ...] = (
    (0.0, 0.0, 0.0, 0.0),
    (-0.44, 0.28, 0.0, 0.0),
    (0.0, 0.0, 0.03, 0.0),
    (-0.44, 0.28, 0.03, 0.0),
    (-0.52, 0.35, 0.0, 0.0),
)

#: ``reach_poses`` for chords an octave wide with keys inside it (C-E-G-C): the default turned
#: pose, and a second one flexed further (0.40 rad of WRJ1's 0.49) and raised 2 cm. In the
#: default pose the index finger cannot come nearer the thumb than F4 while the thumb holds C4
#: and the little finger C5, so the plan leaves C4 out (per key 0.0, F1 0.854, fast); with the
#: second pose every key of C-E-G-C in one hand and two octaves lower in the other sounds in
#: 0.88-1.0 of its frames (F1 0.885 fast, 0.940 faithful, with ``reach_bent_wrist_push``
#: 0: in the flexed pose the push costs C5, F1 0.82 / 0.86). Not the default: on the ``octaves``
#: suite (fast) it plays seventh chords better (0.739 -> 0.782) and an octave melody worse
#: (0.796 -> 0.667), where the plan keeps the flexed, raised hand for the whole melody;
#: open-etude-12 is unchanged but for two pieces (-0.008, -0.0002).
CHORD_REACH_POSES: tuple[tuple[float, float, float, float], ...] = (
    (-0.44, 0.28, 0.0, 0.0075),
    (-0.44, 0.40, 0.0, 0.02),
)

#: Environment options the planner plays best with: the forearm's height slide added. In the
#: paper's action space the Shadow thumb cannot press a white key: with the forearm at its home
#: height its fingertip capsule stops ~1.5 mm above the depth at which a key sounds, even with
#: the wrist flexed (measured by sampling every thumb and wrist angle).
ENV_OPTIONS: dict[str, Any] = {"forearm_dofs": ("tx", "ty", "tz")}
#: The paper's embodiment (``PlannerConfig.paper_embodiment``).
PAPER_ENV_OPTIONS: dict[str, Any] = {"forearm_dofs": ("tx", "ty")}


class PlannerState(Protocol):
    """What the per-hand stages read of the planner (:class:`IKPlanner` sets it at reset)."""

    config: PlannerConfig
    handle: ControlHandle
    """The environment's simulator state (``data``) and step."""
    goal: GoalFrames
    """The song's goal frames: ``keys`` (T, 88) bool due, ``fingers`` (T, 88) int."""
    scratch: mujoco.MjData
    """Scratch state the fingers are solved in (forearm and wrist as commanded)."""
    fingers: np.ndarray
    """(T, 88) int: the finger that presses each due key, 0-4 right hand, 5-9 left (the
    song's or the whole-piece plan's)."""
    key_point: np.ndarray
    """(88, 3) m: where a finger presses each key (world frame)."""
    key_top_z: np.ndarray
    """(88,) m: height of each key's top."""
    key_depth: np.ndarray
    """(88,) m: how far below its top a fingertip is sent to press each key."""
    strikes: StrikePlan
    """How fast each due key is struck (:mod:`strikes`)."""
    key_qpos: np.ndarray
    """(88,) int: each key's joint in ``qpos``."""
    key_threshold: np.ndarray
    """(88,) rad: the key angle past which a key counts as down."""
