"""Note events: the pure key_events function, and events / active keys reported by PianoEnv."""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np
import pytest

from pianist.env import PianoEnv
from pianist.env.events import SUSTAIN_EVENT_KEY, key_events, sustain_event
from pianist.music import Note, Song

THRESHOLD_RAD = math.radians(0.5)
# One long note on the top key (C8), far from both hands.
FAR = Song((Note(108, 0.0, 3.0, finger=4),), name="far")


def rows(events: object) -> list[tuple[float, int, bool]]:
    """Events as (time rounded to 1 us, key, on) rows, from an (n, 3) array or triples."""
    return [(round(float(t), 6), int(k), bool(on)) for t, k, on in events]  # type: ignore[attr-defined]


# --------------------------------------------------------------------------------- pure


def test_key_events_on_and_off_at_substep_times() -> None:
    times = np.array([0.105, 0.11, 0.115, 0.12])
    active = np.zeros((4, 88), dtype=bool)
    active[1:, 3] = True  # key 3 starts sounding after substep 1
    active[:2, 10] = True  # key 10 sounds after substeps 0-1, stops after substep 2
    events, last = key_events(np.zeros(88, dtype=bool), active, times)
    assert events.shape == (3, 3) and events.dtype == np.float64
    assert rows(events) == [(0.105, 10, True), (0.11, 3, True), (0.115, 10, False)]
    np.testing.assert_array_equal(last, active[-1])
    last[3] = False
    assert active[-1, 3]  # a copy, not a view


def test_key_events_use_the_previous_state() -> None:
    times = np.array([1.0, 2.0])
    previous = np.zeros(88, dtype=bool)
    previous[[5, 6]] = True
    active = np.zeros((2, 88), dtype=bool)
    active[:, 5] = True  # still sounding: no event
    active[1, 7] = True  # new
    events, last = key_events(previous, active, times)  # key 6 stopped before substep 0
    assert rows(events) == [(1.0, 6, False), (2.0, 7, True)]
    np.testing.assert_array_equal(np.flatnonzero(last), [5, 7])


def test_key_events_sorted_by_time_then_key() -> None:
    times = np.array([0.5, 0.6, 0.7])
    active = np.zeros((3, 88), dtype=bool)
    active[2, [80, 2]] = True
    active[1:, 40] = True
    active[0, 87] = True
    events, _ = key_events(np.zeros(88, dtype=bool), active, times)
    assert rows(events) == [
        (0.5, 87, True),
        (0.6, 40, True),
        (0.6, 87, False),
        (0.7, 2, True),
        (0.7, 80, True),
    ]


def test_key_events_nothing_changes() -> None:
    previous = np.zeros(88, dtype=bool)
    previous[12] = True
    active = np.tile(previous, (5, 1))
    events, last = key_events(previous, active, np.arange(5.0))
    assert events.shape == (0, 3)
    np.testing.assert_array_equal(last, previous)


def test_sustain_event() -> None:
    event = sustain_event(0.25, True)
    assert event.shape == (1, 3)
    assert rows(event) == [(0.25, SUSTAIN_EVENT_KEY, True)] and SUSTAIN_EVENT_KEY == -1
    assert rows(sustain_event(0.5, False)) == [(0.5, -1, False)]


# --------------------------------------------------------------------------------- env


def hold_action(env: PianoEnv) -> np.ndarray:
    low, high = env.model.actuator_ctrlrange.T
    return np.append((env.data.ctrl - low) / ((high - low) / 2) - 1.0, -1.0)


def strike(env: PianoEnv, key: int, velocity: float) -> None:
    """Put ``key`` at the bottom of its travel moving at ``velocity`` rad/s (+ is down)."""
    env.data.qpos[env.scene.key_qpos[key]] = env.scene.key_max_angle_rad[key]
    env.data.qvel[env.scene.key_dof[key]] = velocity


def substep_oracle(env: PianoEnv, before: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Replay the control step one mj_step at a time on a copy: (S, 88) activity, (S,) times."""
    mirror = copy.copy(before)
    mirror.ctrl[:] = env.data.ctrl  # the control the env applied during the step
    threshold = env.scene.key_max_angle_rad - THRESHOLD_RAD
    S = env.config.substeps
    active, times = np.zeros((S, 88), dtype=bool), np.zeros(S)
    for i in range(S):
        mujoco.mj_step(env.model, mirror)
        active[i] = mirror.qpos[env.scene.key_qpos] >= threshold
        times[i] = mirror.time
    np.testing.assert_array_equal(mirror.qpos, env.data.qpos)  # the env ran exactly S substeps
    return active, times


@pytest.fixture(scope="module")
def far_env() -> PianoEnv:
    return PianoEnv(FAR)


def test_pressed_key_gives_a_note_on_inside_the_step(far_env: PianoEnv) -> None:
    env = far_env
    env.reset(seed=0)
    action = hold_action(env)
    env.step(action)
    key = 30
    strike(env, key, velocity=20.0)
    start = env.data.time
    obs, _, _, _, info = env.step(action)
    end = env.data.time
    events = rows(info["note_events"])
    assert len(events) == 1
    time_s, k, on = events[0]
    assert k == key and on
    assert start < time_s <= end + 1e-9
    assert time_s == pytest.approx(start + 0.005)  # already at the bottom after substep 1
    # Held at its stop for the whole step, the key is still sounding at its end.
    assert np.flatnonzero(info["active_keys"]).tolist() == [key]
    assert obs["piano_keys"][key] == pytest.approx(1.0)
    # Released, the preloaded spring lifts it within the next step: a note-off.
    start = env.data.time
    obs, _, _, _, info = env.step(action)
    events = rows(info["note_events"])
    assert [(k, on) for _, k, on in events] == [(key, False)]
    assert start < events[0][0] <= env.data.time + 1e-9
    assert not info["active_keys"].any()
    assert obs["piano_keys"][key] < 0.5


def test_active_keys_match_the_key_angles(far_env: PianoEnv) -> None:
    env = far_env
    env.reset(seed=0)
    action = hold_action(env)
    for key in (0, 1, 44, 87):  # white and black, both ends, and the due key
        strike(env, key, velocity=20.0)
    _, _, _, _, info = env.step(action)
    threshold = env.scene.key_max_angle_rad - THRESHOLD_RAD
    expected = env.data.qpos[env.scene.key_qpos] >= threshold
    np.testing.assert_array_equal(info["active_keys"], expected)
    np.testing.assert_array_equal(np.flatnonzero(expected), [0, 1, 44, 87])
    assert sorted(k for _, k, _ in rows(info["note_events"])) == [0, 1, 44, 87]
    # 44 and 1 are not due: key press reward loses its 0.5 "no wrong key" half.
    assert info["reward_terms"]["key_press"] == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize(
    ("physics", "control_timestep_s", "warmup_steps"),
    [("faithful", 0.05, 2), ("fast", 0.05, 30), ("faithful", 0.025, 3), ("faithful", 0.1, 1)],
    ids=["faithful", "fast-sleeping-keys", "5-substeps", "20-substeps"],
)
@pytest.mark.parametrize("velocity", [0.0, 5.0, 20.0])
def test_events_match_a_substep_by_substep_replay(
    physics: str, control_timestep_s: float, warmup_steps: int, velocity: float
) -> None:
    """Key activity at every substep, replayed with single mj_step calls, gives exactly the
    env's note events (times included) and final active keys. With velocity 0 the key sounds
    for only a substep or two inside the step; with 20 rad/s it sounds through the step end.
    The fast preset warms up long enough for resting keys to fall asleep."""
    env = PianoEnv(FAR, physics=physics, control_timestep_s=control_timestep_s)
    env.reset(seed=0)
    action = hold_action(env)
    for _ in range(warmup_steps):
        env.step(action)
    key = 52
    strike(env, key, velocity)
    previous = np.zeros(88, dtype=bool)
    before = copy.copy(env.data)
    _, _, _, _, info = env.step(action)
    active, times = substep_oracle(env, before)
    expected, last = key_events(previous, active, times)
    got = rows(info["note_events"])
    assert got == rows(expected)
    assert got and got[0][1] == key and got[0][2]
    np.testing.assert_array_equal(info["active_keys"], last)
    if velocity == 0.0:
        assert [on for *_, on in got] == [True, False]  # a short blip inside the step
    if velocity == 20.0 and env.config.substeps <= 10:
        assert info["active_keys"][key]  # held at its stop for 50 ms, not for 100 ms
