"""Static pictures of an episode: a piano roll of goal versus performance, and its rewards."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.files import atomic_path
from pianist.media.errors import MediaError

if TYPE_CHECKING:
    from pianist.eval import Episode

LOWEST_PITCH = 21  # MIDI pitch of key 0 (A0)
NUM_KEYS = 88
KEY_MARGIN = 3  # keys shown beyond the lowest and highest key used

GOAL_COLOUR = "#c9d6e8"
CORRECT_COLOUR = "#2ca02c"
WRONG_COLOUR = "#d62728"
MISSED_COLOUR = "#ff7f0e"
PEDAL_COLOUR = "#555555"
HAND_SPAN_COLOURS = {"right": "#1f77b4", "left": "#9467bd"}


def pianoroll_counts(episode: Episode) -> dict[str, int]:
    """Key-step cells of the episode by outcome.

    Returns:
        ``correct`` (sounding and due), ``wrong`` (sounding, not due) and ``missed`` (due, not
        sounding): numbers of (step, key) pairs over the episode's T steps and 88 keys.
    """
    active = np.asarray(episode.active_keys, dtype=bool)
    goal = np.asarray(episode.goal_keys, dtype=bool)
    if active.shape != goal.shape or active.ndim != 2 or active.shape[1] != NUM_KEYS:
        raise MediaError(
            f"active_keys {active.shape} and goal_keys {goal.shape} must both be (T, {NUM_KEYS})"
        )
    return {
        "correct": int(np.count_nonzero(active & goal)),
        "wrong": int(np.count_nonzero(active & ~goal)),
        "missed": int(np.count_nonzero(~active & goal)),
    }


def plot_pianoroll(
    episode: Episode,
    path: str | os.PathLike[str],
    title: str = "",
    *,
    weights: Mapping[str, float] | None = None,
    size_in: tuple[float, float] = (12.0, 7.0),
    dpi: int = 100,
) -> dict[str, int]:
    """Draw the goal and the performance of an episode as a piano roll, over its rewards.

    Top panel: time (s) across, keys up the side (the range used, plus a few). The goal is
    drawn as light boxes; on top, key-steps played and due are green, played but not due red,
    due but not played hatched orange outlines. When the goal or the performance uses the
    sustain pedal, a lane under the keys shows it the same way. Bottom panel: every reward term
    and the total reward of each step. Step t covers [t dt, (t + 1) dt). Raw terms differ in
    scale by orders of magnitude (energy is a power in W), so the reward axis turns symmetric-log
    when any value exceeds 2 in magnitude.

    Args:
        episode: the record (``active_keys``, ``goal_keys``, ``sustain``, ``goal_sustain``,
            ``rewards``, ``reward_terms``, ``control_timestep_s``).
        path: the PNG file to write, atomically; its folder must exist.
        title: figure title.
        weights: the reward weights (e.g. ``env.config.rewards.as_dict()``) to plot each term's
            weighted contribution to the total instead of its raw value.
        size_in: (width, height) in inches.
        dpi: pixels per inch.
    Returns:
        The counts of :func:`pianoroll_counts`.
    Raises:
        MediaError: an empty or inconsistent episode, or the file cannot be written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    counts = pianoroll_counts(episode)
    active = np.asarray(episode.active_keys, dtype=bool)
    goal = np.asarray(episode.goal_keys, dtype=bool)
    steps = len(goal)
    if steps == 0:
        raise MediaError("the episode has no steps to plot")
    dt = float(episode.control_timestep_s)
    sustain = np.asarray(episode.sustain, dtype=bool).reshape(-1)
    goal_sustain = np.asarray(episode.goal_sustain, dtype=bool).reshape(-1)
    if sustain.shape != (steps,) or goal_sustain.shape != (steps,):
        raise MediaError(f"sustain and goal_sustain must have shape ({steps},)")

    # Draw only the (Agg, in-memory) figure: no pyplot, so no global backend state is touched.
    fig = Figure(figsize=size_in, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    roll, rewards = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))

    used = np.flatnonzero(active.any(axis=0) | goal.any(axis=0))
    low, high = (int(used[0]), int(used[-1])) if used.size else (39 - 6, 39 + 6)  # around C4
    low, high = max(low - KEY_MARGIN, 0), min(high + KEY_MARGIN, NUM_KEYS - 1)
    lanes = [(key, active[:, key], goal[:, key]) for key in range(low, high + 1)]
    show_pedal = bool(sustain.any() or goal_sustain.any())
    pedal_lane = low - 2
    if show_pedal:
        lanes.append((pedal_lane, sustain, goal_sustain))
    for y, played, due in lanes:
        box = (y - 0.4, 0.8)
        roll.broken_barh(_runs(due, dt), box, facecolor=GOAL_COLOUR, edgecolor="none")
        roll.broken_barh(_runs(played & due, dt), box, facecolor=CORRECT_COLOUR)
        roll.broken_barh(_runs(played & ~due, dt), box, facecolor=WRONG_COLOUR)
        roll.broken_barh(
            _runs(~played & due, dt),
            box,
            facecolor="none",
            edgecolor=MISSED_COLOUR,
            hatch="///",
            linewidth=1.0,
        )
    spans = episode.extra.get("hand_key_span") if hasattr(episode, "extra") else None
    poses = episode.extra.get("hand_pose") if hasattr(episode, "extra") else None
    span_handles = []
    turned_handle = False
    if spans is not None and len(spans) == steps:
        # The planner's hand positions: the keys each hand's fingers reach, step by step.
        edges = np.arange(steps + 1) * dt
        sides = episode.extra.get("hand_sides", ("right", "left"))
        for h, side in enumerate(list(sides)[: spans.shape[1]]):
            colour = HAND_SPAN_COLOURS.get(str(side), PEDAL_COLOUR)
            lo = np.r_[spans[:, h, 0], spans[-1, h, 0]]
            hi = np.r_[spans[:, h, 1], spans[-1, h, 1]]
            roll.fill_between(edges, lo, hi, step="post", color=colour, alpha=0.12, lw=0)
            span_handles.append(Patch(facecolor=colour, alpha=0.3, label=f"{side} hand reach"))
            if poses is not None and poses.shape == (steps, spans.shape[1]) and poses[:, h].any():
                # Where the plan turns the wrist (a reach pose), the band is hatched.
                turned = np.r_[poses[:, h] > 0, poses[-1, h] > 0]
                roll.fill_between(
                    edges,
                    lo,
                    hi,
                    where=turned,
                    step="post",
                    facecolor="none",
                    edgecolor=colour,
                    hatch="..",
                    alpha=0.5,
                    lw=0,
                )
                turned_handle = True
    if turned_handle:
        span_handles.append(Patch(facecolor="none", hatch="..", label="wrist turned"))
    _key_axis(roll, low, high, pedal_lane if show_pedal else None)
    roll.set_xlim(0.0, steps * dt)
    roll.set_ylabel("key")
    roll.set_title(
        f"correct {counts['correct']}, wrong {counts['wrong']}, missed {counts['missed']} "
        "key-steps",
        fontsize="medium",
    )
    roll.legend(
        handles=[
            Patch(facecolor=GOAL_COLOUR, label="goal"),
            Patch(facecolor=CORRECT_COLOUR, label="correct"),
            Patch(facecolor=WRONG_COLOUR, label="wrong"),
            Patch(facecolor="none", edgecolor=MISSED_COLOUR, hatch="///", label="missed"),
            *span_handles,
        ],
        loc="upper left",
        bbox_to_anchor=(1.0, 1.0),
    )

    _plot_rewards(rewards, episode, steps, dt, weights)
    if title:
        fig.suptitle(title)

    with atomic_path(path, suffix=".png", error=MediaError) as tmp:
        fig.savefig(tmp, format="png")
    return counts


def plot_velocities(
    performed: Sequence[int],
    score: Sequence[int],
    path: str | os.PathLike[str],
    title: str = "",
    *,
    size_in: tuple[float, float] = (5.0, 5.0),
    dpi: int = 100,
) -> None:
    """Draw each matched note's performed MIDI velocity against the score's (the diagonal:
    played as written), with their mean absolute difference and rank correlation.

    Raises:
        MediaError: lengths that differ, or the file cannot be written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from pianist.media.dynamics import rank_correlation

    if len(performed) != len(score):
        raise MediaError(f"{len(performed)} performed velocities against {len(score)} scored")
    fig = Figure(figsize=size_in, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0, 127], [0, 127], color="#999", linewidth=1, label="as written")
    ax.scatter(score, performed, s=14, alpha=0.6, color="#2a7ab0", label="matched notes")
    ax.set(xlim=(0, 127), ylim=(0, 127), xlabel="score velocity", ylabel="performed velocity")
    ax.set_aspect("equal")
    ax.legend(loc="upper left", fontsize="small")
    rho = rank_correlation(performed, score)
    mae = float(np.mean(np.abs(np.subtract(performed, score)))) if len(score) else float("nan")
    rho_text = "n/a" if rho is None else f"{rho:.2f}"
    ax.set_title(
        f"{title}\n{len(score)} notes, mean |difference| {mae:.1f}, rank correlation {rho_text}"
        if title
        else f"{len(score)} notes, mean |difference| {mae:.1f}, rank correlation {rho_text}",
        fontsize="small",
    )
    with atomic_path(path, suffix=".png", error=MediaError) as tmp:
        fig.savefig(tmp, format="png")


# --------------------------------------------------------------------------------- internals


def _runs(mask: np.ndarray, dt: float) -> list[tuple[float, float]]:
    """(start s, length s) of every run of True steps in ``mask`` (T,)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    return [(s * dt, (e - s) * dt) for s, e in zip(starts.tolist(), ends.tolist(), strict=True)]


def _key_axis(ax: Any, low: int, high: int, pedal_lane: int | None) -> None:
    """Label the keys with pitch names: every key in a short range, else the Cs."""
    from pianist.music import pitch_to_name

    keys = list(range(low, high + 1))
    if len(keys) > 15:
        keys = [k for k in keys if (LOWEST_PITCH + k) % 12 == 0] or [low, high]
    ticks = keys + ([pedal_lane] if pedal_lane is not None else [])
    labels = [pitch_to_name(LOWEST_PITCH + k) for k in keys]
    labels += ["pedal"] if pedal_lane is not None else []
    ax.set_yticks(ticks, labels)
    bottom = (pedal_lane if pedal_lane is not None else low) - 0.6
    ax.set_ylim(bottom, high + 0.6)
    # Light lines between octaves help read the pitch of a box far from its label.
    for k in range(low, high + 1):
        if (LOWEST_PITCH + k) % 12 == 0:
            ax.axhline(k - 0.5, color="#dddddd", linewidth=0.6, zorder=0)


def _plot_rewards(
    ax: Any, episode: Episode, steps: int, dt: float, weights: Mapping[str, float] | None
) -> None:
    """Step plot of each (weighted) reward term and of the total reward."""
    edges = np.arange(steps + 1) * dt

    peak = 0.0

    def step_line(values: Any, **style: Any) -> None:
        nonlocal peak
        values = np.asarray(values, dtype=np.float64).reshape(-1)
        if values.shape != (steps,):
            raise MediaError(f"reward series must have shape ({steps},), not {values.shape}")
        finite = values[np.isfinite(values)]
        peak = max(peak, float(np.abs(finite).max(initial=0.0)))
        # Repeat the last value so the final step is drawn over its whole interval.
        ax.step(edges, np.append(values, values[-1]), where="post", **style)

    for name, series in episode.reward_terms.items():
        values = np.asarray(series, dtype=np.float64).reshape(-1)
        if values.shape == (steps,) and not values.any():
            continue  # a term that is 0 throughout (velocity without the score's loudness)
        if weights is None:
            step_line(values, label=name, linewidth=1.0)
        elif name in weights:
            weight = float(weights[name])
            step_line(np.asarray(values) * weight, label=f"{name} × {weight:g}", linewidth=1.0)
    step_line(episode.rewards, label="total", color="black", linewidth=1.6)
    if peak > 2.0:
        ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("reward")
    ax.grid(True, color="#eeeeee")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
