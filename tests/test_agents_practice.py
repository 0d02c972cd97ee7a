"""Practice: a correction per step learned by replaying a piece with the refiner."""

import dataclasses
import json
import time

import numpy as np
import pytest

from pianist.agents.practice import (
    CorrectedPlanner,
    PracticeConfig,
    _practice_pass,
    goal_fingerprint,
    load_practice,
    practise,
    same_goal,
    save_practice,
    write_practice_config,
)
from pianist.cli import main
from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.control.refine import RefineOptions
from pianist.control.registry import build_controller
from pianist.eval.session import play
from pianist.music import goal_frames, load_song
from pianist.music.transforms import window

# The opening of a chorale, where the planner alone lets keys flicker and strikes late, so
# looking ahead has something to correct.
SONG = window(load_song("bach-chorale-bwv66-6"), 0.0, 2.0)
FAST = PracticeConfig(passes=2, physics="fast", schedule=(RefineOptions(candidates=4),))


@pytest.fixture(scope="module")
def practised():
    return practise(SONG, FAST)


def test_a_zero_table_plays_the_planners_actions():
    alone = play(SONG, IKPlanner(), physics="fast")
    table = np.zeros_like(alone.episode.actions, dtype=np.float64)
    corrected = play(SONG, CorrectedPlanner(table), physics="fast")
    np.testing.assert_array_equal(alone.episode.actions, corrected.episode.actions)


def test_practice_keeps_the_best_pass_and_its_table_replays_it_exactly(practised):
    history = practised.history
    assert [row["pass"] for row in history] == [0, 1, 2]
    # Pass 0 is the planner alone with each hand plan; the best played is practised.
    plan = practised.hand_planning
    played = {
        p: play(
            SONG, IKPlanner(PlannerConfig().with_fields(hand_planning=p)), physics="fast"
        ).metrics["f1"]
        for p in FAST.plans
    }
    assert history[0]["plan_f1"] == pytest.approx(played)
    assert history[0]["hand_planning"] == plan and played[plan] == max(played.values())
    planner_f1 = played[plan]
    assert history[0]["f1"] == pytest.approx(planner_f1)
    assert practised.f1 == max(row["f1"] for row in history)
    assert practised.f1 > planner_f1  # the look-ahead found something on this passage
    assert history[practised.pass_index]["f1"] == practised.f1
    # A pass simulates the piece once and every step's look-aheads (4 candidates, the
    # combined one and the proposal, 4 steps each at most).
    steps = practised.table.shape[0]
    for row in history[1:]:
        assert steps < row["env_steps"] <= steps * (1 + 6 * 4)
    # The table is a correction of the fingers (the refiner perturbs nothing else) ...
    planner = IKPlanner()
    corrected = CorrectedPlanner(practised.table, physics="fast", hand_planning=plan)
    replay = play(SONG, corrected, physics="fast")
    assert replay.metrics["f1"] == practised.f1  # ... and replays the best pass exactly.
    planner_dims = set(np.flatnonzero(np.abs(practised.table).max(axis=0) > 1e-6))
    play(SONG, planner, physics="fast")
    assert planner_dims and planner_dims <= set(planner.finger_action_dims().tolist())


def test_the_practised_plan_is_kept_with_its_table(tmp_path, practised):
    # This chorale opening plays better with both hands planned together than with the
    # planner's default choice: practice takes that plan, saves it with the table, and the
    # table is replayed with it (with the default plan it plays something else).
    assert practised.history[0]["plan_f1"]["split"] > practised.history[0]["plan_f1"]["best"]
    assert practised.hand_planning == "split"
    save_practice(tmp_path, practised, FAST)
    loaded = CorrectedPlanner.load(tmp_path)
    assert loaded.config.plan.hand_planning == "split"
    assert play(SONG, loaded, physics="fast").metrics["f1"] == practised.f1
    default = CorrectedPlanner(practised.table, physics="fast")
    assert play(SONG, default, physics="fast").metrics["f1"] != practised.f1
    # One plan only: that one.
    only = practise(SONG, dataclasses.replace(FAST, passes=1, plans=("best",)))
    assert only.hand_planning == "best" and list(only.history[0]["plan_f1"]) == ["best"]


def test_a_table_saved_before_plans_were_chosen_loads_with_the_default(tmp_path, practised):
    save_practice(tmp_path, practised, FAST)
    with np.load(tmp_path / "practice.npz") as data:
        arrays = {name: data[name] for name in data.files if name != "hand_planning"}
    np.savez(tmp_path / "practice.npz", **arrays)
    assert CorrectedPlanner.load(tmp_path).config.plan.hand_planning == "best"
    write_practice_config(tmp_path, "chorale", FAST)
    assert load_practice(tmp_path)[2].hand_planning == "best"


def test_a_table_is_refused_for_another_piece(practised):
    other = window(load_song("bach-chorale-bwv66-6"), 2.0, 4.0)
    planner = CorrectedPlanner(practised.table, fingerprint=practised.fingerprint)
    with pytest.raises(ValueError, match="another piece"):
        play(other, planner, physics="fast")
    env_goal = play(SONG, IKPlanner(), physics="fast").goal
    assert goal_fingerprint(env_goal) == practised.fingerprint


def test_a_resumed_run_goes_on_as_an_uninterrupted_one(tmp_path, practised):
    one = practise(SONG, dataclasses.replace(FAST, passes=1))
    write_practice_config(tmp_path, "chorale", FAST)
    save_practice(tmp_path, one, FAST)
    song, config, start = load_practice(tmp_path)
    assert (song, config) == ("chorale", FAST)
    resumed = practise(SONG, config, start=start)
    assert [r["f1"] for r in resumed.history] == [r["f1"] for r in practised.history]
    np.testing.assert_array_equal(resumed.table, practised.table)
    assert resumed.pass_index == practised.pass_index


def test_with_no_pass_limit_the_budget_ends_the_practice():
    unlimited = dataclasses.replace(FAST, passes=None, plans=("best",))
    with pytest.raises(ValueError, match="wall-clock budget"):
        practise(SONG, unlimited)
    # The first pass always runs; no pass starts with less time left than the planner
    # takes to play the piece: here the budget is gone at once.
    result = practise(SONG, unlimited, stop_after_s=1e-3)
    assert [row["pass"] for row in result.history] == [0]


def test_a_pass_that_runs_into_the_budget_stops_looking_ahead_and_keeps_its_table():
    first = practise(SONG, dataclasses.replace(FAST, passes=None, plans=("best",)), stop_after_s=0)
    table, fingerprint = first.table, first.fingerprint  # the planner's: no corrections
    options = dataclasses.replace(FAST, passes=1).options(1, 0)
    past = time.time() - 1.0
    new_table, metrics, refined = _practice_pass(
        SONG, table, fingerprint, "fast", options, [0, 1, 0], "best", past
    )
    assert refined == 0.0  # no step looked ahead
    np.testing.assert_allclose(new_table, table, atol=1e-6)  # the table played as it was
    live, _, refined_live = _practice_pass(SONG, table, fingerprint, "fast", options, [0, 1, 0])
    assert refined_live > 0 and not np.allclose(live, table, atol=1e-6)


def test_practice_keeps_to_its_budget():
    unlimited = dataclasses.replace(FAST, passes=None, plans=("best",))
    started = time.perf_counter()
    result = practise(SONG, unlimited, stop_after_s=6.0)
    elapsed = time.perf_counter() - started
    planner_s = result.history[0]["seconds"]
    assert len(result.history) >= 2
    assert elapsed <= 6.0 + planner_s + 1.0, (elapsed, planner_s)


def test_train_minutes_without_passes_is_a_budget_not_the_default_passes(tmp_path, capsys):
    run = tmp_path / "run"
    args = ["train", "twinkle-twinkle", "--preset", "practice", "--physics", "fast"]
    assert main([*args, "--minutes", "0.001", "--out", str(run), "--no-progress"]) == 0
    assert load_practice(run)[1].passes is None
    # Resumed with --passes, that is the limit again.
    assert main(["train", "--resume", str(run), "--passes", "2", "--no-progress"]) == 0
    assert load_practice(run)[1].passes == 2
    assert [json.loads(r)["pass"] for r in (run / "log.jsonl").read_text().splitlines()] == [
        0,
        1,
        2,
    ]
    capsys.readouterr()


def test_bad_practice_settings_are_refused():
    with pytest.raises(ValueError, match="at least 1 pass"):
        PracticeConfig(passes=0)
    with pytest.raises(ValueError, match="unknown physics"):
        PracticeConfig(physics="slow")
    with pytest.raises(ValueError, match="at least 1 worker"):
        PracticeConfig(workers=0)
    with pytest.raises(ValueError, match="schedule"):
        PracticeConfig(schedule=())
    with pytest.raises(ValueError, match=r"\(T, A\)"):
        CorrectedPlanner(np.zeros(3))
    with pytest.raises(ValueError, match="practice plans"):
        PracticeConfig(plans=("sideways",))
    with pytest.raises(ValueError, match="practice plans"):
        PracticeConfig(plans=())


def test_train_practice_then_eval_and_play_it(tmp_path, capsys, monkeypatch):
    song = tmp_path / "song.mid"
    from pianist.music.midi import write_midi

    write_midi(window(load_song("twinkle-twinkle"), 0.0, 2.0), song)
    run = tmp_path / "run"
    monkeypatch.chdir(tmp_path)  # the song given by a relative path
    args = ["train", "song.mid", "--preset", "practice", "--physics", "fast", "--passes", "1"]
    start = time.perf_counter()
    assert main([*args, "--out", str(run), "--no-progress"]) == 0
    wall = time.perf_counter() - start
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert [row["pass"] for row in log] == [0, 1]
    # Each pass's seconds count from the start once (pass 0's were counted twice before).
    assert 0 < log[0]["seconds"] < log[1]["seconds"] <= wall
    # The run records the file by its absolute path: resumed from anywhere, it finds it.
    assert json.loads((run / "config.json").read_text())["song"] == str(song.resolve())
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    best = max(row["f1"] for row in log)
    assert main(["eval", str(run), str(song)]) == 0
    metrics = json.loads((run / "eval" / "metrics.json").read_text())
    assert metrics["f1"] == pytest.approx(best)
    assert metrics["preset"] == "practice" and metrics["physics"] == "fast"
    assert isinstance(build_controller(f"policy:{run}"), CorrectedPlanner)
    # Resuming goes on from the last pass.
    assert main(["train", "--resume", str(run), "--passes", "2", "--no-progress"]) == 0
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert [row["pass"] for row in log] == [0, 1, 2]
    capsys.readouterr()


def test_a_fingerprint_covers_the_fingering_and_still_reads_older_ones():
    goal = goal_frames(SONG)
    refingered = goal_frames(load_song(SONG, fingering="robot"))
    assert np.array_equal(goal.keys, refingered.keys)
    assert not np.array_equal(goal.fingers, refingered.fingers)
    assert same_goal(goal, goal_fingerprint(goal))
    assert not same_goal(refingered, goal_fingerprint(goal))
    # A table saved before the fingering was covered is checked on the keys and pedal alone.
    legacy = goal_fingerprint(goal, fingering=False)
    assert len(legacy) == 16 and same_goal(refingered, legacy)
    assert not same_goal(goal_frames(window(SONG, 0.0, 1.0)), legacy)


def test_a_practised_piece_is_refused_with_another_fingering(practised):
    planner = CorrectedPlanner(practised.table, fingerprint=practised.fingerprint)
    with pytest.raises(ValueError, match="another lead-in or fingering"):
        play(load_song(SONG, fingering="robot"), planner, physics="fast")


def test_damaged_practice_runs_and_busy_folders_are_one_line(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    write_practice_config(run, "twinkle-twinkle", FAST)
    (run / "practice.npz").write_bytes(b"PK\x03\x04 cut short")
    assert main(["eval", str(run), "twinkle-twinkle", "--out", str(tmp_path / "e")]) == 1
    assert "is not a practice table" in capsys.readouterr().err
    assert main(["train", "--resume", str(run), "--no-progress"]) == 1
    assert "is not a readable practice run" in capsys.readouterr().err
    # A new run is not started over an earlier one's files (nor beside unrelated ones).
    before = sorted(p.name for p in run.iterdir())
    assert main(["train", "c-major-chords", "--out", str(run)]) == 1
    err = capsys.readouterr().err
    assert "already holds files" in err and f"--resume {run}" in err
    assert sorted(p.name for p in run.iterdir()) == before
    # --resume continues the run's own song: another one given beside it is refused.
    assert main(["train", "c-major-chords", "--resume", str(run)]) == 1
    assert "leave out SONG" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--steps", "100"], "--steps does not apply"),
        (["--passes", "0"], "--passes must be at least 1"),
        (["--eval-physics", "fast"], "--eval-physics applies to soft actor-critic presets"),
    ],
)
def test_train_practice_refuses_bad_options(tmp_path, capsys, extra, message):
    args = ["train", "twinkle-twinkle", "--preset", "practice", "--out", str(tmp_path)]
    code = main([*args, *extra])
    assert code != 0
    assert message in capsys.readouterr().err
    assert not (tmp_path / "practice.npz").exists()


def test_eval_of_a_practised_piece_refuses_another_song(tmp_path, capsys, practised):
    write_practice_config(tmp_path, "chorale", FAST)
    save_practice(tmp_path, practised, FAST)
    assert main(["eval", str(tmp_path), "twinkle-twinkle", "--out", str(tmp_path / "e")]) != 0
    assert "another piece" in capsys.readouterr().err


def test_two_workers_play_two_look_aheads_and_keep_the_better(practised):
    config = dataclasses.replace(
        FAST, passes=1, workers=2, schedule=(RefineOptions(candidates=4), RefineOptions(sigma=0.3))
    )
    assert [config.options(1, w).sigma for w in (0, 1)] == [0.15, 0.3]
    assert config.options(2, 0).sigma == 0.15  # the schedule cycles
    result = practise(SONG, config)
    row = result.history[1]
    assert len(row["worker_f1"]) == 2 and row["f1"] == max(row["worker_f1"])
    # Worker 0 played what a one-worker pass with the same look-ahead plays.
    alone = practise(SONG, dataclasses.replace(config, workers=1, schedule=config.schedule[:1]))
    assert row["worker_f1"][0] == alone.history[1]["f1"]


def test_the_look_ahead_can_nudge_the_forearms_and_nothing_else_besides_the_fingers():
    config = dataclasses.replace(
        FAST, passes=1, schedule=(RefineOptions(candidates=4, arm_sigma=0.2),)
    )
    result = practise(SONG, config)
    planner = IKPlanner()
    play(SONG, planner, physics="fast")
    arms = {int(hand.tx_actuator) for hand in planner.hands}
    fingers = set(planner.finger_action_dims().tolist())
    changed = set(np.flatnonzero(np.abs(result.table).max(axis=0) > 1e-6).tolist())
    assert changed & arms  # a nudged slide was played somewhere
    assert changed <= fingers | arms
    with pytest.raises(ValueError, match="arm_sigma"):
        RefineOptions(arm_sigma=-0.1)
