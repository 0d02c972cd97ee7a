"""The falling-notes strip drawn under a video frame: the goal notes approaching a hit line.

The strip is a piano roll seen from the player, drawn with numpy alone. Its columns are the keys
along the keyboard (the same world span as the keyboard's front edge in the picture above, so a
note falls towards the key it belongs to), and its rows above the hit line are future times:
the row ``r`` pixels above the hit line at frame time t shows the goal at t + r / px_per_s.
So a goal note reaches the hit line exactly at the first frame whose time is in its first
control step, the frame in which the 3D key turns pale yellow or green. Under the hit line a
small keyboard repeats the keys' colours of that frame (green: sounding and due, red: sounding
and not due, pale yellow: due and silent).

Goal notes come from ``Episode.goal_keys``: one row per control step, so a note starts and
ends on a step's edge, and a re-struck note has its one-step gap (see
:func:`pianist.music.goal_frames`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pianist.sim import constants as C

BACKGROUND_RGB = (24, 26, 32)
OCTAVE_LINE_RGB = (44, 47, 56)  # a faint line at every C, to read the register
HIT_LINE_RGB = (235, 235, 235)
WHITE_NOTE_RGB = (86, 156, 245)  # notes of white keys
BLACK_NOTE_RGB = (42, 96, 190)  # notes of black keys: darker, as the keys are
KEY_GAP_RGB = (60, 60, 60)
#: Seconds of the future the strip shows above the hit line.
DEFAULT_LOOKAHEAD_S = 2.0
#: Fraction of the frame's height the strip takes.
STRIP_FRACTION = 0.3
_TOLERANCE = 1e-9  # a time on a step's edge counts in that step despite rounding


@dataclass(frozen=True)
class StripLayout:
    """Where things are in a strip of ``height`` x ``width`` pixels.

    Attributes:
        height, width: pixels.
        hit_row: the row showing the goal at the frame's own time.
        px_per_s: rows per second of the future above the hit line.
        column_key: (width,) key of each column, black keys taking the columns they cover and
            white keys the rest; -1 outside the keyboard.
        column_white_key: (width,) the white key under each column; -1 outside.
    """

    height: int
    width: int
    hit_row: int
    px_per_s: float
    column_key: np.ndarray
    column_white_key: np.ndarray

    @property
    def keyboard_rows(self) -> tuple[int, int]:
        """First and end row (exclusive) of the small keyboard under the hit line."""
        return self.hit_row + 2, self.height


def strip_height(frame_height: int) -> int:
    """The strip's height in pixels for a frame of ``frame_height``: even, so the picture
    above it keeps an even height too."""
    return max(16, 2 * round(frame_height * STRIP_FRACTION / 2))


def strip_layout(
    height: int,
    width: int,
    y_span_m: tuple[float, float],
    *,
    lookahead_s: float = DEFAULT_LOOKAHEAD_S,
) -> StripLayout:
    """Lay out a strip whose columns cover the keyboard from y_span_m[0] (column 0's left
    edge) to y_span_m[1] (the last column's right edge), in metres along the keyboard (key 0
    at -y); a decreasing span mirrors the strip.

    Args:
        height, width: pixels, height >= 16.
        y_span_m: world y at the strip's left and right edges.
        lookahead_s: seconds shown above the hit line, > 0.
    """
    if height < 16 or width < 1:
        raise ValueError(
            f"a falling-notes strip needs at least 16 x 1 pixels, not {height}x{width}"
        )
    if not lookahead_s > 0:
        raise ValueError(f"lookahead must be > 0 s, not {lookahead_s}")
    keyboard = max(6, round(height * 0.28))
    hit_row = height - keyboard - 2
    left, right = (float(v) for v in y_span_m)
    y = left + (np.arange(width) + 0.5) * (right - left) / width
    centres = C.key_centre_y()
    white = C.WHITE_KEYS
    nearest_white = white[np.argmin(np.abs(y[:, None] - centres[white][None]), axis=1)]
    inside = np.abs(y - centres[nearest_white]) <= C.WHITE_KEY_PITCH_M / 2
    column_white = np.where(inside, nearest_white, -1)
    black = C.BLACK_KEYS
    distance = np.abs(y[:, None] - centres[black][None])
    nearest_black = black[np.argmin(distance, axis=1)]
    on_black = distance.min(axis=1) <= C.BLACK_KEY_WIDTH_M / 2
    column_key = np.where(on_black, nearest_black, column_white)
    return StripLayout(
        height=height,
        width=width,
        hit_row=hit_row,
        px_per_s=hit_row / lookahead_s,
        column_key=column_key.astype(np.intp),
        column_white_key=column_white.astype(np.intp),
    )


def step_index(times: np.ndarray, control_timestep_s: float) -> np.ndarray:
    """The control step containing each time: floor(t / dt), a time on a step's edge (up to
    rounding) counting in the step it starts. (F,) ints, not clipped."""
    steps = np.asarray(times, dtype=np.float64) / control_timestep_s
    return np.floor(steps + _TOLERANCE).astype(np.intp)


def draw_strip(
    layout: StripLayout,
    time_s: float,
    goal_keys: np.ndarray,
    control_timestep_s: float,
    key_rgba: np.ndarray,
) -> np.ndarray:
    """The strip at one frame time.

    Args:
        layout: from :func:`strip_layout`.
        time_s: the frame's time, seconds from the episode's start.
        goal_keys: (T, 88) bool, keys due at each control step.
        control_timestep_s: seconds per step.
        key_rgba: (88, 3 or 4) floats in [0, 1], the keys' colours at this frame (as
            :func:`pianist.media.video.key_colours` gives them); alpha is ignored.
    Returns:
        (height, width, 3) uint8 RGB.
    """
    goal_keys = np.asarray(goal_keys, dtype=bool)
    out = np.empty((layout.height, layout.width, 3), dtype=np.uint8)
    out[:] = BACKGROUND_RGB
    keys = layout.column_key
    on_keyboard = keys >= 0
    is_c = on_keyboard & (layout.column_white_key % 12 == 3)  # key 3 is C1
    first_column_of_c = is_c & ~np.concatenate([[False], is_c[:-1]])
    out[: layout.hit_row + 1, first_column_of_c] = OCTAVE_LINE_RGB

    # Rows 0..hit_row: the goal at time_s + (hit_row - row) / px_per_s.
    rows = np.arange(layout.hit_row + 1)
    tau = time_s + (layout.hit_row - rows) / layout.px_per_s
    steps = step_index(tau, control_timestep_s)
    valid = (steps >= 0) & (steps < len(goal_keys))
    due = np.zeros((len(rows), C.NUM_KEYS), dtype=bool)
    due[valid] = goal_keys[steps[valid]]
    lit = due[:, np.where(on_keyboard, keys, 0)] & on_keyboard[None]
    # One background column between neighbouring white-key notes keeps them apart.
    edge = np.concatenate([[False], layout.column_white_key[1:] != layout.column_white_key[:-1]])
    lit &= ~(edge & ~C.BLACK_KEY_MASK[np.maximum(keys, 0)])[None]
    colour = np.where(
        C.BLACK_KEY_MASK[np.maximum(keys, 0)][:, None], BLACK_NOTE_RGB, WHITE_NOTE_RGB
    ).astype(np.uint8)
    region = out[: layout.hit_row + 1]
    region[lit] = np.broadcast_to(colour[None], region.shape)[lit]

    out[layout.hit_row + 1] = HIT_LINE_RGB
    # The small keyboard: black keys over the upper 60 %, white keys below.
    top, end = layout.keyboard_rows
    split = top + round((end - top) * 0.6)
    rgb = np.round(np.clip(np.asarray(key_rgba, dtype=np.float64)[:, :3], 0, 1) * 255)
    rgb = rgb.astype(np.uint8)
    upper = np.where(on_keyboard[:, None], rgb[np.maximum(keys, 0)], KEY_GAP_RGB)
    white_keys = layout.column_white_key
    lower = np.where((white_keys >= 0)[:, None], rgb[np.maximum(white_keys, 0)], KEY_GAP_RGB)
    lower[edge] = KEY_GAP_RGB
    upper[edge & ~C.BLACK_KEY_MASK[np.maximum(keys, 0)]] = KEY_GAP_RGB
    out[top:split] = upper[None]
    out[split:end] = lower[None]
    return out
