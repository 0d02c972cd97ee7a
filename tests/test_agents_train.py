"""Training end to end on a tiny network: logs, checkpoints, resume, trained policies."""

import dataclasses
import json

import numpy as np
import pytest

from pianist.agents import PolicyController, get_preset, rundir, train
from pianist.agents import checkpoint as ckpt
from pianist.agents.checkpoint import latest_checkpoint
from pianist.agents.envs import TARGET_SCALE, Featurizer, make_agent_env
from pianist.agents.replay import ReplayBuffer
from pianist.eval import run_episode

SONG = "twinkle-twinkle"  # one hand: the "fast" task simulates only the right hand
STEPS = 330  # two episodes of 161 steps and the start of a third
BASE = get_preset("fast")
TINY = dataclasses.replace(
    BASE,
    agent=dataclasses.replace(BASE.agent, hidden_dims=(16, 16), batch_size=16),
    seed_steps=100,
    steps_per_iteration=1,  # one compiled update size; the fast preset's pipeline stays on
    eval_interval=200,
    checkpoint_interval=150,
    replay_capacity=2000,
)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    train(SONG, TINY, STEPS, out, progress=False)
    return out


def _rows(path, kind):
    rows = [json.loads(x) for x in (path / "log.jsonl").read_text().splitlines()]
    return [
        {k: v for k, v in r.items() if k not in ("wall_s", "steps_per_s")}
        for r in rows
        if r["kind"] == kind
    ]


def test_a_short_run_logs_evaluates_and_checkpoints(run_dir):
    config = json.loads((run_dir / "config.json").read_text())
    assert config["song"] == SONG and config["config"]["agent"]["hidden_dims"] == [16, 16]
    evals = _rows(run_dir, "eval")
    assert [r["step"] for r in evals] == [200, STEPS]
    for r in evals:
        assert 0 <= r["f1"] <= 1 and {"precision", "recall", "sustain_f1", "return"} <= set(r)
    assert [r["step"] for r in _rows(run_dir, "episode")] == [161, 322]
    assert latest_checkpoint(run_dir).name == f"step_{STEPS:09d}"


def test_resume_after_an_interruption_matches_the_uninterrupted_run(run_dir, tmp_path):
    out = tmp_path / "resumed"
    first = train(SONG, TINY, STEPS, out, progress=False, stop_after_s=0.0)
    assert first.step == 161  # stopped at the first episode end, after checkpointing
    notes = []
    second = train(None, None, STEPS, out, resume=True, progress=False, message=notes.append)
    assert second.resumed_from == 161 and "from step 161" in notes[0]
    for kind in ("episode", "train"):
        assert _rows(out, kind) == _rows(run_dir, kind)
    assert [r for r in _rows(out, "eval") if r["step"] > 161] == _rows(run_dir, "eval")
    a = np.load(latest_checkpoint(run_dir) / "agent.npz")
    b = np.load(latest_checkpoint(out) / "agent.npz")
    for key in a.files:
        np.testing.assert_array_equal(a[key], b[key])


def test_a_trained_policy_acts_the_same_after_loading(run_dir):
    controller = PolicyController(run_dir)
    assert controller.step == STEPS
    env = controller.make_env(SONG)
    episode = run_episode(env, controller, seed=0)
    again = run_episode(env, PolicyController(run_dir), seed=0)
    np.testing.assert_array_equal(episode.actions, again.actions)
    logged = _rows(run_dir, "eval")[-1]
    assert episode.metrics()["f1"] == pytest.approx(logged["f1"])
    assert episode.metrics()["return"] == pytest.approx(logged["return"])


def test_evaluations_choose_the_kept_policy_in_the_evaluation_physics(run_dir):
    # The fast preset trains on fast physics and evaluates on the faithful one, where pieces
    # are judged: the logged F1s, the best policy kept, and `pianist eval`'s default are all
    # in the faithful physics; asked for, the policy still plays on fast.
    assert TINY.task.physics == "fast" and TINY.eval_physics == "faithful"
    kept = PolicyController(run_dir / "best")
    env = kept.make_env(SONG)
    assert env.unwrapped.config.scene.physics == "faithful"
    best = ckpt.best_evaluation(run_dir)
    assert best is not None and kept.step == best["step"]
    # The return tells the two physics apart where a barely trained policy's F1 does not.
    faithful = run_episode(env, kept, seed=0).metrics()
    assert (faithful["f1"], faithful["return"]) == pytest.approx((best["f1"], best["return"]))
    on_fast = PolicyController(run_dir / "best", physics="fast")
    fast_env = on_fast.make_env(SONG)
    assert fast_env.unwrapped.config.scene.physics == "fast"
    assert run_episode(fast_env, on_fast, seed=0).metrics()["return"] != pytest.approx(
        best["return"]
    )
    with pytest.raises(ValueError, match="eval_physics"):
        dataclasses.replace(TINY, eval_physics="slow")


def test_a_policy_needs_its_own_environment(run_dir):
    import pianist

    with pytest.raises(ValueError, match="make_env"):
        PolicyController(run_dir).reset(pianist.make_env(SONG, physics="fast", hands="right"))


def test_missing_or_corrupt_checkpoints_are_clear_errors(run_dir, tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        PolicyController(tmp_path / "nothing")
    (tmp_path / "config.json").write_text((run_dir / "config.json").read_text())
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        PolicyController(tmp_path)
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "config.json").write_text((run_dir / "config.json").read_text())
    (broken / "checkpoints" / "step_000000001").mkdir(parents=True)
    (broken / "checkpoints" / "latest.json").write_text('{"dir": "step_000000001", "step": 1}')
    (broken / "checkpoints" / "step_000000001" / "policy.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="corrupt"):
        PolicyController(broken)
    with pytest.raises(ValueError, match="already holds a run"):
        train(SONG, TINY, STEPS, run_dir, progress=False)


def test_compact_goal_points_each_due_finger_at_its_key():
    env = make_agent_env(SONG, TINY.task)
    assert [h.side for h in env.scene.hands] == ["right"]
    obs, _ = env.reset(seed=0)
    for _ in range(30):
        obs, *_ = env.step(np.zeros(env.action_space.shape, np.float32))
    t = env.step_index
    targets = obs["finger_targets"]  # (n, 5, 4)
    assert targets.shape == (TINY.task.finger_target_frames, 5, 4)
    fingers = env.goal.fingers[t]
    due = {int(fingers[k]): k for k in np.flatnonzero(fingers >= 0)}
    assert due, "the song has a note due at this frame"
    key_xyz = env.data.site_xpos[env.scene.key_sites]
    for finger in range(5):
        assert targets[0, finger, 0] == (finger in due)
        if finger in due:
            tip = obs["rh_fingertips"][finger]
            # Targets are taken with the keys at rest; the key may be pressed a little now.
            np.testing.assert_allclose(
                targets[0, finger, 1:], (key_xyz[due[finger]] - tip) * TARGET_SCALE, atol=0.05
            )
        else:
            assert not targets[0, finger, 1:].any()
    features = Featurizer(env, TINY.task)
    assert features(obs).shape == (features.obs_dim,)
    assert obs["prev_action"].shape == env.action_space.shape and obs["prev_reward"].shape == (1,)


def test_residual_actions_add_the_scaled_agent_action_to_the_planner():
    task = get_preset("residual").task
    env = make_agent_env(SONG, task)
    features = Featurizer(env, task)
    obs, _ = env.reset(seed=0)
    features.reset(env, 0)
    x = features(obs)
    A = env.action_space.shape[0]
    assert features.obs_dim == x.shape[0] and np.array_equal(x[-A:], features._base)
    a = np.linspace(-1, 1, A, dtype=np.float32)
    expected = np.clip(x[-A:] + task.residual_scale * a, -1, 1)
    np.testing.assert_allclose(features.env_action(a), expected)


def test_replay_keeps_episodes_apart_across_the_wrap():
    buffer = ReplayBuffer(obs_dim=1, action_dim=1, capacity=5)
    value = 0.0
    for length in (3, 4):  # 2 episodes: 4 + 5 observations in 5 slots
        buffer.start_episode(np.array([value]))
        for _ in range(length):
            value += 1
            buffer.add(np.array([value]), value, 1.0, np.array([value]))
        value += 100
    batch = buffer.sample(np.random.default_rng(0), 64)
    # Every transition's next observation is its own action value (set above), never another
    # episode's first observation.
    np.testing.assert_array_equal(batch.next_obs, batch.action)
    assert buffer.transitions == 4
    restored = ReplayBuffer(1, 1, 5)
    restored.load_arrays(buffer.state_arrays())
    again = restored.sample(np.random.default_rng(0), 64)
    np.testing.assert_array_equal(again.obs, batch.obs)


def test_the_run_directory_layout(run_dir):
    assert rundir.config_path(run_dir) == run_dir / "config.json"
    assert rundir.log_path(run_dir) == run_dir / "log.jsonl"
    assert rundir.latest_pointer(run_dir) == run_dir / "checkpoints" / "latest.json"
    assert rundir.checkpoint_name(STEPS) == f"step_{STEPS:09d}"
    assert rundir.holds_run(run_dir) and (rundir.best_dir(run_dir) / "config.json").is_file()
    assert rundir.read_run_config(rundir.best_dir(run_dir)) == rundir.read_run_config(run_dir)


def test_truncating_the_log_keeps_rows_up_to_the_checkpoint(tmp_path):
    with rundir.RunLog(tmp_path) as log:
        for step in (10, 20, 30):
            log.write({"kind": "episode", "step": step})
    with rundir.log_path(tmp_path).open("a") as f:
        f.write('{"kind": "eval", "st')  # a row cut by a crash
    rundir.truncate_log(tmp_path, 20)
    rows = [json.loads(x) for x in rundir.log_path(tmp_path).read_text().splitlines()]
    assert [r["step"] for r in rows] == [10, 20]
    rundir.truncate_log(tmp_path, 0)
    assert rundir.log_path(tmp_path).read_text() == ""
    rundir.remove_log(tmp_path)
    rundir.truncate_log(tmp_path, 0)  # no log: nothing to do
    assert not rundir.log_path(tmp_path).exists()


def test_unusable_run_configurations_are_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        rundir.read_run_config(tmp_path / "nothing")
    with pytest.raises(FileNotFoundError, match="no config.json"):
        rundir.read_run_config(tmp_path)
    rundir.write_run_config(tmp_path, {"song": SONG})
    with pytest.raises(ValueError, match="not a valid run configuration"):
        rundir.read_run_config(tmp_path)


def test_a_midi_file_without_fingering_trains_as_the_fingered_song(tmp_path):
    # A MIDI file carries no fingering: the task estimates it, as `pianist play` does, so the
    # file's task is the song's (one hand, fingered), not both hands with nothing to follow.
    from pianist.music import get_song, strip_fingering, write_midi

    path = tmp_path / "twinkle.mid"
    write_midi(strip_fingering(get_song(SONG)), path)
    from_file = make_agent_env(str(path), BASE.task)
    by_name = make_agent_env(SONG, BASE.task)
    assert from_file.action_space.shape == by_name.action_space.shape == (20,)
    goal = from_file.unwrapped.goal
    assert np.all(goal.fingers[goal.keys] >= 0)
    assert Featurizer(from_file, BASE.task).obs_dim == Featurizer(by_name, BASE.task).obs_dim


def test_a_policy_plays_a_midi_file_without_fingering_in_its_task(run_dir, tmp_path):
    from pianist.music import get_song, strip_fingering, write_midi

    path = tmp_path / "twinkle.mid"
    write_midi(strip_fingering(get_song(SONG)), path)
    policy = PolicyController(run_dir)
    env = policy.make_env(str(path))  # the file's fingers estimated, as in training
    assert env.action_space.shape == policy.make_env(SONG).action_space.shape
    assert 0.0 <= run_episode(env, policy, seed=0).metrics()["f1"] <= 1.0
