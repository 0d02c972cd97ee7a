"""The controllers' actions, bit for bit, against a recording made before the controller
layer was restructured (issue 53): the planner, refine, search and MPC on two debug songs and
the openings of two open-etude-12 pieces, fast physics. Since strikes are predicted in songs
whose velocities differ (``predict_strikes``, "dynamics" by default) the Maple Leaf Rag's
default cases (velocities 80 and 85) are recorded anew, and the cases with
``predict_strikes=never`` keep the actions recorded before it.

The recording is ``tests/data/controller_actions.npz``; ``python tests/test_controller_actions.py``
writes it again (only when the controllers are meant to play differently). Bit-for-bit holds
on a machine whose NumPy dispatches the same SIMD kernels as the recording's (the linear
algebra and elementwise maths may round differently elsewhere); on another the actions must
agree to ``1e-4``, and the message says which comparison was made.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

RECORDING = Path(__file__).parent / "data" / "controller_actions.npz"

#: (song, seconds of its opening played, controller spec)
CASES: tuple[tuple[str, float, str], ...] = (
    ("twinkle-twinkle", 4.0, "planner"),
    ("c-major-chords", 4.0, "planner"),
    ("chopin-mazurka-op6-no2", 4.0, "planner"),
    ("joplin-maple-leaf-rag", 4.0, "planner"),
    ("twinkle-twinkle", 2.0, "refine"),
    ("c-major-chords", 2.0, "refine"),
    ("chopin-mazurka-op6-no2", 2.0, "refine"),
    ("joplin-maple-leaf-rag", 2.0, "refine"),
    ("twinkle-twinkle", 2.0, "refine:open_loop=true,candidates=4"),
    ("joplin-maple-leaf-rag", 2.0, "refine:open_loop=true,candidates=4"),
    ("twinkle-twinkle", 3.0, "search"),
    ("c-major-chords", 3.0, "search"),
    ("chopin-mazurka-op6-no2", 3.0, "search"),
    ("joplin-maple-leaf-rag", 3.0, "search"),
    ("c-major-chords", 1.5, "search:refine,segment_steps=10,variants=plain+stiff-wrist"),
    ("twinkle-twinkle", 1.0, "mpc:num_samples=6,iterations=2"),
    ("c-major-chords", 1.0, "mpc:tenth,iterations=1"),
    ("chopin-mazurka-op6-no2", 1.0, "mpc:num_samples=6,iterations=2"),
    ("joplin-maple-leaf-rag", 1.0, "mpc:num_samples=6,iterations=2"),
    # Strikes with the planner's own command, as recorded before strikes were predicted.
    ("twinkle-twinkle", 4.0, "planner:predict_strikes=never"),
    ("c-major-chords", 4.0, "planner:predict_strikes=never"),
    ("chopin-mazurka-op6-no2", 4.0, "planner:predict_strikes=never"),
    ("joplin-maple-leaf-rag", 4.0, "planner:predict_strikes=never"),
    ("c-major-chords", 2.0, "refine:predict_strikes=never"),
    ("joplin-maple-leaf-rag", 2.0, "refine:predict_strikes=never"),
    ("twinkle-twinkle", 2.0, "refine:open_loop=true,candidates=4,predict_strikes=never"),
    ("chopin-mazurka-op6-no2", 3.0, "search:predict_strikes=never"),
    (
        "c-major-chords",
        1.5,
        "search:refine,segment_steps=10,variants=plain+stiff-wrist,predict_strikes=never",
    ),
)


def _key(song: str, seconds: float, spec: str) -> str:
    return f"{song}|{seconds}|{spec}"


def _cpu_fingerprint() -> str:
    """The SIMD features NumPy dispatches on, and the versions whose maths the actions use."""
    import mujoco

    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # older NumPy
        from numpy.core._multiarray_umath import __cpu_features__ as features  # type: ignore
    on = ",".join(sorted(name for name, present in features.items() if present))
    return f"numpy {np.__version__}; mujoco {mujoco.__version__}; {on}"


def _actions(song_name: str, seconds: float, spec: str) -> np.ndarray:
    from pianist.eval.session import play
    from pianist.music import load_song
    from pianist.music.transforms import window

    song = window(load_song(song_name), 0.0, seconds)
    result = play(song, _controller(spec), physics="fast", seed=0)
    return result.episode.actions


def _controller(spec: str):  # noqa: ANN202 - whatever the controller layer makes of a spec
    try:
        from pianist.control.registry import parse_controller
    except ImportError:  # the recording was made before the registry existed
        from pianist.control import make_controller

        return make_controller(spec)
    return parse_controller(spec).build()


@pytest.fixture(scope="module")
def recording() -> dict[str, np.ndarray]:
    with np.load(RECORDING, allow_pickle=False) as data:
        return {name: data[name] for name in data.files}


@pytest.mark.parametrize(("song", "seconds", "spec"), CASES)
def test_actions_match_the_recording(recording, song, seconds, spec):
    recorded = recording[_key(song, seconds, spec)]
    played = _actions(song, seconds, spec)
    assert played.shape == recorded.shape
    same_machine = str(recording["fingerprint"]) == _cpu_fingerprint()
    if same_machine:
        difference = np.flatnonzero(np.any(played != recorded, axis=1))
        assert difference.size == 0, (
            f"{spec} on {song}: actions differ bit for bit from step {difference[:1]} "
            f"(max {np.max(np.abs(played - recorded)):.3g})"
        )
    else:
        np.testing.assert_allclose(
            played,
            recorded,
            atol=1e-4,
            err_msg=f"{spec} on {song} (another CPU than the recording's: compared to 1e-4)",
        )


def record() -> None:
    """Write the recording from the controllers as they play now."""
    arrays = {"fingerprint": np.array(_cpu_fingerprint())}
    for song, seconds, spec in CASES:
        arrays[_key(song, seconds, spec)] = _actions(song, seconds, spec)
        print(f"{spec:>60} on {song}: {arrays[_key(song, seconds, spec)].shape}")
    RECORDING.parent.mkdir(exist_ok=True)
    temporary = RECORDING.with_suffix(".tmp.npz")
    np.savez_compressed(temporary, **arrays)
    temporary.replace(RECORDING)


if __name__ == "__main__":
    sys.exit(record())
