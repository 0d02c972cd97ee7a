"""Controllers from their specs, the strings of ``--controller``: the one resolver that the
command line, sweeps and datasets share.

``policy:RUN_DIR`` (a trained agent, or a practised piece: a ``--preset practice`` run),
``bc:DIR`` (a behaviour-cloning policy), ``generalist`` (the fingertip policy shipped with
the package; ``generalist:forearm=policy``: its forearms go to its own slide targets
instead of along the plan's path), or anything
:func:`pianist.control.make_controller` takes (``planner``, ``refine[:...]``, ``search[:...]``,
``mpc[:...]``, ``random``, ``zero``, ``replay:ACTIONS.npy``).
"""

from __future__ import annotations

from typing import Any

#: Every kind of spec, for the error that names them.
KINDS = (
    "planner, refine[:FIELD=VALUE,...], search[:refine,FIELD=VALUE,...], mpc[:PRESET,...], "
    "generalist[:forearm=plan|policy], policy:RUN_DIR, bc:DIR, random, zero or "
    "replay:ACTIONS.npy"
)


def controller_from_spec(spec: str) -> Any:
    """The controller a ``--controller`` spec names (see the module docstring).

    Raises:
        ValueError: an unknown spec; FileNotFoundError: a run or policy folder that is missing.
    """
    for prefix, what in (("policy:", "RUN_DIR"), ("bc:", "DIR"), ("replay:", "ACTIONS.npy")):
        if spec == prefix:
            raise ValueError(f"--controller {prefix} needs a path: {prefix}{what}")
    if spec.startswith("policy:"):
        from pianist.agents.policy import PolicyController
        from pianist.agents.practice import CorrectedPlanner, is_practice_run

        run_dir = spec.removeprefix("policy:")
        if is_practice_run(run_dir):
            return CorrectedPlanner.load(run_dir)
        return PolicyController(run_dir)
    if spec == "generalist" or spec.startswith("generalist:"):
        from pianist.agents.generalist import generalist_controller

        option = spec.removeprefix("generalist").removeprefix(":")
        if option not in ("", "forearm=plan", "forearm=policy"):
            raise ValueError(
                f"unknown generalist option {option!r}: use forearm=plan or forearm=policy"
            )
        return generalist_controller(option.removeprefix("forearm=") or None)  # type: ignore[arg-type]
    if spec.startswith("bc:"):
        from pianist.agents.bc import BCController

        return BCController(spec.removeprefix("bc:"))
    from pianist.control import make_controller

    try:
        return make_controller(spec)
    except ValueError as exc:
        if str(exc).startswith("unknown controller"):
            raise ValueError(f"unknown controller {spec!r}; use {KINDS}") from None
        raise
