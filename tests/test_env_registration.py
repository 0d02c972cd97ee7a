"""Gymnasium ids pianist/<song>-v0 for the built-in songs."""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest

import pianist.env
from pianist.env import PianoEnv
from pianist.env.registration import env_id, register_envs
from pianist.music import list_songs


def _builtin() -> list[str]:
    suites = ("debug", "robopianist-debug", "octaves", "dynamics", "open-etude-12")
    return [song for suite in suites for song in list_songs(suite)]


def test_every_song_is_registered() -> None:
    songs = _builtin()
    assert len(songs) >= 24 and "twinkle-twinkle" in songs and "joplin-maple-leaf-rag" in songs
    assert "CMajorChordProgressionTwoHands" in songs and "block-octaves" in songs
    assert "crescendo-scale" in songs
    for song in songs:
        spec = gym.spec(f"pianist/{song}-v0")
        assert spec.kwargs["song"] == song
        assert spec.namespace == "pianist" and spec.version == 0
    assert env_id("c-major-chords") == "pianist/c-major-chords-v0"
    assert pianist.env.register_envs is register_envs


def test_register_envs_is_idempotent() -> None:
    before = {k for k in gym.registry if k.startswith("pianist/")}
    originals = [f"RoboPianist-debug-{s}-v0" for s in list_songs("robopianist-debug")]
    ids = register_envs()
    dynamics = [f"pianist/{s}-dynamics-v0" for s in _builtin()]
    assert ids == [f"pianist/{s}-v0" for s in _builtin()] + dynamics + originals
    assert {k for k in gym.registry if k.startswith("pianist/")} == before


def test_the_originals_ids_make_its_debug_songs() -> None:
    # The ids the original registers for its debug songs, as its published runs name them.
    assert gym.spec("RoboPianist-debug-CMajorScaleOneHand-v0").kwargs["song"] == (
        "CMajorScaleOneHand"
    )
    env = gym.make("RoboPianist-debug-TwinkleTwinkleLittleStar-v0", physics="fast")
    try:
        assert (
            env.unwrapped.song.name
            == gym.make("pianist/TwinkleTwinkleLittleStar-v0", physics="fast").unwrapped.song.name
        )
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    finally:
        env.close()


def test_a_step_before_reset_is_a_clear_error() -> None:
    env = PianoEnv("c-major-chords", physics="fast")
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros(env.action_space.shape, dtype=np.float32))


def test_make_and_step() -> None:
    env = gym.make("pianist/twinkle-twinkle-v0")
    try:
        assert isinstance(env.unwrapped, PianoEnv)
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        env.action_space.seed(0)
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert np.isfinite(reward) and not terminated and not truncated
        assert set(info["reward_terms"]) == {
            "key_press",
            "fingering",
            "energy",
            "sustain",
            "forearm",
            "velocity",
        }
    finally:
        env.close()


@pytest.mark.parametrize(
    ("kwargs", "check"),
    [
        ({"lookahead": 3}, lambda obs, env: obs["goal"].shape == (4, 89)),
        ({"hands": "right"}, lambda obs, env: "lh_joints" not in obs and "rh_joints" in obs),
        ({"reduced_action_space": False}, lambda obs, env: env.action_space.shape == (45,)),
    ],
    ids=["lookahead", "hands", "full-action-space"],
)
def test_make_passes_options(kwargs: dict, check: Callable[..., bool]) -> None:
    env = gym.make("pianist/c-major-scale-right-v0", **kwargs)
    try:
        obs, _ = env.reset(seed=0)
        assert check(obs, env)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_the_dynamics_variant_observes_the_scores_loudness_at_each_onset():
    from gymnasium.utils.env_checker import check_env

    from pianist.env.registration import dynamics_env_id
    from pianist.music import Note, Song

    song = Song(notes=(Note(60, 0.0, 0.3, velocity=32), Note(64, 0.1, 0.3, velocity=127)), name="d")
    env = PianoEnv(song, physics="fast", lookahead=2, velocity_goal=True)
    obs, _ = env.reset(seed=0)
    velocity = obs["goal_velocity"]
    assert velocity.shape == (3, 88) and env.observation_space["goal_velocity"].shape == (3, 88)
    assert velocity[0, 60 - 21] == pytest.approx(32 / 127)  # C4 starts at frame 0
    assert velocity[2, 64 - 21] == pytest.approx(1.0)  # E4 at frame 2
    assert np.count_nonzero(velocity) == 2  # only where notes start
    obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    assert obs["goal_velocity"][1, 64 - 21] == pytest.approx(1.0)  # one frame nearer
    check_env(PianoEnv(song, physics="fast", velocity_goal=True), skip_render_check=True)
    # Off by default: the paper's observation.
    assert "goal_velocity" not in PianoEnv(song, physics="fast").observation_space.spaces
    made = gym.make(dynamics_env_id("twinkle-twinkle"), physics="fast")
    assert "goal_velocity" in made.observation_space.spaces
    made.close()
