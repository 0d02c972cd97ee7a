"""The Gymnasium environment: two Shadow hands play one song on the 88-key piano.

Observation (a ``gymnasium.spaces.Dict``; every entry float32). L is the lookahead.

==================  ============  ======  ===================================================
key                 shape         unit    meaning
==================  ============  ======  ===================================================
``goal``            (L+1, 89)     0/1     keys due (88) and sustain (1) at frames t..t+L,
                                          zero past the end of the song
``fingers_due``     (10,)         0/1     fingers due at frame t: 0-4 right thumb..little,
                                          5-9 left thumb..little
``piano_keys``      (88,)         [0, 1]  key depression, 0 up, 1 at the bottom of travel
``piano_sustain``   (1,)          0/1     sustain pedal state
``goal_velocity``   (L+1, 88)     [0, 1]  with ``velocity_goal`` only: MIDI velocity / 127 of
                                          each note starting at frames t..t+L, 0 elsewhere
``rh_joints``       (23,)/(26,)   rad, m  right hand joint positions, forearm slides first
``lh_joints``       (23,)/(26,)   rad, m  the same for the left hand
``rh_fingertips``   (5, 3)        m       fingertip positions, thumb..little (world frame)
``lh_fingertips``   (5, 3)        m       the same for the left hand
``rh_forearm``      (3,)          m       forearm root position (world frame)
``lh_forearm``      (3,)          m       the same for the left hand
==================  ============  ======  ===================================================

The joint count is 23 with the reduced action space (21 hand joints + 2 forearm slides) and
26 without; extra forearm DoFs add to it. One-hand scenes have only that hand's entries.

Action: a vector in [-1, 1]^(nu + 1): one entry per actuator (right hand then left, each hand's
finger/wrist actuators then its forearm actuators; see :attr:`PianoEnv.action_names`), mapped
linearly onto the actuator's control range, then the sustain pedal (pressed when >= 0).

Step t applies the action for one control step (10 physics substeps by default), then scores
the keys sounding at the end of the step against goal frame t. The episode has one step per
goal frame and ends *truncated* after the last; with ``wrong_press_termination`` it ends
*terminated* at the first step where a key that is not due sounds.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from pianist.env import rewards as R
from pianist.env.config import REWARD_TERMS, EnvConfig, make_config
from pianist.env.events import EMPTY_EVENTS, key_events, sustain_event
from pianist.env.loudness import speed_to_velocity, strike_speeds
from pianist.env.tape import StepTape
from pianist.music import GoalFrames, Song, goal_frames, load_song
from pianist.sim import constants as C
from pianist.sim.scene import Scene, build_scene

HAND_OBS_PREFIX = {"right": "rh", "left": "lh"}
_INSTABILITY_WARNINGS = tuple(
    int(w)
    for w in (
        mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADQVEL,
        mujoco.mjtWarning.mjWARN_BADQACC,
    )
)
FORWARD_SIDES = ("right", "left")
#: A key this far below its upper stop is not at rest (it rests at ~0: its spring preloads it).
KEY_REST_TOLERANCE_RAD = np.deg2rad(0.05)
#: Upward velocity written to a sleeping key to wake it.
WAKE_VELOCITY_RAD_S = 1e-3
#: The simulator's fields the steps to come depend on (with ``time``): a tape plays back only
#: from a state equal in all of them (PianoEnv.play_tape).
_TAPE_START_FIELDS = (
    "qpos",
    "qvel",
    "act",
    "ctrl",
    "userdata",
    "qacc_warmstart",
    "history",
    "tree_asleep",
    "qfrc_applied",
    "xfrc_applied",
)


class SimulationUnstableError(RuntimeError):
    """MuJoCo reported a diverging simulation (NaN, Inf or huge accelerations)."""


def action_to_ctrl(action: np.ndarray, ctrlrange: np.ndarray) -> np.ndarray:
    """Normalised actuator actions -> actuator controls (what :meth:`PianoEnv.step` applies).

    Args:
        action: (..., nu) values in [-1, 1] (clipped), one per actuator, sustain excluded.
        ctrlrange: (nu, 2) control range of each actuator (``model.actuator_ctrlrange``).
    Returns:
        (..., nu) controls, -1 -> the range's lower end, 1 -> its upper end.
    """
    low, high = ctrlrange[:, 0], ctrlrange[:, 1]
    action = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)  # float32 in: no rounding
    return low + (action + 1.0) * ((high - low) / 2)


def resolve_goal(song: Song | GoalFrames | str | Path, dt: float) -> tuple[GoalFrames, Song | None]:
    """A song name, file, Song or GoalFrames -> goal frames at control step ``dt``."""
    if isinstance(song, GoalFrames):
        if abs(song.dt - dt) > 1e-9:
            raise ValueError(f"goal frames at dt {song.dt} s do not match the control step {dt} s")
        return song, None
    resolved = song if isinstance(song, Song) else load_song(song)
    return goal_frames(resolved, dt=dt), resolved


@dataclass(frozen=True)
class EnvState:
    """A :class:`PianoEnv`'s episode state between two steps (:meth:`PianoEnv.snapshot`):
    restored, the episode goes on exactly as it would have (same physics, events, rewards)."""

    data: mujoco.MjData
    """A private copy of the simulator state (every field: sleeping keys, sensor history)."""
    step: int
    active: np.ndarray
    sustain: bool
    pending_events: np.ndarray
    key_state: np.ndarray
    key_qpos_after_step: np.ndarray
    warnings_seen: int
    key_qpos_before_step: np.ndarray
    """(88,) rad: the keys' angles as the step before the last began (strike speeds)."""


class PianoEnv(gym.Env):
    """Play a song on the piano. See the module docstring for observations and actions."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": round(1 / C.CONTROL_TIMESTEP_S)}

    def __init__(
        self,
        song: Song | GoalFrames | str | Path,
        config: EnvConfig | None = None,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (480, 640),
        render_camera: str = "closeup",
        **options: Any,
    ) -> None:
        """
        Args:
            song: a built-in song name, a MIDI or PIG file, a Song, or GoalFrames.
            config: the full configuration; or give flat ``options`` instead
                (see :func:`pianist.env.config.make_config`), not both.
            render_mode: None or "rgb_array".
            render_size: (height, width) of rendered frames in pixels.
            render_camera: name of the camera used by :meth:`render`.
        """
        if config is not None and options:
            raise TypeError("pass either config or keyword options, not both")
        self.config = config if config is not None else make_config(**options)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"unknown render_mode {render_mode!r}; use None or 'rgb_array'")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1 / self.config.control_timestep_s)}

        self.goal, self.song = resolve_goal(song, self.config.control_timestep_s)
        self.goal = self.goal.with_lead_in(self.config.lead_in_steps)
        self.scene: Scene = build_scene(self.config.scene, key_history=self.config.substeps)
        self.model: mujoco.MjModel = self.scene.model
        self.data = mujoco.MjData(self.model)
        self._render_size = render_size
        self._render_camera = render_camera
        self._renderer: Any = None
        if render_camera not in {self.model.camera(i).name for i in range(self.model.ncam)}:
            names = sorted(self.model.camera(i).name for i in range(self.model.ncam))
            raise ValueError(f"unknown camera {render_camera!r}; choose from {names}")
        self._setup_indices()
        self._setup_goal()
        self._setup_spaces()
        self._t = 0
        self._started = False  # an episode has been started (reset)
        self._tape: StepTape | None = None  # steps to play back (play_tape)

    # ----------------------------------------------------------------------------- set-up

    def _setup_indices(self) -> None:
        model, scene = self.model, self.scene
        keys = scene.key_qpos
        # Keys are built first, so their qpos is one contiguous block: a slice is a view.
        if np.array_equal(keys, np.arange(keys[0], keys[0] + C.NUM_KEYS)):
            self._key_slice: slice | np.ndarray = slice(int(keys[0]), int(keys[0]) + C.NUM_KEYS)
        else:
            self._key_slice = keys
        self._key_max = scene.key_max_angle_rad
        self._key_threshold = self._key_max - C.KEY_ACTIVATION_THRESHOLD_RAD
        # Sleeping islands (the fast preset): a key can fall asleep held down by a finger and,
        # its spring not evaluated while it sleeps, stay down after the finger has left (it
        # sounded for 18 s in a piece). Such keys are woken before every step.
        self._sleep = bool(model.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_SLEEP))
        key_joints = [int(np.flatnonzero(model.jnt_qposadr == q)[0]) for q in keys]
        self._key_trees = model.body_treeid[model.jnt_bodyid[key_joints]]
        self._ctrl_low = model.actuator_ctrlrange[:, 0].copy()
        self._ctrl_half = (model.actuator_ctrlrange[:, 1] - model.actuator_ctrlrange[:, 0]) / 2
        # Fingertip site of each of the 10 fingers, -1 when that hand is absent.
        self._finger_sites = np.full(10, -1, dtype=np.intp)
        for hand in scene.hands:
            offset = 0 if hand.side == "right" else 5
            self._finger_sites[offset : offset + 5] = hand.fingertip_sites
        self._forearm_pair = None
        if scene.forearms_can_touch:
            self._forearm_pair = {scene.hands[0].forearm_body, scene.hands[1].forearm_body}
        self._tx_joint = {
            h.side: model.joint(f"{C.HAND_PREFIX[h.side]}forearm_tx").id
            for h in scene.hands
            if f"{C.HAND_PREFIX[h.side]}forearm_tx"
            in {model.joint(j).name for j in range(model.njnt)}
        }
        S = self.config.substeps
        self._substep_active = np.zeros((S, C.NUM_KEYS), dtype=bool)
        ring = scene.key_history_values.shape[1]
        if ring < S:
            raise ValueError(f"the key sensors keep {ring} samples, need {S}")
        # For each cursor position of the circular history, the addresses of the newest S - 1
        # samples in time order: (ring, S-1, 88) values and (ring, S-1) times.
        slots = (np.arange(ring)[:, None] - np.arange(S - 2, -1, -1)[None, :]) % ring
        self._history_cursor = int(scene.key_history_cursor[0])
        self._history_values = scene.key_history_values[:, slots].transpose(1, 2, 0).copy()
        self._history_times = scene.key_history_times[0, slots]
        weights = self.config.rewards.as_dict()
        self._weights = [(name, weights[name]) for name in REWARD_TERMS]

    def _setup_goal(self) -> None:
        goal, lookahead = self.goal, self.config.lookahead
        T = goal.num_frames
        # Rows up to T + L: the observation after the last step still shows L + 1 frames.
        padded = np.zeros((T + lookahead + 1, C.NUM_KEYS + 1), dtype=np.float32)
        padded[:T, : C.NUM_KEYS] = goal.keys
        padded[:T, C.NUM_KEYS] = goal.sustain
        self._goal_padded = padded
        # The loudness of each note at the frame it starts (velocity_goal), padded the same way.
        onset_velocity = np.zeros((T + lookahead + 1, C.NUM_KEYS), dtype=np.float32)
        onset_velocity[:T] = np.where(goal.onsets, goal.velocities / 127.0, 0.0)
        self._velocity_padded = onset_velocity
        self._finger_mask = goal.finger_mask.astype(np.float32)
        # Per frame, computed once: the due keys, and (fingertip site, key site) pairs of the
        # fingered ones whose hand is in the scene (the others are not scored).
        self._due_keys = [np.flatnonzero(row) for row in goal.keys]
        self._fingering_sites = []
        for keys, fingers in zip(self._due_keys, goal.fingers, strict=True):
            keys = keys[fingers[keys] >= 0]
            sites = self._finger_sites[fingers[keys]]
            present = sites >= 0
            self._fingering_sites.append((sites[present], self.scene.key_sites[keys[present]]))
        if self.config.fingering_reward == "optimal":
            # Label-free: every fingertip of the scene may take any due key.
            tips = self._finger_sites[self._finger_sites >= 0]
            self._fingering_sites = [(tips, self.scene.key_sites[keys]) for keys in self._due_keys]

    def _setup_spaces(self) -> None:
        L = self.config.lookahead
        f32 = np.float32
        unit = (0.0, 1.0)  # (low, high)
        # Generous finite bounds (joint angles and slides in rad/m, positions in m): the
        # instability check raises long before a state could leave them.
        joints = (-2 * np.pi, 2 * np.pi)
        position = (-5.0, 5.0)
        spaces: dict[str, gym.spaces.Space] = {
            "goal": gym.spaces.Box(*unit, shape=(L + 1, C.NUM_KEYS + 1), dtype=f32),
            "fingers_due": gym.spaces.Box(*unit, shape=(10,), dtype=f32),
            "piano_keys": gym.spaces.Box(*unit, shape=(C.NUM_KEYS,), dtype=f32),
            "piano_sustain": gym.spaces.Box(*unit, shape=(1,), dtype=f32),
        }
        if self.config.velocity_goal:
            spaces["goal_velocity"] = gym.spaces.Box(*unit, shape=(L + 1, C.NUM_KEYS), dtype=f32)
        for hand in self.scene.hands:
            p = HAND_OBS_PREFIX[hand.side]
            spaces[f"{p}_joints"] = gym.spaces.Box(
                *joints, shape=(len(hand.joint_qpos),), dtype=f32
            )
            spaces[f"{p}_fingertips"] = gym.spaces.Box(*position, shape=(5, 3), dtype=f32)
            spaces[f"{p}_forearm"] = gym.spaces.Box(*position, shape=(3,), dtype=f32)
        self.observation_space = gym.spaces.Dict(spaces)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(self.model.nu + 1,), dtype=np.float32)

    # ----------------------------------------------------------------------------- API

    @property
    def action_names(self) -> list[str]:
        """Name of each action dimension: actuator names, then ``sustain``."""
        return [self.model.actuator(i).name for i in range(self.model.nu)] + ["sustain"]

    @property
    def num_steps(self) -> int:
        """Steps in a full episode (one per goal frame)."""
        return self.goal.num_frames

    @property
    def step_index(self) -> int:
        """Index of the goal frame the next step will play."""
        return self._t

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode at step 0, or with ``options={"start": state}`` go on from an
        :class:`EnvState` (:meth:`snapshot`) as :meth:`restore` does."""
        super().reset(seed=seed)
        self._tape = None
        start = (options or {}).get("start")
        if start is not None:  # continue an episode from a snapshot of it (see restore)
            self.restore(start)
            return self._observation(), {
                "step": start.step,
                "active_keys": start.active.copy(),
                "sustain": start.sustain,
            }
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        if self.config.randomize_hand_positions:
            for joint in self._tx_joint.values():
                adr = model.jnt_qposadr[joint]
                low, high = model.jnt_range[joint]
                data.qpos[adr] = np.clip(self.np_random.uniform(-0.05, 0.05), low, high)
        mujoco.mj_forward(model, data)
        # Hold the initial pose: each position servo's target is its current length.
        data.ctrl[:] = np.clip(data.actuator_length, *model.actuator_ctrlrange.T)
        self._t = 0
        self._started = True
        self._active = np.zeros(C.NUM_KEYS, dtype=bool)
        self._sustain = False
        self._pending_events = EMPTY_EVENTS
        self._key_state = self.key_state()
        self._key_qpos_after_step = self.data.qpos[self._key_slice].copy()
        self._key_qpos_before_step = self._key_qpos_after_step.copy()
        self._warnings_seen = self._instability_warnings()
        info = {"step": 0, "active_keys": self._active.copy(), "sustain": False}
        return self._observation(), info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._tape is not None:
            outputs = self._step_from_tape(action)
            if outputs is not None:
                return outputs
        self.apply_action(action)
        self.advance_physics()
        return self.finish_step()

    def play_tape(self, tape: StepTape) -> bool:
        """Play ``tape``'s steps back from the next step on (:mod:`pianist.env.tape`): as
        long as each step's action is the tape's, the step returns the recorded outcome (and
        the observation made again from the recorded state) and sets the recorded state
        instead of simulating it. The episode is the same, bit for bit, as simulating every
        step.

        Args:
            tape: steps recorded (:meth:`StepTape.record`) on a :meth:`fork` of this
                environment in its current state, closed (:meth:`StepTape.finish`).
        Returns:
            Whether the tape was taken: not (and nothing changes) unless it is closed, has
            steps, was recorded with this environment's goal frames and configuration, and
            starts at this environment's current step and state.
        """
        if (
            not self._started
            or tape.end is None
            or len(tape) == 0
            or tape.goal is not self.goal
            or tape.config != self.config
            or not self._is_at(tape.start)
        ):
            return False
        self._leave_tape()
        self._tape = tape
        return True

    def _is_at(self, state: EnvState) -> bool:
        """Whether the episode is exactly at the snapshot ``state`` (its step, counters and
        every field of the simulator state that the steps to come depend on)."""
        if state.step != self._t or state.sustain != self._sustain:
            return False
        mine = (
            self._active,
            self._key_state,
            self._key_qpos_after_step,
            self._key_qpos_before_step,
            self._pending_events,
        )
        theirs = (
            state.active,
            state.key_state,
            state.key_qpos_after_step,
            state.key_qpos_before_step,
            state.pending_events,
        )
        if not all(np.array_equal(a, b) for a, b in zip(mine, theirs, strict=True)):
            return False
        return state.data.time == self.data.time and all(
            np.array_equal(getattr(state.data, name), getattr(self.data, name))
            for name in _TAPE_START_FIELDS
        )

    def _step_from_tape(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]] | None:
        """The tape's next step if ``action`` is its action (else the tape is left: None)."""
        tape = self._tape
        assert tape is not None
        index = self._t - tape.start_step
        if not tape.matches(index, action):
            self._leave_tape()
            return None
        tape.set_state(index, self.model, self.data)
        reward, terminated, truncated, info = tape.outcome(index)
        self._t += 1
        self._active = info["active_keys"].copy()
        self._sustain = info["sustain"]
        self._key_state = self.key_state()
        if index + 1 == len(tape):  # its last step: the full recorded state, and no tape
            assert tape.end is not None
            self.restore(tape.end)
        # Made from the state as a simulated step makes it (mj_kinematics after the step).
        return self._observation(), reward, terminated, truncated, info

    def _leave_tape(self) -> None:
        """Stop playing the tape, the environment brought to exactly where simulating the
        steps played from it would have: its start restored, those steps simulated."""
        tape, self._tape = self._tape, None
        if tape is None or self._t == tape.start_step:
            return
        played = self._t - tape.start_step
        self.restore(tape.start)
        for action in tape.actions[:played]:
            self.apply_action(action)
            self.advance_physics()
            self.finish_step()

    def advance_physics(self) -> None:
        """Run the substeps of one control step in a single ``mj_step`` call.

        The call releases Python's global lock for the whole control step (the batched
        environment relies on it), and the keys' sensor history still records where every key
        was after every substep.
        """
        mujoco.mj_step(self.model, self.data, nstep=self.config.substeps)

    def _instability_warnings(self) -> int:
        warning = self.data.warning
        return sum(warning[i].number for i in _INSTABILITY_WARNINGS)

    def _substep_key_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(S, 88) key angles (rad) and (S,) times (s) after each substep of the last step.

        Sensors sample at the start of a substep, so the history's newest S - 1 samples are
        the states after substeps 1..S-1 of this step, and ``qpos`` is the state after the last.
        """
        S, data = self.config.substeps, self.data
        history = data.history
        cursor = int(history[self._history_cursor])
        positions = np.empty((S, C.NUM_KEYS))
        times = np.empty(S)
        positions[:-1] = history[self._history_values[cursor]]
        times[:-1] = history[self._history_times[cursor]]
        positions[-1] = data.qpos[self._key_slice]
        times[-1] = data.time
        return positions, times

    def apply_action(self, action: np.ndarray) -> None:
        """Validate ``action`` and write it to ``data.ctrl`` and the pedal (first half of step)."""
        self._leave_tape()
        if not self._started:
            raise RuntimeError("no episode has been started: call reset() before step()")
        if self._t >= self.goal.num_frames:
            raise RuntimeError("the episode is over: call reset()")
        action = np.asarray(action, dtype=np.float64)
        if action.shape != (self.model.nu + 1,):
            raise ValueError(f"action must have shape ({self.model.nu + 1},), not {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError("action contains NaN or Inf")
        action = np.clip(action, -1.0, 1.0)
        self.data.ctrl[:] = action_to_ctrl(action[:-1], self.model.actuator_ctrlrange)
        sustain = bool(action[-1] >= 0.0)  # the pedal value (a + 1) / 2 reaches 0.5
        self._pending_events = EMPTY_EVENTS
        if sustain != self._sustain:
            self._pending_events = sustain_event(self.data.time, sustain)
        self._sustain = sustain
        self.data.userdata[0] = float(sustain)
        if self._sleep:
            self._wake_pressed_keys()

    def _wake_pressed_keys(self) -> None:
        """Wake every sleeping key that is not resting on its upper stop (see _setup_indices).

        A sleeping tree wakes when its velocity is written; the upward velocity given is far
        below what a released key reaches in a substep.
        """
        data = self.data
        asleep = data.tree_asleep[self._key_trees] >= 0
        if not asleep.any():
            return
        qpos = data.qpos[self._key_slice]
        down = qpos > KEY_REST_TOLERANCE_RAD
        # Only keys left as the last step ended: a key moved by hand since wakes by itself.
        untouched = (qpos == self._key_qpos_after_step) & (data.qvel[self.scene.key_dof] == 0.0)
        wake = asleep & down & untouched
        if wake.any():
            data.qvel[self.scene.key_dof[wake]] = -WAKE_VELOCITY_RAD_S

    def finish_step(self) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Last part of :meth:`step`, once ``data`` holds the state a control step later."""
        model, data = self.model, self.data
        # On a diverging substep MuJoCo warns and resets the state, then goes on stepping.
        if self._instability_warnings() != self._warnings_seen or not np.isfinite(data.qpos).all():
            raise SimulationUnstableError(
                f"the simulation diverged at t = {data.time:.3f} s (step {self._t}); "
                "MuJoCo reset the state"
            )
        # After mj_step, derived positions lag qpos by one substep: bring them up to date.
        mujoco.mj_kinematics(model, data)
        key_qpos, times = self._substep_key_positions()
        np.greater_equal(key_qpos, self._key_threshold, out=self._substep_active)

        events = self._pending_events
        key_ev, self._active = key_events(self._active, self._substep_active, times)
        if key_ev.size:
            events = np.concatenate([events, key_ev]) if events.size else key_ev

        t = self._t
        self._key_state = self.key_state()
        # The keys' angles as this step and the one before began (the strikes' speeds).
        starts = (self._key_qpos_before_step, self._key_qpos_after_step)
        self._key_qpos_before_step = self._key_qpos_after_step
        self._key_qpos_after_step = self.data.qpos[self._key_slice].copy()
        terms = self._reward_terms(t)
        terms["velocity"] = self._velocity_term(t, key_ev, *starts)
        reward = sum(w * terms[name] for name, w in self._weights)
        due = self.goal.keys[t]
        wrong = bool((self._active & ~due).any())
        self._t = t + 1
        terminated = self.config.wrong_press_termination and wrong
        truncated = self._t >= self.goal.num_frames and not terminated
        info = {
            "step": self._t,
            "reward_terms": terms,
            "active_keys": self._active.copy(),
            "sustain": self._sustain,
            "goal_keys": due,
            "goal_sustain": bool(self.goal.sustain[t]),
            # Plain tuples (time_s, key, on): variable length, so Gymnasium's vector envs keep
            # them as objects instead of trying to stack them. Key -1 is the sustain pedal.
            "note_events": tuple(
                (time_s, int(key), bool(on)) for time_s, key, on in events.tolist()
            ),
        }
        return self._observation(), float(reward), terminated, truncated, info

    def snapshot(self, reuse: EnvState | None = None) -> EnvState:
        """The episode's state now (a copy: later steps do not change it).

        ``reuse``: an earlier snapshot of this environment (or of a fork of it) that the
        caller will not use again: its simulator copy is overwritten and taken over by the new
        one, instead of a new one allocated (which costs ~25 times the copy; a look-ahead
        takes one or two snapshots per step)."""
        self._leave_tape()
        if reuse is not None and reuse.data.qpos.shape == self.data.qpos.shape:
            data = reuse.data
        else:
            data = mujoco.MjData(self.model)
        mujoco.mj_copyData(data, self.model, self.data)
        return EnvState(
            data=data,
            step=self._t,
            active=self._active.copy(),
            sustain=self._sustain,
            pending_events=self._pending_events.copy(),
            key_state=self._key_state.copy(),
            key_qpos_after_step=self._key_qpos_after_step.copy(),
            key_qpos_before_step=self._key_qpos_before_step.copy(),
            warnings_seen=self._warnings_seen,
        )

    def restore(self, state: EnvState) -> None:
        """Continue from a :meth:`snapshot` of this environment or of one :meth:`fork` ed from
        it (the same model): the next step is the one that followed the snapshot."""
        if state.data.qpos.shape != self.data.qpos.shape or state.step > self.goal.num_frames:
            raise ValueError("the snapshot is of another environment")
        self._tape = None
        mujoco.mj_copyData(self.data, self.model, state.data)
        self._started = True
        self._t = state.step
        self._active = state.active.copy()
        self._sustain = state.sustain
        self._pending_events = state.pending_events.copy()
        self._key_state = state.key_state.copy()
        self._key_qpos_after_step = state.key_qpos_after_step.copy()
        self._key_qpos_before_step = state.key_qpos_before_step.copy()
        self._warnings_seen = state.warnings_seen

    def fork(self, seed: int | None = None) -> PianoEnv:
        """A second environment of the same song and configuration in this one's state, for
        looking ahead: stepping it leaves this one untouched. It shares the model, scene and
        goal (read only) and has its own simulator state; it does not render. Of an
        environment with no episode started yet, the fork is reset with ``seed`` (the state
        this one's ``reset(seed=seed)`` would start from)."""
        self._leave_tape()
        other = copy.copy(self)
        other._tape = None
        other.data = mujoco.MjData(self.model)
        other._substep_active = np.zeros_like(self._substep_active)
        other._renderer = None
        other.render_mode = None
        other._np_random = copy.deepcopy(self._np_random)
        if self._started:
            other.restore(self.snapshot())
        else:
            other.reset(seed=seed)
        return other

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            height, width = self._render_size
            self._renderer = mujoco.Renderer(self.model, height=height, width=width)
        self._renderer.update_scene(self.data, camera=self._render_camera)
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ----------------------------------------------------------------------------- internals

    def key_state(self) -> np.ndarray:
        """(88,) key depression in [0, 1]."""
        return np.clip(self.data.qpos[self._key_slice], 0.0, self._key_max) / self._key_max

    def _reward_terms(self, t: int) -> dict[str, float]:
        site_xpos = self.data.site_xpos
        fingertips, targets = self._fingering_sites[t]
        return {
            "key_press": R.key_press_reward(
                self._key_state, self.goal.keys[t], self._active, self._due_keys[t]
            ),
            "fingering": self._fingering_term(site_xpos[fingertips], site_xpos[targets]),
            # Force and velocity sensors, as computed during the last substep.
            "energy": R.energy(
                self.data.sensordata[self.scene.actuator_force_sensors],
                self.data.sensordata[self.scene.actuator_velocity_sensors],
            ),
            "sustain": R.sustain_reward(bool(self.goal.sustain[t]), self._sustain),
            "forearm": R.forearm_reward(self._forearms_touch()),
        }

    def _velocity_term(
        self, t: int, events_now: np.ndarray, previous_start: np.ndarray, start: np.ndarray
    ) -> float:
        """The ``velocity`` reward term of step ``t`` (:func:`rewards.velocity_reward`): how
        far the due keys struck in it (``events_now`` (n, 3), its key events) sounded from
        the score's velocities, each strike's speed measured as the metrics measure it
        (:mod:`pianist.env.loudness`, from the keys' angles as the previous step and this
        one began, ``previous_start`` and ``start`` (88,) rad). 0 without
        ``velocity_goal``."""
        if not self.config.velocity_goal or events_now.size == 0:
            return 0.0
        struck = events_now[(events_now[:, 1] >= 0) & (events_now[:, 2] != 0)]
        keys = struck[:, 1].astype(int)
        due = self.goal.keys[t, keys]
        if not due.any():
            return 0.0
        dt = self.config.control_timestep_s
        events = struck[due].copy()
        events[:, 0] -= self.data.time - 2 * dt  # from the previous step's start
        angles = np.stack([previous_start, start, self._key_qpos_after_step])
        speeds = strike_speeds(events, angles, dt, self._key_threshold)
        played = speed_to_velocity(speeds)
        return R.velocity_reward(played, self.goal.velocities[t, keys[due]])

    @property
    def _fingering_term(self) -> Any:
        if self.config.fingering_reward == "optimal":
            return R.optimal_fingering_reward
        return R.fingering_reward

    def _forearms_touch(self) -> bool:
        if self._forearm_pair is None:
            return False
        # Contacts of the current positions (data.contact after mj_step is a substep old).
        mujoco.mj_collision(self.model, self.data)
        if self.data.ncon == 0:
            return False
        body = self.model.geom_bodyid[self.data.contact.geom]  # (ncon, 2)
        first, second = self._forearm_pair
        return bool(
            np.any(
                ((body[:, 0] == first) & (body[:, 1] == second))
                | ((body[:, 0] == second) & (body[:, 1] == first))
            )
        )

    def _observation(self) -> dict[str, np.ndarray]:
        data, t, L = self.data, self._t, self.config.lookahead
        obs: dict[str, np.ndarray] = {
            "goal": self._goal_padded[t : t + L + 1].copy(),
            "fingers_due": (
                self._finger_mask[t].copy()
                if t < self.goal.num_frames
                else np.zeros(10, np.float32)
            ),
            "piano_keys": self._key_state.astype(np.float32),
            "piano_sustain": np.array([float(self._sustain)], dtype=np.float32),
        }
        if self.config.velocity_goal:
            obs["goal_velocity"] = self._velocity_padded[t : t + L + 1].copy()
        for hand in self.scene.hands:
            p = HAND_OBS_PREFIX[hand.side]
            obs[f"{p}_joints"] = data.qpos[hand.joint_qpos].astype(np.float32)
            obs[f"{p}_fingertips"] = data.site_xpos[hand.fingertip_sites].astype(np.float32)
            obs[f"{p}_forearm"] = data.xpos[hand.forearm_body].astype(np.float32)
        return obs
