"""Where an episode's key-frames go wrong, note by note (pure NumPy, any controller).

The F1 says how much is wrong; this says what kind of wrong. A *note* is a run of consecutive
frames in which one key is due. Every due key-frame that does not sound falls in exactly one
class, and every key-frame that sounds without being due in exactly one other:

- missed, by the note it belongs to:
  - ``late``: before the note first sounds (the strike came after the note's first frame);
  - ``dropout``: after the note first sounded (the key rose under its finger, or was let go);
  - ``never``: a note that never sounds;
- false (sounding, not due), by the nearest note of the same key:
  - ``held``: that key was due within ``window`` frames before (held past the note's end, or
    not let up between two notes of the key);
  - ``early``: else, due within ``window`` frames after (struck before its note);
  - ``other``: neither (a wrong key, typically a neighbour of one being pressed).

Shares of key-frames are of the due key-frames, so the three missed ones add up to 1 - the
key-frame recall, and the false ones compare with them directly. :func:`f1_lost` weighs each
class in the metric's own unit instead: the episode F1 it costs.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np

from pianist.eval.metrics import _as_bool_pair, per_step_precision_recall_f1


def _notes(goal: np.ndarray) -> Iterator[tuple[int, int, int]]:
    """Every note of ``goal`` (T, K) bool: (key, first frame, frame after its last)."""
    for key in np.flatnonzero(goal.any(axis=0)).tolist():
        edges = np.diff(goal[:, key].astype(np.int8), prepend=0, append=0)
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for start, end in zip(starts.tolist(), ends.tolist(), strict=True):
            yield key, start, end


def error_masks(pressed: np.ndarray, goal: np.ndarray, window: int = 2) -> dict[str, np.ndarray]:
    """Every wrong key-frame of an episode by its class (module docstring).

    Args:
        pressed: (T, K) bool, key k sounding at the end of step t.
        goal: (T, K) bool, key k due at step t.
        window: frames (>= 1) within which a false key-frame counts as held from the note
            before it or early for the note after it.

    Returns:
        (T, K) bool masks, disjoint: ``late``, ``dropout``, ``never`` (missed key-frames;
        together ``goal & ~pressed``) and ``held``, ``early``, ``other`` (false key-frames;
        together ``pressed & ~goal``).
    Raises:
        ValueError: mismatched or non-boolean arrays, an empty episode, ``window`` < 1.
    """
    pressed, goal = _as_bool_pair(pressed, goal, ndim=2)
    if window < 1:
        raise ValueError(f"window must be >= 1 frame, not {window}")
    late, dropout, never = (np.zeros_like(goal) for _ in range(3))
    for key, start, end in _notes(goal):
        sounding = pressed[start:end, key]
        if not sounding.any():
            never[start:end, key] = True
            continue
        first = start + int(np.argmax(sounding))
        late[start:first, key] = True
        dropout[first:end, key] = ~sounding[first - start :]
    # False key-frames by the nearest due frames of the same key, before and after.
    false = pressed & ~goal
    due_before = np.zeros_like(goal)
    due_after = np.zeros_like(goal)
    for shift in range(1, window + 1):
        due_before[shift:] |= goal[:-shift]
        due_after[:-shift] |= goal[shift:]
    return {
        "late": late,
        "dropout": dropout,
        "never": never,
        "held": false & due_before,
        "early": false & ~due_before & due_after,
        "other": false & ~due_before & ~due_after,
    }


def f1_lost(
    pressed: np.ndarray, goal: np.ndarray, classes: Mapping[str, np.ndarray]
) -> dict[str, float]:
    """The episode F1 each class of wrong key-frames costs: how much higher the F1 (the mean
    over steps of each step's F1, the paper's metric) would be were that class alone put
    right, its missed key-frames sounding and its false ones silent.

    Key-frame shares weigh every key-frame alike; the metric does not: a key missed in a step
    with one key due costs that step's whole F1, one of a six-key chord about a tenth of it.
    This counts in the metric's unit, so the classes' figures say where F1 can be gained.

    Args:
        pressed: (T, K) bool, key k sounding at the end of step t.
        goal: (T, K) bool, key k due at step t.
        classes: name -> (T, K) bool mask; only its wrong key-frames count (a mask may be
            wider, e.g. every key-frame the plan leaves out, sounded or not).
    Returns:
        name -> F1 gained (>= 0) were the class put right.
    """
    pressed, goal = _as_bool_pair(pressed, goal, ndim=2)
    base = float(per_step_precision_recall_f1(pressed, goal)[2].mean())
    out = {}
    for name, mask in classes.items():
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != goal.shape:
            raise ValueError(f"class {name!r} has shape {mask.shape}, not {goal.shape}")
        fixed = (pressed | (mask & goal)) & ~(mask & ~goal)
        out[name] = float(per_step_precision_recall_f1(fixed, goal)[2].mean()) - base
    return out


#: A planner's (T, K) masks of the due key-frames its plan gives up, in an episode's
#: ``extra`` (:meth:`pianist.control.planner.IKPlanner.plan_arrays`), by their class name.
PLAN_CLASSES = {"plan_left_out": "left_out_keys", "plan_in_shift": "shift_keys"}


def f1_lost_by_kind(
    pressed: np.ndarray, goal: np.ndarray, plan: Mapping[str, np.ndarray] | None = None
) -> dict[str, float]:
    """``f1_lost_<class>``: the episode F1 each kind of error costs (:func:`f1_lost`): the
    missed key-frames by class (``never``, ``late``, ``dropout``), every false key-frame
    together (``false``), and given a planner's ``plan`` arrays (:data:`PLAN_CLASSES`), the
    keys its plan left out or let go for a shift (these overlap the others)."""
    masks = error_masks(pressed, goal)
    classes = {name: masks[name] for name in ("never", "late", "dropout")}
    classes["false"] = masks["held"] | masks["early"] | masks["other"]
    for name, key in PLAN_CLASSES.items():
        mask = (plan or {}).get(key)
        if mask is not None:
            classes[name] = mask
    return {f"f1_lost_{name}": value for name, value in f1_lost(pressed, goal, classes).items()}


def note_errors(pressed: np.ndarray, goal: np.ndarray, window: int = 2) -> dict[str, float]:
    """Count an episode's errors by kind (module docstring); the arguments and errors
    raised are :func:`error_masks`'s.

    Returns:
        ``notes``: how many notes the goal has; ``notes_late_share`` and
        ``notes_never_share``: of those, the share first sounding after their first frame and
        the share never sounding; ``onset_delay_mean_frames``: the mean frames from a note's
        start to its first sounding frame, over the notes that sound; ``lost_*_share``: missed
        key-frames by class, and ``false_*_share``: false key-frames by class, each as a share
        of the due key-frames (0 when nothing is due).
    """
    masks = error_masks(pressed, goal, window)
    goal = np.asarray(goal, dtype=bool)
    pressed = np.asarray(pressed, dtype=bool)
    notes = late_notes = never_notes = 0
    delays: list[int] = []  # frames from each sounding note's start to its first sound
    for key, start, end in _notes(goal):
        notes += 1
        sounding = pressed[start:end, key]
        if not sounding.any():
            never_notes += 1
            continue
        first = int(np.argmax(sounding))
        delays.append(first)
        late_notes += first > 0
    due = int(np.count_nonzero(goal))

    def share(name: str) -> float:
        return int(np.count_nonzero(masks[name])) / due if due else 0.0

    return {
        "notes": float(notes),
        "notes_late_share": late_notes / notes if notes else 0.0,
        "notes_never_share": never_notes / notes if notes else 0.0,
        "onset_delay_mean_frames": float(np.mean(delays)) if delays else 0.0,
        **{f"lost_{name}_share": share(name) for name in ("late", "dropout", "never")},
        **{f"false_{name}_share": share(name) for name in ("held", "early", "other")},
    }
