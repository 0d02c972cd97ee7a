"""Practice: learning one piece by playing it again and again with the physics.

What is learned is a correction per step, ``table`` (T, A) float64: the action at step ``t``
is the inverse-kinematics planner's action plus ``table[t]`` (:class:`CorrectedPlanner`). The
planner stays in the loop, so the corrections are feed-forward nudges on top of a controller
that still reacts to where the hands are.

A practice pass plays the whole piece with the refiner (:class:`pianist.control.refine.Refiner`)
around the corrected planner: at every step it looks ahead with perturbations of the fingers'
part of the action (and small ones of the forearms' slides), plays the best, and the action
played becomes the step's new correction.
Before the first pass the planner plays the piece once with each hand plan of
``PracticeConfig.plans`` (its default choice, and both hands planned together), and the one
that plays best is practised: which plan suits a piece differs, and practice keeps the order.
The unperturbed candidate is the last pass's own action, so each pass starts from the
performance the previous one reached and only moves where looking ahead finds better; the
passes take the look-aheads of a schedule in turn (:data:`SCHEDULE`) with fresh samples. With
``workers`` > 1 that many passes start from the same table at once, each with the next
look-ahead, and the best one goes on. The pass's F1 is the F1 of its table replayed (the
table reproduces the played actions exactly, and the episode is deterministic), and the table
of the best pass is kept.

Compared with the refiner played live (``--refine``, ~0.5x real time), a practised piece plays
at the planner's speed, and the passes after the first add what one look-ahead could not find.
Compared with reinforcement learning from the reward, it learns nothing that carries over to
another piece: the table is indexed by the step of this piece in this scene, and it is refused
for any other.
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
import time
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, get_args, get_type_hints

import gymnasium as gym
import numpy as np

from pianist.agents.rundir import CONFIG, LOG
from pianist.control.planner import IKPlanner, PlanConfig, PlannerConfig
from pianist.control.refine import RefineOptions, Refiner
from pianist.env.handle import control_handle
from pianist.files import write_bytes_atomic, write_json_atomic

if TYPE_CHECKING:
    from pianist.music import GoalFrames, Song

TABLE = "practice.npz"
"""The file of a practice run directory holding the best table and what it was learned on."""


_FINGERED = "f:"
"""The prefix of a fingerprint that covers the fingering too (tables saved before it have
16 hex digits of the keys and pedal alone, and are still checked on those)."""


def goal_fingerprint(goal: GoalFrames, fingering: bool = True) -> str:
    """A digest of a song's goal frames (keys, pedal and, with ``fingering``, the finger on
    each key per step): a table learned on one piece is refused for any other, and for the
    same piece with another lead-in or another fingering."""
    digest = hashlib.sha256()
    digest.update(np.asarray(goal.keys.shape, dtype=np.int64).tobytes())
    digest.update(np.packbits(goal.keys).tobytes())
    digest.update(np.packbits(goal.sustain).tobytes())
    if not fingering:
        return digest.hexdigest()[:16]
    digest.update(np.ascontiguousarray(goal.fingers, dtype=np.int8).tobytes())
    return _FINGERED + digest.hexdigest()[:16]


def same_goal(goal: GoalFrames, fingerprint: str) -> bool:
    """Whether ``goal`` is the one ``fingerprint`` (:func:`goal_fingerprint`) was made of; a
    fingerprint from before the fingering was covered is compared on the keys and pedal."""
    fingered = fingerprint.startswith(_FINGERED)
    return goal_fingerprint(goal, fingering=fingered) == fingerprint


SCHEDULE: tuple[RefineOptions, ...] = (
    RefineOptions(arm_sigma=0.05),
    RefineOptions(sigma=0.3, arm_sigma=0.05),
    RefineOptions(horizon_steps=8, arm_sigma=0.05),
    RefineOptions(horizon_steps=8, sigma=0.3, candidates=12, arm_sigma=0.05),
)
"""The look-aheads the passes take in turn. Once one look-ahead finds little more to change
(a pass refining under a fifth of the steps), another one finds other changes: a longer
horizon sees a late strike's cost, a wider perturbation reaches a finger that is further off.
Each also nudges the forearms' slides (a hand kept a little longer over a held key, or moved a
little earlier): K545 0.917 -> 0.927 and the mazurka 0.815 -> 0.818 after 4 minutes on one
core, fast physics."""


PLANS: tuple[str, ...] = ("best", "split")
"""The hand plans a practice tries first: the planner's default choice among its one-hand
plans, and both hands planned together. Which plays a piece better differs from piece to
piece, and practice keeps the ranking: the Schoenberg 0.813 / 0.841 played, 0.899 / 0.912
after 4 minutes; the first polonaise 0.749 / 0.729, then 0.834 / 0.811 (fast, one worker)."""


@dataclass(frozen=True)
class PracticeConfig:
    """How a piece is practised."""

    passes: int | None = 20
    """Most practice passes (each plays the whole piece once with the refiner per worker);
    None: no limit, the wall-clock budget ends the practice (``pianist train --minutes M``
    without ``--passes``)."""
    physics: str = "faithful"
    """The physics preset practised in, and played in afterwards: a table is a correction of
    that physics' trajectories and does not transfer to the other preset."""
    seed: int = 0
    """Seeds the refiner's perturbations (pass p, worker w draws from ``(seed, p, w)``)."""
    workers: int = 1
    """Passes played at once from the same table, each in its own process with the next
    look-ahead of the schedule; the best becomes the next table (2 on two cores)."""
    schedule: tuple[RefineOptions, ...] = SCHEDULE
    """The look-aheads, taken in turn: pass p, worker w uses the
    ``((p - 1) * workers + w)``-th (cycling)."""
    plans: tuple[str, ...] = PLANS
    """The planner's hand plans (``PlanConfig.hand_planning``) the practice starts by
    playing once each; it practises the one that plays best (the first of equals)."""

    def __post_init__(self) -> None:
        if self.passes is not None and self.passes < 1:
            raise ValueError(f"practice needs at least 1 pass, not {self.passes}")
        if self.workers < 1:
            raise ValueError(f"practice needs at least 1 worker, not {self.workers}")
        if not self.schedule:
            raise ValueError("practice needs at least one look-ahead in its schedule")
        known = get_args(get_type_hints(PlanConfig)["hand_planning"])
        if not self.plans or any(plan not in known for plan in self.plans):
            raise ValueError(
                f"practice plans must be some of {', '.join(known)}, not {list(self.plans)}"
            )
        from pianist.sim.scene import PHYSICS_PRESETS

        if self.physics not in PHYSICS_PRESETS:
            raise ValueError(
                f"unknown physics {self.physics!r}; use one of {', '.join(PHYSICS_PRESETS)}"
            )

    def options(self, index: int, worker: int) -> RefineOptions:
        """The look-ahead of pass ``index`` (from 1) in ``worker`` (from 0)."""
        return self.schedule[((index - 1) * self.workers + worker) % len(self.schedule)]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PracticeConfig:
        data = dict(data)
        data["schedule"] = tuple(RefineOptions(**o) for o in data.get("schedule", ()))
        if "plans" in data:
            data["plans"] = tuple(data["plans"])
        return cls(**data)


class CorrectedPlanner(IKPlanner):
    """The planner with a learned correction added to its action at every step.

    ``table``: (T, A) corrections in action units for the T steps of one piece (steps past T
    get none). ``fingerprint``: the goal frames' :func:`goal_fingerprint` the table was
    learned on (None: not checked); ``physics``: the preset it was learned in (None: any);
    ``hand_planning``: the planner's hand plan it was learned with.
    """

    def __init__(
        self,
        table: np.ndarray,
        *,
        fingerprint: str | None = None,
        physics: str | None = None,
        hand_planning: str = "best",
    ) -> None:
        super().__init__(PlannerConfig().with_fields(hand_planning=hand_planning))
        table = np.asarray(table, dtype=np.float64)
        if table.ndim != 2:
            raise ValueError(f"a correction table is (T, A), not {table.shape}")
        self.table = table
        self.fingerprint = fingerprint
        self.physics = physics
        self.raw_actions: dict[int, np.ndarray] = {}
        self._main_data: Any = None

    @classmethod
    def load(cls, run_dir: str | Path) -> CorrectedPlanner:
        """The best table of a practice run directory (:func:`practise`).

        Raises:
            FileNotFoundError: no practice table there; ValueError: an unreadable one.
        """
        path = Path(run_dir) / TABLE
        if not path.is_file():
            raise FileNotFoundError(f"{run_dir} holds no practised piece ({TABLE} is missing)")
        try:
            with np.load(path, allow_pickle=False) as data:
                table = data["table"]
                fingerprint = str(data["fingerprint"])
                physics = str(data["physics"])
                # Tables from before the plan was chosen were practised with the default.
                plan = str(data["hand_planning"]) if "hand_planning" in data else "best"
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ValueError(f"{path} is not a practice table ({exc})") from None
        return cls(table, fingerprint=fingerprint, physics=physics, hand_planning=plan)

    def env_options(self, song: Song | None = None) -> dict[str, Any]:
        options = super().env_options(song)
        if self.physics is not None:
            options["physics"] = self.physics
        return options

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        super().reset(env, seed)
        handle = control_handle(env)
        if self.fingerprint is not None and not same_goal(handle.goal, self.fingerprint):
            raise ValueError(
                "this correction table was practised on another piece (or on the whole of "
                "this one, not an excerpt, or with another lead-in or fingering): it plays "
                "only the piece as practised; practise this one with "
                "`pianist train SONG --preset practice`"
            )
        dims = handle.model.nu + 1  # the actuators and the pedal
        if self.table.shape[0] and self.table.shape[1] != dims:
            raise ValueError(
                f"the table corrects {self.table.shape[1]} action values, this environment "
                f"has {dims}"
            )
        self._main_data = handle.data
        self.raw_actions = {}

    def act(self, observation: object = None) -> np.ndarray:
        raw = super().act(observation)
        t = self.handle.step_index
        if self.handle.data is self._main_data:
            # The episode's own step (not a look-ahead on a fork): what practice rewrites.
            self.raw_actions[t] = raw
        if t >= self.table.shape[0]:
            return raw
        return (raw + self.table[t]).clip(-1.0, 1.0).astype(np.float32)

    def options_dict(self) -> dict[str, Any]:
        return {
            "practice": {
                "steps": int(self.table.shape[0]),
                "physics": self.physics,
                "hand_planning": self.config.plan.hand_planning,
            }
        }


class _PassRefiner(Refiner):
    """The refiner of one practice pass: its perturbations drawn from ``seed``, whatever the
    episode's seed."""

    def __init__(
        self,
        planner: CorrectedPlanner,
        options: RefineOptions,
        seed: list[int],
        deadline: float | None = None,
    ):
        super().__init__(planner, options)
        self._seed = seed
        self.deadline = deadline
        """``time.time()`` from which the pass stops looking ahead: the rest of the piece is
        played by the corrected planner alone (its table kept), so a pass ends soon after a
        wall-clock budget runs out and keeps what it learned before."""

    def reset(self, env: gym.Env, seed: int | None = None) -> None:
        super().reset(env, seed)
        self.rng = np.random.default_rng(self._seed)

    def act(self, observation: Any = None) -> np.ndarray:
        if self.deadline is not None and time.time() >= self.deadline:
            self._steps += 1  # a step played without refining
            return self.planner.act(observation)
        return super().act(observation)


@dataclass
class PracticeResult:
    """What :func:`practise` learned: the best ``table`` (T, A), its whole-piece ``f1`` and
    the ``pass_index`` that made it (0: the planner alone), and one row per pass in
    ``history`` (pass, f1, precision, recall, refined_share, seconds since the start, and
    from pass 1 the worker kept, every worker's f1 and ``env_steps``: the environment steps
    all the workers simulated, look-aheads included)."""

    table: np.ndarray
    f1: float
    pass_index: int
    history: list[dict[str, Any]]
    fingerprint: str
    hand_planning: str = "best"
    """The planner's hand plan practised (the best played of ``PracticeConfig.plans``)."""


def practise(
    song: Song,
    config: PracticeConfig | None = None,
    *,
    stop_after_s: float | None = None,
    start: PracticeResult | None = None,
    on_pass: Callable[[PracticeResult], None] | None = None,
) -> PracticeResult:
    """Practise ``song`` for ``config.passes`` passes or until ``stop_after_s`` seconds of
    wall-clock time have passed: a pass that runs into the budget stops looking ahead there
    and plays the rest of the piece with the table so far (what it learned before is kept),
    and no pass starts with less time left than the planner takes to play the piece. The
    first pass (the planner alone) always runs.

    Args:
        song: the piece, fingered (the planner needs a finger on every note).
        config: passes, physics, seed, workers and the refiner's look-aheads.
        stop_after_s: wall-clock budget in seconds (None: only ``passes``, which must then
            be a number).
        start: a result to continue from (its table, best F1 and history; the passes go on
            counting from its last).
        on_pass: called with the result so far after every pass (to save it).

    Returns:
        The best table and the history of every pass.
    """
    config = config or PracticeConfig()
    if config.passes is None and stop_after_s is None:
        raise ValueError("practice with no limit on its passes needs a wall-clock budget")
    t0 = time.perf_counter()
    deadline = None if stop_after_s is None else time.time() + stop_after_s
    pool = _pool(config.workers)
    try:
        if start is None:
            result = _first_pass(song, config, pool, t0)
            if on_pass is not None:
                on_pass(result)
        else:
            result = start
        # The seconds of the passes before this call (a resumed run's); a new run's pass 0
        # was timed from ``t0`` like the passes below.
        elapsed0 = start.history[-1]["seconds"] if start is not None and start.history else 0.0
        first = result.history[-1]["pass"] + 1 if result.history else 1
        last = config.passes if config.passes is not None else sys.maxsize
        # What playing the piece once without looking ahead takes (pass 0 played it so).
        planner_s = time.perf_counter() - t0 if start is None else 0.0
        for index in range(first, last + 1):
            if deadline is not None and deadline - time.time() < planner_s:
                break  # a pass started now would end past the budget
            jobs = [
                (
                    song,
                    result.table,
                    result.fingerprint,
                    config.physics,
                    config.options(index, w),
                    [config.seed, index, w],
                    result.hand_planning,
                    deadline,
                )
                for w in range(config.workers)
            ]
            if pool is None:
                outcomes = [_practice_pass(*job) for job in jobs]
            else:
                outcomes = list(pool.map(_practice_pass, *zip(*jobs, strict=True)))
            # The best worker's pass (the first of equals).
            worker = max(range(len(outcomes)), key=lambda w: (outcomes[w][1]["f1"], -w))
            table, metrics, refined = outcomes[worker]
            seconds = elapsed0 + time.perf_counter() - t0
            row = _row(index, metrics, seconds, refined)
            row["worker"], row["worker_f1"] = worker, [o[1]["f1"] for o in outcomes]
            row["env_steps"] = int(sum(o[1]["env_steps"] for o in outcomes))
            result.history.append(row)
            if metrics["f1"] > result.f1:
                result.table, result.f1, result.pass_index = table, metrics["f1"], index
            if on_pass is not None:
                on_pass(result)
            if stop_after_s is not None and time.perf_counter() - t0 >= stop_after_s:
                break
    finally:
        if pool is not None:
            pool.shutdown()
    return result


def _first_pass(song: Song, config: PracticeConfig, pool: Any, t0: float) -> PracticeResult:
    """Pass 0: the planner alone with each of ``config.plans`` (in the pool's processes when
    there is one), the best played kept (the first of equals); its row records them all."""
    plans = list(config.plans)
    if pool is None:
        trials = [_plan_trial(song, config.physics, plan) for plan in plans]
    else:
        physics = [config.physics] * len(plans)
        trials = list(pool.map(_plan_trial, [song] * len(plans), physics, plans))
    best = max(range(len(plans)), key=lambda i: (trials[i][0]["f1"], -i))
    metrics, steps, dims, fingerprint = trials[best]
    row = _row(0, metrics, time.perf_counter() - t0, 0.0)
    row["hand_planning"] = plans[best]
    row["plan_f1"] = {plan: trial[0]["f1"] for plan, trial in zip(plans, trials, strict=True)}
    return PracticeResult(
        table=np.zeros((steps, dims)),
        f1=float(metrics["f1"]),
        pass_index=0,
        history=[row],
        fingerprint=fingerprint,
        hand_planning=plans[best],
    )


def _plan_trial(song: Song, physics: str, plan: str) -> tuple[dict[str, float], int, int, str]:
    """The planner alone with hand plan ``plan``: its metrics (f1, precision, recall), the
    episode's steps and action size, and the goal's fingerprint."""
    from pianist.eval.session import play

    config = PlannerConfig().with_fields(hand_planning=plan)
    played = play(song, IKPlanner(config), physics=physics, seed=0)
    goal = played.goal
    steps, dims = played.episode.actions.shape
    metrics = {name: float(played.metrics[name]) for name in ("f1", "precision", "recall")}
    return metrics, steps, dims, goal_fingerprint(goal)


def _pool(workers: int) -> Any:
    """Spawned worker processes for ``workers`` > 1 (None: play the passes here)."""
    if workers == 1:
        return None
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def _practice_pass(
    song: Song,
    table: np.ndarray,
    fingerprint: str,
    physics: str,
    options: RefineOptions,
    seed: list[int],
    hand_planning: str = "best",
    deadline: float | None = None,
) -> tuple[np.ndarray, dict[str, float], float]:
    """One pass: the piece played by the refiner around the planner corrected by ``table``
    (looking ahead until ``deadline``, a ``time.time()``; after it the corrected planner
    alone). Returns the table that replays that performance, its metrics (f1, precision,
    recall) and the share of steps the look-ahead changed."""
    from pianist.eval.session import play

    planner = CorrectedPlanner(table, fingerprint=fingerprint, hand_planning=hand_planning)
    refiner = _PassRefiner(planner, options, seed, deadline)
    played = play(song, refiner, physics=physics, seed=0)
    actions = np.asarray(played.episode.actions, dtype=np.float64)
    raw = np.stack([planner.raw_actions[t] for t in range(actions.shape[0])])
    # The correction that makes the planner's action the one played, exactly: float32
    # actions differ by a float64-exact amount, and raw + it rounds back to the action.
    new_table = actions - raw.astype(np.float64)
    metrics = {name: float(played.metrics[name]) for name in ("f1", "precision", "recall")}
    # Every environment step the pass simulated: the piece's own and the look-aheads'.
    metrics["env_steps"] = float(actions.shape[0] + refiner.simulated_steps)
    return new_table, metrics, refiner.stats()["refined_share"]


def _row(index: int, metrics: dict[str, Any], seconds: float, refined: float) -> dict[str, Any]:
    return {
        "pass": index,
        "f1": float(metrics["f1"]),
        "precision": float(metrics["precision"]),
        "recall": float(metrics["recall"]),
        "refined_share": refined,
        "seconds": seconds,
    }


# ------------------------------------------------------------------------- run directories


def save_practice(run_dir: str | Path, result: PracticeResult, config: PracticeConfig) -> None:
    """Write the best table with every pass's row (``practice.npz``, what a resumed run reads)
    and the rows again as ``log.jsonl`` (to read), each atomically: a run killed mid-write
    keeps the previous ones."""
    run_dir = Path(run_dir)
    buffer = io.BytesIO()
    np.savez(
        buffer,
        table=result.table,
        fingerprint=np.array(result.fingerprint),
        physics=np.array(config.physics),
        f1=np.array(result.f1),
        pass_index=np.array(result.pass_index),
        history=np.array(json.dumps(result.history)),
        hand_planning=np.array(result.hand_planning),
    )
    write_bytes_atomic(buffer.getvalue(), run_dir / TABLE)
    lines = "".join(json.dumps(row) + "\n" for row in result.history)
    write_bytes_atomic(lines.encode(), run_dir / LOG)


def practise_in(
    run_dir: str | Path,
    song: Song,
    song_spec: str,
    config: PracticeConfig,
    *,
    start: PracticeResult | None = None,
    stop_after_s: float | None = None,
    on_pass: Callable[[PracticeResult], None] | None = None,
) -> PracticeResult:
    """:func:`practise` as a run in ``run_dir`` (an existing folder): its ``config.json``
    (``song_spec``: the song as the user gave it) written first, the best table and the log
    saved after every pass, so that :func:`load_practice` resumes it from its last pass."""
    write_practice_config(run_dir, song_spec, config)

    def saved(result: PracticeResult) -> None:
        save_practice(run_dir, result, config)
        if on_pass is not None:
            on_pass(result)

    return practise(song, config, stop_after_s=stop_after_s, start=start, on_pass=saved)


def write_practice_config(run_dir: str | Path, song: str, config: PracticeConfig) -> None:
    """``config.json`` of a practice run: the song as given and the :class:`PracticeConfig`."""
    data = {"kind": "practice", "song": song, **config.to_dict()}
    write_json_atomic(data, Path(run_dir) / CONFIG)


def is_practice_run(run_dir: str | Path) -> bool:
    """Whether ``run_dir`` is a practice run (its config.json says so)."""
    path = Path(run_dir) / CONFIG
    try:
        return json.loads(path.read_text()).get("kind") == "practice"
    except (OSError, json.JSONDecodeError, AttributeError):
        return False


def load_practice(run_dir: str | Path) -> tuple[str, PracticeConfig, PracticeResult]:
    """The song, configuration and best result so far of a practice run (to resume it).

    Raises:
        ValueError: the directory is not a readable practice run.
    """
    run_dir = Path(run_dir)
    try:
        data = json.loads((run_dir / CONFIG).read_text())
        song = data.pop("song")
        data.pop("kind")
        config = PracticeConfig.from_dict(data)
        with np.load(run_dir / TABLE, allow_pickle=False) as arrays:
            result = PracticeResult(
                table=arrays["table"],
                f1=float(arrays["f1"]),
                pass_index=int(arrays["pass_index"]),
                history=json.loads(str(arrays["history"])),
                fingerprint=str(arrays["fingerprint"]),
                hand_planning=(
                    str(arrays["hand_planning"]) if "hand_planning" in arrays else "best"
                ),
            )
    except (
        OSError,
        KeyError,
        ValueError,
        TypeError,
        EOFError,
        zipfile.BadZipFile,
        json.JSONDecodeError,
    ) as exc:
        raise ValueError(f"{run_dir} is not a readable practice run ({exc})") from None
    return song, config, result
