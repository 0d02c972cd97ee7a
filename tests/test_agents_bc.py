"""Behaviour cloning, DAgger and the multi-song environment (pianist.agents.bc,
pianist.env.multi_song)."""

import json

import numpy as np
import pytest

pytest.importorskip("jax")
minari = pytest.importorskip("minari")

from pianist.agents import bc  # noqa: E402
from pianist.cli import main  # noqa: E402
from pianist.control import make_controller  # noqa: E402
from pianist.control.planner import ENV_OPTIONS, IKPlanner  # noqa: E402
from pianist.control.registry import build_controller  # noqa: E402
from pianist.data.build import BuildSettings, build_dataset  # noqa: E402
from pianist.data.minari_io import load_dataset  # noqa: E402
from pianist.env.handle import control_handle  # noqa: E402
from pianist.env.multi_song import MultiSongEnv  # noqa: E402
from pianist.eval.session import make_env, play  # noqa: E402

SONG = "c-major-chords"  # 4 s, both hands: 81 steps an episode
DATASET = "pianist/bc-test-v0"
# Measured on SONG (2 planner episodes, (128, 128), 1500 steps, input noise 0.3, seeds 0-3):
# BC 0.47-0.83; the zero controller 0.0 and the random one 0.025. The floor sits between.
FLOOR = 0.2


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A 2-episode planner dataset of SONG, and a policy trained on it by ``pianist bc train``."""
    root = tmp_path_factory.mktemp("datasets")
    build_dataset([SONG], episodes=2, settings=BuildSettings(), dataset_id=DATASET, root=root)
    out = tmp_path_factory.mktemp("bc") / "policy"
    args = ["bc", "train", "--dataset", DATASET, "--root", str(root), "--out", str(out)]
    assert main([*args, "--hidden", "128", "128", "--steps", "1500", "--batch-size", "128"]) == 0
    return root, out


def test_bc_lowers_its_loss_on_a_fixed_batch():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((64, 30)).astype(np.float32)
    y = np.tanh(x @ rng.standard_normal((30, 5)) / 3).astype(np.float32)
    mean, std = bc.standardiser(x)
    trainer = bc.Trainer(
        bc.BCConfig(hidden_dims=(64, 64), batch_size=64, input_noise=0.0), 30, 5, mean, std
    )
    before = trainer.loss(x, y)
    losses = trainer.fit(x, y, steps=300)
    after = trainer.loss(x, y)
    assert after < 0.1 * before and losses[-1] < losses[0]
    # The NumPy policy computes what the trained network does.
    features = bc.Features.from_shapes({"goal": (1, 30)})
    policy = trainer.policy(features, {})
    mse = float(np.mean((policy.net(x) - y) ** 2))
    assert mse == pytest.approx(after, rel=1e-3, abs=1e-6)


def test_features_are_every_entry_in_sorted_order_with_the_goal_cut():
    features = bc.Features.from_shapes({"piano_keys": (3,), "goal": (4, 2), "a": (2, 2)}, 2)
    obs = {
        "piano_keys": np.array([7, 8, 9]),
        "goal": np.arange(8).reshape(4, 2),
        "a": np.array([[1, 2], [3, 4]]),
    }
    assert features.keys == ("a", "goal", "piano_keys") and features.dim == 4 + 4 + 3
    assert features(obs).tolist() == [1, 2, 3, 4, 0, 1, 2, 3, 7, 8, 9]


def test_a_tiny_dataset_trains_a_policy_that_plays_its_song(trained, capsys):
    root, out = trained
    controller = build_controller(f"bc:{out}")
    # It plays in the scene of the demonstrations (the planner's forearm slides).
    assert controller.env_options(None)["forearm_dofs"] == ENV_OPTIONS["forearm_dofs"]
    f1 = play(SONG, controller, seed=0).metrics["f1"]
    baselines = {
        name: play(SONG, make_controller(name), seed=0, env_options=dict(ENV_OPTIONS)).metrics["f1"]
        for name in ("zero", "random")
    }
    assert max(baselines.values()) < FLOOR < f1, (f1, baselines)
    # pianist bc eval plays each song in the multi-song environment: the same F1 for SONG.
    capsys.readouterr()
    assert main(["bc", "eval", str(out), "--songs", SONG, "twinkle-twinkle"]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()}
    assert rows[SONG][1:] == ["1", f"{f1:.3f}"] and "twinkle-twinkle" in rows
    saved = json.loads((out / bc.CONFIG_FILE).read_text())
    assert saved["info"]["dataset"] == DATASET and saved["info"]["steps"] == 162


@pytest.mark.slow
def test_dagger_labels_are_the_planners_actions_in_the_states_the_policy_visits(trained):
    _, out = trained
    policy = bc.load_policy(out)
    rollout = bc.labelled_rollout(policy, SONG, seed=0)
    T = len(rollout.actions)
    assert rollout.labels.shape == rollout.actions.shape == (T, 41)
    # Replaying the policy's actions in a fresh environment, a fresh planner proposes exactly
    # the labels: they are the planner's actions in the states the policy brought about.
    env = make_env(SONG, bc.BCController(policy))
    obs, _ = env.reset(seed=0)
    planner = IKPlanner()
    planner.reset(env, seed=0)
    for t in range(T):
        np.testing.assert_array_equal(planner.act(obs), rollout.labels[t])
        np.testing.assert_array_equal(policy.act(obs), rollout.actions[t])
        obs, *_ = env.step(rollout.actions[t])
    # The played actions are the policy's, not the planner's.
    assert np.abs(rollout.actions - rollout.labels).max() > 0.1
    # A round adds every state it visited to the data, labelled.
    root, _ = trained
    data = bc.demonstrations(bc.minari_episodes(load_dataset(DATASET, root)))
    before = len(data.x)
    config = bc.BCConfig(hidden_dims=(16,), steps=5)
    _, history = bc.dagger(data, [SONG], 1, config, dict(ENV_OPTIONS))
    assert len(data.x) == before + T and history[0]["steps"] == before + T
    assert 0.0 <= history[0]["f1"][SONG] <= 1.0
    # Songs played in worker processes give the same rollouts, in song order.
    songs = [SONG, "twinkle-twinkle"]
    alone = list(bc.labelled_rollouts(policy, songs, seed=0))
    pooled = list(bc.labelled_rollouts(policy, songs, seed=0, workers=2))
    assert [r.song for r in pooled] == [r.song for r in alone] == songs
    for a, b in zip(alone, pooled, strict=True):
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.labels, b.labels)


def test_multi_song_env_samples_every_song_with_the_same_spaces():
    songs = ["c-major-chords", "twinkle-twinkle", "c-major-scale-right"]
    env = MultiSongEnv(songs, forearm_dofs=("tx", "ty", "tz"), lookahead=2)
    seen = []
    for i in range(12):
        obs, info = env.reset(seed=3 if i == 0 else None)
        seen.append(info["song"])
        # The controllers' view is the drawn song's environment, whose spaces are the env's.
        assert control_handle(env).song.name == info["song"]
        assert env.env.observation_space == env.observation_space
        assert env.env.action_space == env.action_space
        assert env.observation_space.contains(obs)
        env.step(env.action_space.sample())
    assert set(seen) == set(songs)
    # Seeded: the same seed draws the same songs.
    again = [env.reset(seed=3)[1]["song"]] + [env.reset()[1]["song"] for _ in range(11)]
    assert again == seen
    assert env.reset(options={"song": "twinkle-twinkle"})[1]["song"] == "twinkle-twinkle"
    with pytest.raises(ValueError, match="not one of"):
        env.reset(options={"song": "nope"})
    env.close()


def test_bad_input_is_refused_in_one_line(tmp_path, capsys):
    args = ["bc", "train", "--dataset", "pianist/none-v0", "--root", str(tmp_path)]
    assert main([*args, "--out", str(tmp_path / "p")]) == 1
    assert "no dataset pianist/none-v0" in capsys.readouterr().err
    assert main(["play", SONG, "--controller", f"bc:{tmp_path}", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no behaviour-cloning policy" in err


def test_bc_train_refuses_what_would_lose_data_or_write_garbage(trained, tmp_path, capsys):
    root, policy = trained
    base = ["bc", "train", "--dataset", DATASET, "--root", str(root), "--steps", "20"]
    # An --out holding anything but an earlier policy is refused, and left as it was.
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    afile = tmp_path / "afile"
    afile.write_text("keep me too")
    for out, message in ((other, "holds other files (notes.txt)"), (afile, "is a file")):
        assert main([*base, "--out", str(out)]) == 1
        assert message in capsys.readouterr().err
    assert (other / "notes.txt").read_text() == "keep me" and afile.read_text() == "keep me too"
    assert main([*base, "--out", str(tmp_path.parent)]) == 1  # above the working folder
    assert "working folder or above it" in capsys.readouterr().err
    # A non-finite setting, a negative seed and an unknown DAgger song fail before training.
    bad = [
        (["--learning-rate", "inf"], "--learning-rate must be a finite number > 0"),
        (["--input-noise", "inf"], "--input-noise must be a finite number >= 0"),
        (["--seed", "-1"], "--seed must be >= 0"),
        (["--dagger-rounds", "1", "--songs", "no-such-song"], "unknown song"),
    ]
    for extra, message in bad:
        assert main([*base, *extra, "--out", str(tmp_path / "new")]) == 1
        captured = capsys.readouterr()
        assert message in captured.err and "steps" not in captured.out  # nothing trained
        assert not (tmp_path / "new").exists()
    # An earlier policy's folder is replaced whole.
    again = tmp_path / "again"
    assert main([*base, "--out", str(again)]) == 0
    assert main([*base, "--out", str(again)]) == 0
    assert sorted(p.name for p in again.iterdir()) == [bc.CONFIG_FILE, bc.WEIGHTS_FILE]
    capsys.readouterr()


def test_a_damaged_dataset_and_a_scene_dagger_cannot_label_are_one_line(trained, tmp_path):
    import shutil

    root, _ = trained
    damaged_root = tmp_path / "datasets"
    shutil.copytree(root, damaged_root)
    (hdf5,) = (damaged_root / DATASET / "data").glob("*.hdf5")
    data = bytearray(hdf5.read_bytes())
    # The middle third: HDF5's own structures and chunks, past the superblock it opens with.
    start, end = len(data) // 3, 2 * len(data) // 3
    data[start:end] = np.random.default_rng(0).bytes(end - start)
    hdf5.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="cannot be read"):
        dataset = load_dataset(DATASET, str(damaged_root))  # a str root, as documented
        bc.demonstrations(bc.minari_episodes(dataset))
    # DAgger's teacher plays in the planner's scene: demonstrations from another are refused.
    dataset = load_dataset(DATASET, root)
    data = bc.demonstrations(bc.minari_episodes(dataset))
    with pytest.raises(ValueError, match="build the dataset with the planner"):
        bc.dagger(data, [SONG], 1, bc.BCConfig(steps=1), {"forearm_dofs": ("tx", "ty")})
