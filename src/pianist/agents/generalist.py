"""The generalist shipped with the package: one policy for any song, trained on none of them.

``pianist play SONG --controller generalist`` plays with it right after install, in NumPy,
with no training at play time: a :class:`pianist.agents.fingertip.FingertipPolicy` (an MLP
that, per hand and step, says what each finger does, from the next second of the song,
fingered for this robot by the planner's whole-piece plan at reset, and the hand's state),
played through the planner's execution stages (the slide's servo along that plan's path,
fingertip targets, inverse kinematics). Stored in
``pianist/agents/data/generalist/``. It was trained by DAgger with the IK planner as the
expert on Bach chorales of the music21 corpus cut into segments and on generated etudes;
``open-etude-12`` and the debug songs were held out. How to train it again, and what it
scores: ``docs/generalist.md``.
"""

from __future__ import annotations

from pathlib import Path

from pianist.agents.fingertip.controller import CONFIG_FILE, FingertipController, Forearm

#: The shipped policy's folder (``fingertip.json``, ``weights.npz``).
GENERALIST_DIR = Path(__file__).resolve().parent / "data" / "generalist"


def generalist_controller(forearm: Forearm | None = None) -> FingertipController:
    """The shipped generalist as a controller (``--controller generalist``); ``forearm``:
    where its forearms go (:data:`~pianist.agents.fingertip.controller.Forearm`; None: along
    the plan's path).

    Raises:
        FileNotFoundError: the package was installed without its weights.
    """
    if not (GENERALIST_DIR / CONFIG_FILE).is_file():
        raise FileNotFoundError(
            f"the generalist's weights are missing from {GENERALIST_DIR}; reinstall pianist"
        )
    return FingertipController(GENERALIST_DIR, forearm=forearm)
