"""How far the played loudness is from the score's: a controller on pieces with marked
dynamics.

For every song (default: the ``dynamics`` suite, :mod:`pianist.music.marked_dynamics`) and
physics preset, one episode of the controller (default: the planner as ``pianist play``
plays, seed 0), and from its ``metrics.json`` values:

- ``f1``: the notes;
- ``velocity mae``: the mean absolute difference, in MIDI velocity (1-127), between each
  performed note and the score's note it matches (same key, onset within the tolerance of
  :mod:`pianist.media.dynamics`);
- ``velocity rho``: the Spearman rank correlation of the two (1: the loud notes played
  loudest; NaN where the score's notes all have one velocity);
- ``realtime``: simulated time over wall time of the episode, the controller's set-up
  included (noisy on a shared machine).

Issue 55's targets are rho >= 0.8 and mae <= 12 per piece, the F1 within 0.005 of the same
controller without velocity control. The planner controls loudness with its pushed strikes
(on by default; ``--controller planner:push_below_velocity=0`` strikes every note at full
speed, the controller without velocity control; also ``refine:...`` and ``search:...``).

Run: ``python benchmarks/bench_dynamics.py [--suite dynamics | --songs a,b]
[--presets faithful,fast] [--controller SPEC] [--json out.json]``.
"""

from __future__ import annotations

import argparse
from functools import partial

from pianist.control.registry import ControllerSpec, parse_controller
from pianist.eval.session import play
from pianist.media.results import played_dynamics

from arguments import preset_list, song_list, song_table  # isort: skip  (beside this script)

COLUMNS = ("f1", "velocity mae", "velocity rho", "realtime")


def row(name: str, physics: str, spec: ControllerSpec) -> dict[str, float]:
    """The controller's F1 and loudness error on one song and preset."""
    result = play(name, spec.build(), physics=physics, seed=0)
    metrics = {**result.metrics, **played_dynamics(result)[3]}

    def number(key: str) -> float:
        value = metrics.get(key)
        return float("nan") if value is None else float(value)

    return {
        "f1": number("f1"),
        "velocity mae": number("velocity_mae"),
        "velocity rho": number("velocity_rank_correlation"),
        "realtime": number("realtime_factor"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="dynamics")
    parser.add_argument("--songs", default=None, help="comma-separated songs (instead of --suite)")
    parser.add_argument("--presets", default="faithful,fast")
    parser.add_argument("--controller", default="planner", help="a controller spec")
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args()
    names = song_list(parser, args.songs, args.suite)
    presets = preset_list(parser, args.presets)
    try:
        spec = parse_controller(args.controller)
    except ValueError as exc:
        parser.error(str(exc))
    settings = {"suite": None if args.songs else args.suite, "presets": presets}
    settings["controller"] = str(spec)
    song_table(names, presets, partial(row, spec=spec), COLUMNS, args.json, settings)


if __name__ == "__main__":
    main()
