"""The generalist shipped with the package: one behaviour-cloning policy for any song.

``pianist play SONG --controller generalist`` plays with it right after install, in NumPy,
with no training and no planner at play time: a :class:`pianist.agents.bc.BCPolicy` (an MLP on
the environment's state and goal) stored in ``pianist/agents/data/generalist/``. It was trained
by DAgger with the IK planner as the expert on Bach chorales of the music21 corpus cut into
segments; ``open-etude-12`` and the debug songs were held out. How to train it again, and what
it scores on the held-out pieces: ``docs/generalist.md``.
"""

from __future__ import annotations

from pathlib import Path

from pianist.agents.bc import CONFIG_FILE, BCController

#: The shipped policy's folder (``bc.json``, ``weights.npz``).
GENERALIST_DIR = Path(__file__).resolve().parent / "data" / "generalist"


def generalist_controller() -> BCController:
    """The shipped generalist as a controller (``--controller generalist``).

    Raises:
        FileNotFoundError: the package was installed without its weights.
    """
    if not (GENERALIST_DIR / CONFIG_FILE).is_file():
        raise FileNotFoundError(
            f"the generalist's weights are missing from {GENERALIST_DIR}; reinstall pianist"
        )
    return BCController(GENERALIST_DIR)
