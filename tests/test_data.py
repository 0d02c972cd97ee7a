"""Demonstration datasets: recorded episodes written as Minari datasets and read back."""

import json
from pathlib import Path

import minari
import numpy as np
import pytest

from pianist.cli import main
from pianist.control import make_controller
from pianist.control.base import BaseController
from pianist.data import build as build_module
from pianist.data.build import BuildSettings, build_dataset, resolve_songs, work_dir
from pianist.data.record import read_episode, song_provenance
from pianist.eval.session import play

SONG = "c-major-chords"  # 4 s, two hands: the shortest debug song


def test_dataset_round_trip_matches_the_played_episode(tmp_path, monkeypatch, capsys):
    root = tmp_path / "datasets"
    report = build_dataset(
        [SONG],
        episodes=2,
        settings=BuildSettings(controller="planner", noise=0.02, seed=3),
        dataset_id="pianist/round-trip-v0",
        root=root,
        workers=2,  # the two episodes in two spawned processes
    )
    assert report.recorded == 2 and report.skipped == 0
    assert not (root / build_module.WORK_FOLDER).exists()  # removed once the dataset exists

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    dataset = minari.load_dataset("pianist/round-trip-v0")
    assert dataset.total_episodes == 2
    first, second = dataset[0], dataset[1]

    # Episode 0 is the planner as it plays, noiseless, with the first seed.
    played = play(SONG, make_controller("planner"), seed=3, record_observations=True)
    episode = played.episode
    T = episode.num_steps
    assert len(first) == T and first.actions.shape == episode.actions.shape
    np.testing.assert_array_equal(first.actions, episode.actions)
    np.testing.assert_array_equal(first.rewards, episode.rewards)
    observations = episode.extra["observations"]
    assert set(first.observations) == set(observations)
    for name, values in observations.items():
        assert first.observations[name].shape[0] == T + 1
        np.testing.assert_array_equal(first.observations[name], values)
    np.testing.assert_array_equal(first.infos["active_keys"], episode.active_keys)
    np.testing.assert_array_equal(first.infos["goal_keys"], episode.goal_keys)
    np.testing.assert_array_equal(first.infos["sustain"], episode.sustain)
    for name, values in episode.reward_terms.items():
        np.testing.assert_array_equal(first.infos["reward_terms"][name], values)
    assert first.truncations[-1] and not first.truncations[:-1].any()
    assert not first.terminations.any()

    metas = list(dataset.storage.get_episode_metadata([0, 1]))
    assert metas[0]["f1"] == pytest.approx(played.metrics["f1"])
    assert (metas[0]["seed"], metas[0]["noise"]) == (3, 0.0)
    assert (metas[1]["seed"], metas[1]["noise"]) == (4, 0.02)
    assert json.loads(metas[0]["provenance"])["suite"] == "debug"
    # Episode 1 has noise: another demonstration of the same song.
    assert not np.array_equal(second.actions, first.actions)
    pianist_meta = dataset.storage.metadata["pianist"]
    assert pianist_meta["songs"][SONG]["name"] == SONG
    assert pianist_meta["settings"]["controller"] == "planner"

    assert main(["dataset", "info", "pianist/round-trip-v0", "--root", str(root)]) == 0
    out = capsys.readouterr().out
    mean_f1 = (metas[0]["f1"] + metas[1]["f1"]) / 2
    assert f"2 episodes, {2 * T} steps, mean F1 {mean_f1:.3f}" in out


def test_rerun_records_only_missing_episodes(tmp_path, monkeypatch):
    root = tmp_path / "datasets"
    dataset_id = "pianist/resume-v0"
    settings = BuildSettings(noise=0.02)
    record = build_module.record_episode

    def second_fails(song, controller, seed, *args, **kwargs):
        if seed == 1:
            raise ValueError("the simulation became unstable")  # stands for any failure
        return record(song, controller, seed, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(build_module, "record_episode", second_fails)
        with pytest.raises(ValueError, match="1 of 2 episodes failed.*unstable"):
            build_dataset([SONG], episodes=2, settings=settings, dataset_id=dataset_id, root=root)
    episodes = work_dir(dataset_id, root) / "episodes"
    kept = episodes / f"{SONG}--0000"
    assert kept.is_dir() and not (episodes / f"{SONG}--0001").exists()
    assert not (root / dataset_id).exists()  # no dataset until every episode exists
    recorded_first = read_episode(kept)

    # Other settings would mix two kinds of episodes: refused before anything is played.
    with pytest.raises(ValueError, match="other settings"):
        build_dataset(
            [SONG], episodes=2, settings=BuildSettings(noise=0.05), dataset_id=dataset_id, root=root
        )

    played: list[tuple[str, int]] = []

    def counted(song, controller, seed, *args, **kwargs):
        played.append((song, seed))
        return record(song, controller, seed, *args, **kwargs)

    monkeypatch.setattr(build_module, "record_episode", counted)
    lines: list[str] = []
    report = build_dataset(
        [SONG], episodes=2, settings=settings, dataset_id=dataset_id, root=root, log=lines.append
    )
    assert (report.recorded, report.skipped, report.episodes) == (1, 1, 2)
    assert "1 already recorded, 1 to record" in lines[0]
    assert played == [(SONG, 1)]  # episode 0 (seed 0) was not played again
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    dataset = minari.load_dataset(dataset_id)
    assert dataset.total_episodes == 2
    np.testing.assert_array_equal(dataset[0].actions, recorded_first.actions)


def test_a_damaged_recorded_episode_is_named_with_what_to_do(tmp_path, monkeypatch):
    from pianist.data.record import ARRAYS_FILE
    from pianist.sweep.datasets import assemble_sweep

    root = tmp_path / "datasets"
    dataset_id = "pianist/damaged-v0"
    record = build_module.record_episode

    def second_fails(song, controller, seed, *args, **kwargs):
        if seed == 1:
            raise ValueError("stands for any failure")
        return record(song, controller, seed, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(build_module, "record_episode", second_fails)
        with pytest.raises(ValueError, match="1 of 2 episodes failed"):
            build_dataset([SONG], episodes=2, dataset_id=dataset_id, root=root)
    kept = work_dir(dataset_id, root) / "episodes" / f"{SONG}--0000"
    (kept / ARRAYS_FILE).write_bytes(b"PK\x03\x04 cut short")  # a write cut off by a crash
    with pytest.raises(ValueError, match=f"delete {kept} and build again"):
        build_dataset([SONG], episodes=2, dataset_id=dataset_id, root=root)
    with pytest.raises(FileNotFoundError, match="no sweep folder"):
        assemble_sweep(tmp_path / "no-sweep", "pianist/x-v0", root)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--songs", "no-such-suite"], "is not a suite"),
        (["--songs", "debug", "--episodes", "0"], "--episodes must be >= 1"),
        (["--songs", "debug", "--out", "no version"], "is not a Minari id"),
        (["--songs", "debug", "--root", "FILE/datasets"], "cannot create output directory"),
    ],
)
def test_bad_input_is_refused_in_one_line(tmp_path, capsys, args, message):
    blocker = tmp_path / "FILE"
    blocker.write_text("a file where a folder should be")
    args = [a.replace("FILE", str(blocker)) for a in args]
    if "--root" not in args:
        args += ["--root", str(tmp_path / "datasets")]
    assert main(["dataset", "build", *args]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pianist: error:") and message in err[0]
    assert not (tmp_path / "datasets" / "pianist").exists()  # nothing written


def test_folder_songs_and_their_provenance(tmp_path):
    from pianist.music import get_song, load_song, write_midi, write_pig

    folder = tmp_path / "midi"
    folder.mkdir()
    write_midi(get_song("c-major-chords"), folder / "chords.mid")
    write_midi(get_song("twinkle-twinkle"), folder / "twinkle.mid")
    write_pig(get_song("c-major-scale-right"), folder / "scale.txt")  # PIG: fingered
    (folder / "notes.md").write_text("not a song of the folder")
    refs = resolve_songs([str(folder)])
    assert [Path(r).name for r in refs] == ["chords.mid", "scale.txt", "twinkle.mid"]
    assert load_song(refs[1]).notes == get_song("c-major-scale-right").notes
    file_info = song_provenance(refs[0])
    assert file_info["suite"] is None and len(file_info["sha256"]) == 64
    assert file_info["fingering"].startswith("automatic")  # MIDI files carry no fingers
    piece = song_provenance("bach-prelude-c-major-bwv846")
    assert piece["suite"] == "open-etude-12" and piece["composer"] == "Johann Sebastian Bach"
    assert "licence" in piece and "fingering" in piece
    with pytest.raises(ValueError, match="no song files"):
        resolve_songs([str(tmp_path)])


class _AddsEntry(BaseController):
    """A controller whose environment wrapper adds an observation entry in place, as a
    trained policy's task does (the recorder sits inside it and must not see the entry)."""

    def wrap_env(self, env):
        import gymnasium as gym

        class Adds(gym.Wrapper):
            def reset(self, **kwargs):
                obs, info = self.env.reset(**kwargs)
                obs["extra"] = np.zeros(1, np.float32)
                return obs, info

            def step(self, action):
                obs, *rest = self.env.step(action)
                obs["extra"] = np.zeros(1, np.float32)
                return (obs, *rest)

        return Adds(env)

    def reset(self, env, seed=None):
        self.size = env.action_space.shape

    def act(self, observation):
        assert "extra" in observation  # the controller sees its own wrapper's entries
        return np.zeros(self.size, np.float32)


def test_observations_are_the_environments_own_under_a_noisy_wrapped_controller():
    from pianist.control import NoisyController

    result = play(SONG, NoisyController(_AddsEntry(), 0.01), seed=0, record_observations=True)
    observations = result.episode.extra["observations"]
    assert "extra" not in observations and "piano_keys" in observations
    assert observations["piano_keys"].shape == (result.episode.num_steps + 1, 88)
    assert np.abs(result.episode.actions).max() > 0  # the noise was applied
    plain = play(SONG, _AddsEntry(), seed=0)
    assert "observations" not in plain.episode.extra  # recorded only when asked
