"""Physical constants of the piano and the hands, with units in their names.

Frame: x runs along the key length (the player sits at +x), y along the keyboard (low keys at
-y), z up. Key 0 is A0 (MIDI 21), key 87 is C8 (MIDI 108).
"""

from __future__ import annotations

import math

import numpy as np

# --- Keyboard -------------------------------------------------------------------------------

NUM_KEYS = 88
NUM_WHITE_KEYS = 52
NUM_BLACK_KEYS = 36
LOWEST_MIDI_PITCH = 21  # A0
HIGHEST_MIDI_PITCH = LOWEST_MIDI_PITCH + NUM_KEYS - 1  # C8

# Counting from A (index 0), the black keys of an octave are A#, C#, D#, F#, G#.
BLACK_KEY_OFFSETS_IN_OCTAVE = frozenset({1, 4, 6, 9, 11})

WHITE_KEY_LENGTH_M = 0.15
WHITE_KEY_WIDTH_M = 0.0225
WHITE_KEY_HEIGHT_M = 0.0225
WHITE_KEY_GAP_M = 0.001
WHITE_KEY_PITCH_M = WHITE_KEY_WIDTH_M + WHITE_KEY_GAP_M  # centre-to-centre spacing
KEYBOARD_LENGTH_M = NUM_WHITE_KEYS * WHITE_KEY_WIDTH_M + (NUM_WHITE_KEYS - 1) * WHITE_KEY_GAP_M
WHITE_KEY_MASS_KG = 0.04

BLACK_KEY_LENGTH_M = 0.09
BLACK_KEY_WIDTH_M = 0.01
BLACK_KEY_HEIGHT_M = 0.018
# A black key's top sits 12.5 mm above a white key's top.
BLACK_KEY_TOP_ABOVE_WHITE_M = 0.0125
BLACK_KEY_MASS_KG = 0.02

# Back ends of all keys are aligned, so a shorter black key's centre sits further back (-x).
WHITE_KEY_CENTRE_X_M = 0.0
BLACK_KEY_CENTRE_X_M = -(WHITE_KEY_LENGTH_M - BLACK_KEY_LENGTH_M) / 2
WHITE_KEY_CENTRE_Z_M = WHITE_KEY_HEIGHT_M / 2
BLACK_KEY_CENTRE_Z_M = WHITE_KEY_HEIGHT_M + BLACK_KEY_TOP_ABOVE_WHITE_M - BLACK_KEY_HEIGHT_M / 2

# The hinge sits at the back end of the key, so a front-end travel d gives theta = atan(d / l).
WHITE_KEY_TRAVEL_M = 0.01
BLACK_KEY_TRAVEL_M = 0.008
WHITE_KEY_MAX_ANGLE_RAD = math.atan(WHITE_KEY_TRAVEL_M / WHITE_KEY_LENGTH_M)
BLACK_KEY_MAX_ANGLE_RAD = math.atan(BLACK_KEY_TRAVEL_M / BLACK_KEY_LENGTH_M)

# A negative spring reference preloads every key up against its stop.
KEY_SPRING_STIFFNESS_NM_PER_RAD = 2.0
KEY_SPRING_REF_RAD = math.radians(-1.0)
KEY_DAMPING_NMS_PER_RAD = 0.05
KEY_ARMATURE_KGM2 = 0.001
KEY_SOLREF = (0.01, 1.0)

# A key sounds once it is within half a degree of the bottom of its travel.
KEY_ACTIVATION_THRESHOLD_RAD = math.radians(0.5)

# Fraction of the half-length towards the player where a fingertip should strike the key.
KEY_TARGET_FORWARD_FRACTION = 0.35

BASE_SIZE_M = (0.1, KEYBOARD_LENGTH_M, 0.04)  # full extents x, y, z
BASE_CENTRE_M = (-0.127, 0.0, 0.02)

# The sustain pedal is an action and a state, not a body: active when its value is >= 0.5.
SUSTAIN_THRESHOLD = 0.5


def is_black_key(key: int) -> bool:
    """Whether piano key ``key`` (0 = A0 .. 87 = C8) is black."""
    return key % 12 in BLACK_KEY_OFFSETS_IN_OCTAVE


BLACK_KEY_MASK = np.array([is_black_key(k) for k in range(NUM_KEYS)], dtype=bool)
BLACK_KEYS = np.flatnonzero(BLACK_KEY_MASK)
WHITE_KEYS = np.flatnonzero(~BLACK_KEY_MASK)
KEY_MAX_ANGLE_RAD = np.where(BLACK_KEY_MASK, BLACK_KEY_MAX_ANGLE_RAD, WHITE_KEY_MAX_ANGLE_RAD)


def white_key_y(white_index: int | np.ndarray) -> float | np.ndarray:
    """Centre y (m) of the ``white_index``-th white key (0 = A0 .. 51 = C8)."""
    return -KEYBOARD_LENGTH_M / 2 + WHITE_KEY_WIDTH_M / 2 + white_index * WHITE_KEY_PITCH_M


def key_centre_y() -> np.ndarray:
    """Centre y (m) of each of the 88 keys, shape (88,).

    A black key sits over the gap between its two white neighbours.
    """
    white_rank = np.cumsum(~BLACK_KEY_MASK) - 1  # ordinal of the white key at or below each key
    y = np.asarray(white_key_y(white_rank), dtype=float)
    return np.where(BLACK_KEY_MASK, y + WHITE_KEY_PITCH_M / 2, y)


# --- Hands ----------------------------------------------------------------------------------

HAND_SIDES = ("right", "left")
HAND_PREFIX = {"right": "rh/", "left": "lh/"}  # name prefix of every element of a hand
# The right hand sits at +y: seen from the player (at +x, facing -x), +y is on the right.
FOREARM_ROOT_POS_M = {"right": (0.4, 0.15, 0.13), "left": (0.4, -0.15, 0.13)}
FINGER_NAMES = ("th", "ff", "mf", "rf", "lf")  # thumb, index, middle, ring, little
FINGERTIP_SITE_OFFSET_M = {"th": 0.0275, "ff": 0.026, "mf": 0.026, "rf": 0.026, "lf": 0.026}

# Forearm slides: along the keyboard (reach every key) and into the keys (-x).
FOREARM_SLIDE_KP = 300.0
FOREARM_INTO_KEYS_RANGE_M = (0.0, 0.06)
FOREARM_TZ_RANGE_M = (-0.04, 0.0)
FOREARM_TZ_KP = 1000.0
FOREARM_ROLL_RANGE_RAD = (-0.25, 0.25)
FOREARM_PITCH_RANGE_RAD = (0.0, 0.15)
FOREARM_YAW_RANGE_RAD = (-0.25, 0.25)
FOREARM_ROTATION_KP = 50.0

# The paper's reduced action space: these joints go, and the thumb's THJ2 range narrows.
REDUCED_REMOVED_JOINTS = ("THJ5", "THJ1", "LFJ5")
REDUCED_THJ2_RANGE_RAD = (0.0, 0.698)

# Primitive fingertip collision: a capsule along the distal phalanx instead of the mesh.
FINGERTIP_CAPSULE_RADIUS_M = 0.0095
FINGERTIP_CAPSULE_HALF_LENGTH_M = 0.0085
FINGERTIP_CAPSULE_CENTRE_M = 0.0135

# --- Physics --------------------------------------------------------------------------------

PHYSICS_TIMESTEP_S = 0.005
CONTROL_TIMESTEP_S = 0.05
