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
key-frame recall, and the false ones compare with them directly.
"""

from __future__ import annotations

import numpy as np

from pianist.eval.metrics import _as_bool_pair


def note_errors(pressed: np.ndarray, goal: np.ndarray, window: int = 2) -> dict[str, float]:
    """Count an episode's errors by kind (module docstring).

    Args:
        pressed: (T, K) bool, key k sounding at the end of step t.
        goal: (T, K) bool, key k due at step t.
        window: frames (>= 1) within which a false key-frame counts as held from the note
            before it or early for the note after it.

    Returns:
        ``notes``: how many notes the goal has; ``notes_late_share`` and
        ``notes_never_share``: of those, the share first sounding after their first frame and
        the share never sounding; ``onset_delay_mean_frames``: the mean frames from a note's
        start to its first sounding frame, over the notes that sound; ``lost_*_share``: missed
        key-frames by class, and ``false_*_share``: false key-frames by class, each as a share
        of the due key-frames (0 when nothing is due).
    Raises:
        ValueError: mismatched or non-boolean arrays, an empty episode, ``window`` < 1.
    """
    pressed, goal = _as_bool_pair(pressed, goal, ndim=2)
    if window < 1:
        raise ValueError(f"window must be >= 1 frame, not {window}")
    notes = late_notes = never_notes = 0
    lost = {"late": 0, "dropout": 0, "never": 0}
    delays: list[int] = []  # frames from each sounding note's start to its first sound
    for key in np.flatnonzero(goal.any(axis=0)).tolist():
        edges = np.diff(goal[:, key].astype(np.int8), prepend=0, append=0)
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # ends: exclusive
        notes += len(starts)
        for start, end in zip(starts.tolist(), ends.tolist(), strict=True):
            sounding = pressed[start:end, key]
            if not sounding.any():
                never_notes += 1
                lost["never"] += end - start
                continue
            first = int(np.argmax(sounding))
            delays.append(first)
            late_notes += first > 0
            lost["late"] += first
            lost["dropout"] += int(np.count_nonzero(~sounding[first:]))
    due = int(np.count_nonzero(goal))
    # False key-frames by the nearest due frames of the same key, before and after.
    false = pressed & ~goal
    due_before = np.zeros_like(goal)
    due_after = np.zeros_like(goal)
    for shift in range(1, window + 1):
        due_before[shift:] |= goal[:-shift]
        due_after[:-shift] |= goal[shift:]
    held = false & due_before
    early = false & ~due_before & due_after
    other = false & ~due_before & ~due_after

    def share(count: int) -> float:
        return count / due if due else 0.0

    return {
        "notes": float(notes),
        "notes_late_share": late_notes / notes if notes else 0.0,
        "notes_never_share": never_notes / notes if notes else 0.0,
        "onset_delay_mean_frames": float(np.mean(delays)) if delays else 0.0,
        **{f"lost_{name}_share": share(count) for name, count in lost.items()},
        "false_held_share": share(int(np.count_nonzero(held))),
        "false_early_share": share(int(np.count_nonzero(early))),
        "false_other_share": share(int(np.count_nonzero(other))),
    }
