"""Run a controller through one episode of a PianoEnv and record it."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from pianist.control.registry import realtime_text
from pianist.env.handle import control_handle
from pianist.eval.episode import Episode

if TYPE_CHECKING:
    import gymnasium as gym

    from pianist.control.base import Controller


def run_episode(
    env: gym.Env, controller: Controller, seed: int | None = 0, *, progress: bool = False
) -> Episode:
    """Play one full episode.

    Args:
        env: a :class:`pianist.env.PianoEnv` or a wrapper around one.
        controller: the controller (:class:`pianist.control.base.Controller`; only ``reset``
            and ``act`` are called here, :func:`pianist.eval.session.play` calls the rest).
        seed: passed to ``env.reset`` and to the controller.
        progress: show a progress bar on stderr: "planning" while the controller is reset
            (a planner makes its plan then), then the steps played and the speed as a
            multiple of real time (controller included), to two significant figures.
    Returns:
        The :class:`Episode` record.
    """
    handle = control_handle(env)
    observation, _ = env.reset(seed=seed)
    bar = _progress_bar(handle.num_steps) if progress else None
    start = time.perf_counter()  # the speed counts the planning, as metrics.json's does
    controller.reset(env, seed=seed)
    if bar is not None:
        bar.set_description("playing")
    actions, active, sustain, goal_keys, goal_sustain, rewards = [], [], [], [], [], []
    terms: dict[str, list[float]] = {}
    events: list[tuple[float, int, bool]] = []
    qpos = [handle.data.qpos.copy()]
    done = False
    while not done:
        action = np.asarray(controller.act(observation), dtype=np.float32)
        observation, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        actions.append(action)
        active.append(info["active_keys"])
        sustain.append(info["sustain"])
        goal_keys.append(info["goal_keys"])
        goal_sustain.append(info["goal_sustain"])
        rewards.append(reward)
        for name, value in info["reward_terms"].items():
            terms.setdefault(name, []).append(value)
        events.extend(info["note_events"])
        qpos.append(handle.data.qpos.copy())
        if bar is not None:
            bar.update(1)
            if bar.n % 20 == 0 or done:
                elapsed = time.perf_counter() - start
                simulated = bar.n * handle.control_timestep_s
                bar.set_postfix_str(f"{realtime_text(simulated / max(elapsed, 1e-9))} real time")
    if bar is not None:
        bar.close()
    return Episode(
        actions=np.stack(actions),
        active_keys=np.stack(active),
        sustain=np.array(sustain, dtype=bool),
        goal_keys=np.stack(goal_keys),
        goal_sustain=np.array(goal_sustain, dtype=bool),
        rewards=np.array(rewards),
        reward_terms={name: np.array(values) for name, values in terms.items()},
        note_events=np.array(events, dtype=float).reshape(-1, 3),
        control_timestep_s=handle.control_timestep_s,
        end_time_s=float(handle.data.time),
        qpos=np.stack(qpos),
        lead_in_steps=handle.config.lead_in_steps,
    )


def _progress_bar(total: int) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="step", desc="planning", leave=False, dynamic_ncols=True)
