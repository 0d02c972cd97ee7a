"""What each entry of ``metrics.json`` means, in plain words, and a result in one sentence:
for the report page (:mod:`pianist.media.report`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

#: Entry -> what it means. Shares of "due key-steps" count a key due at one control step once.
METRIC_TEXT: dict[str, str] = {
    "precision": "Of the keys sounding, the share that were due (the paper's metric: the mean "
    "over control steps).",
    "recall": "Of the keys due, the share that sounded (mean over control steps).",
    "f1": "The paper's score: the balance of precision and recall, per control step, averaged.",
    "song_precision": "Precision from the song's first note on (a lead-in's silent steps left "
    "out).",
    "song_recall": "Recall from the song's first note on.",
    "song_f1": "F1 from the song's first note on.",
    "sustain_precision": "Precision of the sustain pedal (down when the score has it down).",
    "sustain_recall": "Recall of the sustain pedal.",
    "sustain_f1": "F1 of the sustain pedal.",
    "steps": "Control steps of the episode (20 a second).",
    "seconds": "Seconds of music simulated.",
    "return": "The sum of the environment's rewards over the episode.",
    "notes": "Notes in the score (of the excerpt played).",
    "notes_late_share": "Share of the notes whose key first sounded after the note began.",
    "notes_never_share": "Share of the notes whose key never sounded.",
    "onset_delay_mean_frames": "How late a note's key first sounded, on average, in control "
    "steps of 0.05 s.",
    "lost_late_share": "Share of the due key-steps missed because a note started late.",
    "lost_dropout_share": "Share of the due key-steps missed after the note had sounded (the "
    "key came up too soon).",
    "lost_never_share": "Share of the due key-steps in notes that never sounded.",
    "false_held_share": "Keys sounding after their note ended (held on), in due key-steps.",
    "false_early_share": "Keys sounding just before their note began, in due key-steps.",
    "false_other_share": "Other keys sounding that were not due, in due key-steps.",
    "reach_ceiling_recall": "The most recall any controller can reach with these hands' "
    "reach, each moment on its own.",
    "reach_ceiling_f1": "The most F1 any controller can reach with these hands' reach, each "
    "moment on its own: what these hands allow.",
    "plan_left_out_share": "Share of the due key-steps the planner's plan gives no finger (a "
    "chord wider than the hand).",
    "plan_in_shift_share": "Share of the due key-steps the plan lets go while a hand moves.",
    "plan_f1": "The F1 of sounding exactly what the plan leaves playable: the most its "
    "execution can score.",
    "song": "The song played.",
    "controller": "The controller, as --controller names it.",
    "controller_options": "The controller's settings.",
    "physics": "The physics preset: faithful (the paper's simulation) or fast.",
    "fingering": "How the song was fingered (auto: the song's own, the rest estimated).",
    "seed": "The episode's seed.",
    "env_options": "The environment's options as played (the controller's included).",
    "wall_seconds": "Seconds the episode took on this machine, planning included.",
    "realtime_factor": "Seconds of music played per second of wall time (above 1: faster "
    "than real time).",
    "velocity_mae": "How far the played loudness is from the score's: the mean absolute "
    "difference of MIDI velocities (0-127) over the matched notes.",
    "velocity_matched_notes": "Notes matched between the performance and the score for the "
    "loudness.",
    "velocity_mean": "The mean MIDI velocity the performance played.",
    "velocity_rank_correlation": "Whether the performance is louder where the score is "
    "louder: Spearman's rank correlation of the matched notes' velocities (1: the same order, "
    "0: unrelated; none when either has one velocity throughout).",
    "as_written": "Whether a score was read as written (no repeats, ornaments or fermatas).",
    "excerpt_start_s": "Where the excerpt played starts in the song (s).",
    "excerpt_seconds": "How long the excerpt played is (s).",
    "refined_share": "Share of the steps where looking ahead changed the planner's action.",
    "refine_seconds_per_step": "Wall seconds the refiner spent looking ahead per step.",
    "lookahead_steps_per_step": "Steps simulated ahead per step played.",
    "search_seconds_per_segment": "Wall seconds the search spent per segment.",
    "preset": "The training preset of the run played.",
    "run": "The training run played.",
    "checkpoint_step": "The environment step of the checkpoint played.",
    "trained_physics": "The physics preset the run was trained in.",
    "f1_lost_never": "F1 lost to notes that never sounded: what F1 would gain were they "
    "alone put right.",
    "f1_lost_late": "F1 lost to notes that sounded late.",
    "f1_lost_dropout": "F1 lost to keys that came up too soon.",
    "f1_lost_false": "F1 lost to keys sounding that were not due.",
    "f1_lost_plan_left_out": "F1 lost to the keys the plan gives no finger (they overlap the "
    "kinds above).",
    "f1_lost_plan_in_shift": "F1 lost to the keys the plan lets go while a hand moves (they "
    "overlap the kinds above).",
    "mpc_steps": "Control steps the MPC planned.",
    "mpc_iterations": "Planning iterations in all (the iterations option per step, times the "
    "steps).",
    "mpc_plan_seconds": "Wall seconds the MPC spent planning.",
    "mpc_ms_per_step": "Milliseconds of planning per control step.",
    "mpc_realtime_factor": "Seconds of music per second of planning (the paper's budget: 0.1).",
    "mpc_rollout_steps_per_s": "Simulated rollout steps per second of planning.",
    "mpc_rollout_fraction": "Share of the planning time spent simulating rollouts.",
}

#: Entry prefix -> what entries beginning with it mean ({} is the rest of the name).
METRIC_PREFIX_TEXT: dict[str, str] = {
    "rehearsed_f1_": "The F1 the planner's candidate plan '{}' scored when the planner "
    "played it through alone before the episode; it plays the best of them (a controller "
    "built on the planner, such as refine or search, then changes what is played).",
    "search_share_": "Share of the steps the search played with the '{}' settings.",
    "plan_": "The plan's {}.",
}


def metric_text(name: str) -> str:
    """What the ``metrics.json`` entry ``name`` means, in plain words."""
    if name in METRIC_TEXT:
        return METRIC_TEXT[name]
    for prefix, text in METRIC_PREFIX_TEXT.items():
        if name.startswith(prefix):
            return text.format(name.removeprefix(prefix).replace("_", " "))
    return "Recorded by the command or the controller."


def in_words(metrics: Mapping[str, Any], missed: int | None, wrong: int | None) -> str:
    """The result in one sentence: ``"missed 12 of 190 notes, 3 wrong; F1 0.82 of the 0.96
    these hands allow"``. ``missed`` and ``wrong``: counts from the key record (None: not
    recorded)."""
    notes = metrics.get("notes")
    parts = []
    if missed is not None and isinstance(notes, int | float) and math.isfinite(notes):
        parts.append(f"missed {missed} of {int(notes)} notes")
    if wrong is not None:
        parts.append(f"{wrong} wrong")
    text = ", ".join(parts)
    f1, ceiling = metrics.get("f1"), metrics.get("reach_ceiling_f1")
    if isinstance(f1, float):
        allowed = f" of the {ceiling:.2f} these hands allow" if isinstance(ceiling, float) else ""
        text += ("; " if text else "") + f"F1 {f1:.2f}{allowed}"
    return text[:1].upper() + text[1:] if text else "No metrics recorded."
