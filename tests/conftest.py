"""Test-wide settings."""

import os

# Offscreen rendering on a machine without a display; mujoco reads this at its first import.
os.environ.setdefault("MUJOCO_GL", "egl")
