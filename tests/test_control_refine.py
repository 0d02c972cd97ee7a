"""The refiner: the planner's actions improved by looking ahead on a fork of the environment."""

import dataclasses

import numpy as np
import pytest

from pianist.cli import main
from pianist.control import make_controller
from pianist.control.planner import IKPlanner
from pianist.control.refine import RefineOptions, Refiner
from pianist.control.registry import parse_controller
from pianist.eval.session import make_env, play
from pianist.music import Song, load_song
from pianist.music.notes import Note
from pianist.music.transforms import window


def _refiner_at_start(song, options: RefineOptions):
    """A refiner reset on a fresh fast-physics environment of ``song``: (refiner, env, obs)."""
    refiner = Refiner(options=options)
    env = make_env(song, refiner, physics="fast")
    obs, _ = env.reset(seed=0)
    refiner.reset(env, seed=0)
    return refiner, env, obs


def test_without_candidates_the_refiner_plays_the_planners_actions():
    song = window(load_song("twinkle-twinkle"), 0.0, 2.0)
    alone = play(song, IKPlanner(), physics="fast", seed=0)
    refined = play(song, Refiner(options=RefineOptions(candidates=0)), physics="fast", seed=0)
    np.testing.assert_array_equal(alone.episode.actions, refined.episode.actions)


def test_looking_ahead_leaves_the_episode_and_the_planner_as_they_were():
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 1.0)
    refiner, env, obs = _refiner_at_start(song, RefineOptions(candidates=3, horizon_steps=3))
    twin = IKPlanner()
    twin_env = make_env(song, twin, physics="fast")
    twin_env.reset(seed=0)
    twin.reset(twin_env, seed=0)
    for _ in range(5):
        # The twin planner, in the same state with the same memory, proposes alone.
        twin_env.unwrapped.restore(env.unwrapped.snapshot())
        twin.set_memory(refiner.planner.memory())
        proposal = twin.act(obs)
        qpos = env.unwrapped.data.qpos.copy()
        action = refiner.act(obs)
        np.testing.assert_array_equal(env.unwrapped.data.qpos, qpos)  # looked ahead elsewhere
        # The refiner's planner remembers what the twin does after proposing, and the refined
        # action differs from the proposal in the fingers only.
        for mine, theirs in zip(refiner.planner.memory(), twin.memory(), strict=True):
            assert mine.equals(theirs)
        others = np.setdiff1d(np.arange(action.size), refiner.dims)
        np.testing.assert_allclose(action[others], proposal[others], atol=1e-6)
        obs, *_ = env.step(action)
    assert env.unwrapped.step_index == 5
    assert refiner.stats()["refined_share"] >= 0.0
    # Every step looked ahead at least once (3 steps) and at most 3 + 1 candidates + the
    # combined one; the count is what the simulation ran on the fork.
    assert 5 * 3 <= refiner.simulated_steps <= 5 * 5 * 3
    assert refiner.stats()["lookahead_steps_per_step"] == refiner.simulated_steps / 5


@pytest.mark.parametrize("open_loop", [False, True])
def test_refining_plays_a_chorale_passage_better_than_the_planner(open_loop):
    # The opening of a chorale, where the planner alone lets keys flicker and strikes late.
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 3.0)
    alone = play(song, IKPlanner(), physics="fast", seed=0).metrics
    options = RefineOptions(open_loop=open_loop)
    refined = play(song, Refiner(options=options), physics="fast", seed=0).metrics
    assert refined["f1"] >= alone["f1"] + 0.03, (alone["f1"], refined["f1"])
    assert refined["controller_options"]["refine"]["candidates"] == RefineOptions().candidates
    assert refined["controller_options"]["refine"]["open_loop"] is open_loop
    assert 0 < refined["refined_share"] < 1


def test_each_finger_takes_the_candidate_that_cost_it_least():
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 1.0)
    refiner, env, _ = _refiner_at_start(song, RefineOptions(candidates=2))
    offsets = np.zeros((3, env.action_space.shape[0]), dtype=np.float32)
    offsets[1, refiner.dims], offsets[2, refiner.dims] = 0.1, -0.1
    costs = np.zeros((3, 10))
    costs[0, :] = 1.0  # the proposal costs every finger a key
    costs[1, 0] = costs[2, 1] = 2.0  # candidate 1 is worse for finger 0, 2 for finger 1
    combined = refiner._combine(offsets, costs)
    thumb, index = refiner.finger_dims[0], refiner.finger_dims[1]  # of the right hand
    np.testing.assert_allclose(combined[thumb], -0.1)  # finger 0: candidate 2
    np.testing.assert_allclose(combined[index], 0.1)  # finger 1: candidate 1
    np.testing.assert_allclose(combined[refiner.finger_dims[2]], 0.1)  # a tie: the first
    others = np.setdiff1d(np.arange(combined.size), refiner.dims)
    np.testing.assert_array_equal(combined[others], 0.0)  # forearms, wrists, pedal untouched


def test_a_look_aheads_cost_is_shared_among_the_fingers_that_answer_for_it():
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 1.0)
    refiner, _, obs = _refiner_at_start(song, RefineOptions(candidates=1, horizon_steps=4))
    proposal = refiner.planner.act(obs)
    zero = np.zeros_like(proposal)
    total, per_finger = refiner._look_ahead(
        proposal, zero, refiner.handle.snapshot(), refiner.planner.memory()
    )
    # From home the hands miss the first chord: every due key is some finger's, and so is
    # every wrong one, so the parts add up to the whole.
    assert total > 0 and per_finger.sum() == pytest.approx(total)


def test_crossed_fingers_are_found_in_either_hand():
    refiner, _, _ = _refiner_at_start(load_song("c-major-scale-both"), RefineOptions(candidates=1))
    sides = [hand.side for hand in refiner.planner.hands]
    # Fingertips 2 cm apart in order, each hand's little finger furthest from its thumb.
    up = [1.0 if side == "right" else -1.0 for side in sides]
    tip_y = np.concatenate([u * (0.3 + 0.02 * np.arange(5)) for u in up])
    assert refiner._crossed(tip_y).size == 0
    hand = sides.index("left")
    crossed = tip_y.copy()
    crossed[hand * 5 + 2] = crossed[hand * 5 + 3] - 0.005  # middle past ring, toward the bass
    offset = refiner.planner.hands[hand].finger_offset
    assert sorted(refiner._crossed(crossed).tolist()) == [offset + 2, offset + 3]
    crossed[hand * 5 + 2] = crossed[hand * 5 + 3] + 0.002  # 2 mm short of it: not crossed
    assert refiner._crossed(crossed).size == 0


def parse_refine_options(text: str) -> RefineOptions:
    """The options of ``refine:TEXT`` (the spec's fields are the refiner's options)."""
    spec = parse_controller(f"refine:{text}" if text else "refine")
    assert isinstance(spec, RefineOptions)
    fields = dataclasses.fields(RefineOptions)  # the spec adds the planner's option
    return RefineOptions(**{f.name: getattr(spec, f.name) for f in fields})


def test_refine_options_parse_and_refuse():
    assert parse_refine_options("") == RefineOptions()
    assert parse_refine_options("candidates=16,sigma=0.2") == RefineOptions(16, sigma=0.2)
    with pytest.raises(ValueError, match="unknown refine option"):
        parse_refine_options("samples=3")
    with pytest.raises(ValueError, match="needs a whole number"):
        parse_refine_options("candidates=many")
    assert parse_refine_options("keep_previous=false").keep_previous is False
    with pytest.raises(ValueError, match="needs true or false"):
        parse_refine_options("keep_previous=maybe")
    with pytest.raises(ValueError, match="horizon_steps >= 1"):
        RefineOptions(horizon_steps=0)
    assert parse_refine_options("open_loop=true,threads=0") == RefineOptions(
        open_loop=True, threads=0
    )
    with pytest.raises(ValueError, match="threads >= 0"):
        RefineOptions(threads=-1)
    with pytest.raises(ValueError, match="open_loop_batch >= 0"):
        RefineOptions(open_loop_batch=-2)
    assert isinstance(make_controller("refine:candidates=2"), Refiner)


def test_cli_refine_is_for_the_planner_only(tmp_path, capsys):
    code = main(
        [
            "play",
            "twinkle-twinkle",
            "--controller",
            "random",
            "--refine",
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--refine refines the planner" in err
    assert not (tmp_path / "out").exists()


def test_keys_the_plan_leaves_out_do_not_count_in_the_look_ahead():
    # A right-hand chord wider than the hand (two octaves) while the left hand is busy below:
    # the plan leaves part of it out, and no perturbation of the fingers can play it.
    notes = [Note(p, 0.1, 1.2, finger=f) for p, f in ((60, 0), (64, 1), (67, 2), (84, 4))]
    notes += [Note(36, 0.1, 1.2, finger=9), Note(43, 0.1, 1.2, finger=5)]
    song = Song(tuple(notes), name="too-wide")
    options = RefineOptions(candidates=3, horizon_steps=3)
    runs = []
    for count_left_out in (False, True):
        refiner = Refiner(options=options)
        env = make_env(song, refiner, physics="fast")
        env.reset(seed=0)
        refiner.reset(env, seed=0)
        goal = refiner.handle.goal.keys
        left_out = np.any([arrays.skip for arrays in refiner.planner.plan.hands], axis=0)
        assert left_out.any() and not (refiner.planned & left_out).any()
        assert refiner.planned.sum() == goal.sum() - left_out.sum()
        if count_left_out:
            refiner.planned = goal.copy()  # as if they counted
        obs = None
        for _ in range(goal.shape[0]):
            obs, *_ = env.step(refiner.act(obs))
        runs.append(refiner.simulated_steps)
    # Counted, every look-ahead over the chord costs something and tries every candidate.
    assert runs[0] < runs[1], runs


def test_continuing_the_unperturbed_look_ahead_plays_the_same_with_fewer_steps():
    # Where the planner's own action was played, the next step's unperturbed look-ahead is
    # the last one's, one step further: continued instead of simulated again, the episode
    # is the same action for action, with fewer steps simulated on the fork.
    song = window(load_song("chopin-mazurka-op6-no2"), 0.0, 4.0)
    runs = {}
    for continued in (False, True):
        options = RefineOptions(candidates=2, horizon_steps=3, continue_look_ahead=continued)
        refiner = Refiner(options=options)
        played = play(song, refiner, physics="fast", seed=0)
        runs[continued] = (played.episode.actions, refiner.simulated_steps)
    np.testing.assert_array_equal(runs[False][0], runs[True][0])
    assert runs[True][1] < runs[False][1]


def test_a_rollout_reproduces_the_environments_steps():
    # Faithful physics (no sleeping keys): the batched open-loop look-ahead is the
    # environment's own stepping, bit for bit, for every sequence of the batch.
    from pianist.control.rollout_ahead import RolloutAhead

    song = window(load_song("mozart-sonata-k545-allegro"), 0.0, 2.0)
    planner = IKPlanner()
    env = make_env(song, planner, physics="faithful")
    obs, _ = env.reset(seed=0)
    planner.reset(env, seed=0)
    for _ in range(10):
        obs, *_ = env.step(planner.act(obs))
    penv = env.unwrapped
    start = penv.snapshot()
    sites = np.concatenate([hand.sites for hand in planner.hands])
    actions, keys, tips = [], [], []
    for _ in range(4):
        action = planner.act(obs)
        obs, *_ = env.step(action)
        actions.append(action)
        keys.append(penv.data.qpos[penv.scene.key_qpos].copy())
        tips.append(penv.data.site_xpos[sites].copy())
    ahead = RolloutAhead(penv.model, penv.config.substeps, penv.scene.key_qpos, sites, nthread=2)
    other = np.stack(actions) * 0.5  # a second sequence, which must not disturb the first
    got_keys, got_tips = ahead.run(start.data, np.stack([np.stack(actions), other]))
    np.testing.assert_array_equal(got_keys[0], np.stack(keys))
    np.testing.assert_array_equal(got_tips[0], np.stack(tips))
    assert not np.array_equal(got_keys[1], got_keys[0])


def test_the_open_loop_look_ahead_of_no_offset_costs_what_the_planners_own_does():
    # Replaying the unperturbed look-ahead's actions open-loop (faithful physics: exact)
    # lands where the planner acting in closed loop did, so it costs the same, finger by finger.
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 1.0)
    refiner = Refiner(options=RefineOptions(candidates=2, horizon_steps=4, open_loop=True))
    env = make_env(song, refiner, physics="faithful")
    obs, _ = env.reset(seed=0)
    refiner.reset(env, seed=0)
    checked = 0
    for _ in range(8):
        state = refiner.handle.snapshot()
        memory = refiner.planner.memory()
        proposal = refiner.planner.act(obs)
        cost, per_finger = refiner._unperturbed(proposal, state, memory)
        refiner.planner.attach(refiner.handle)
        refiner.planner.set_memory(memory)
        zero = np.zeros((1, proposal.size), dtype=np.float32)
        costs, parts = refiner._open_loop(zero, state)
        assert costs[0] == cost
        np.testing.assert_array_equal(parts[0], per_finger)
        checked += cost > 0
        obs, *_ = env.step(refiner.planner.act(obs))
    assert checked  # from home the first chord is missed: costs that are not all zero
    # A second episode of the same scene reuses the look-ahead (its thread pool), not a new one.
    batched = refiner._batched
    env.reset(seed=1)
    refiner.reset(env, seed=1)
    assert batched is not None and refiner._batched is batched


def _stubbed_search(open_loop_costs, closed_loop_costs, batch, verify=True):
    """A refiner whose open-loop and closed-loop look-aheads return the given costs per
    candidate, searched in batches of ``batch``: (costs returned, batch sizes simulated,
    candidates looked ahead in closed loop)."""
    refiner = Refiner(options=RefineOptions(open_loop=True, open_loop_batch=batch, verify=verify))
    offsets = np.arange(len(open_loop_costs), dtype=np.float32)[:, None]
    batches, closed = [], []

    def open_loop(chunk, state):
        batches.append(len(chunk))
        picked = [open_loop_costs[int(row[0])] for row in chunk]
        return picked, [np.zeros(10) for _ in picked]

    def look_ahead(proposal, offset, state, memory):
        closed.append(int(offset[0]))
        return closed_loop_costs[int(offset[0])], np.zeros(10)

    refiner._open_loop = open_loop
    refiner._look_ahead = look_ahead
    costs, _ = refiner._open_loop_search(np.zeros(1), offsets, None, None)
    return costs, batches, closed


def test_the_open_loop_search_ends_after_a_batch_that_misses_nothing():
    open_loop = [3.0, 2.0, 0.0, 5.0, 1.0, 1.0]
    # One batch (the default): every candidate, the cheapest verified in closed loop.
    costs, batches, closed = _stubbed_search(open_loop, [9, 9, 0.0, 9, 9, 9], batch=0)
    assert (
        batches == [6] and closed == [2] and costs == [np.inf, np.inf, 0.0, np.inf, np.inf, np.inf]
    )
    # In pairs: the second pair holds a candidate that misses nothing, verified so: the
    # search ends there, as the closed-loop one does, and the third pair is not simulated.
    costs, batches, closed = _stubbed_search(open_loop, [9, 9, 0.0, 9, 9, 9], batch=2)
    assert batches == [2, 2] and closed == [2] and costs == [np.inf, np.inf, 0.0, np.inf]
    # Verified, it misses a key after all: the search goes on, and the candidate cheapest
    # open-loop is not looked ahead twice.
    costs, batches, closed = _stubbed_search(open_loop, [9, 9, 1.0, 9, 9, 9], batch=2)
    assert batches == [2, 2, 2] and closed == [2] and costs[2] == 1.0 and len(costs) == 6
    # Without verifying, the open-loop cost alone ends it.
    costs, batches, closed = _stubbed_search(open_loop, [9] * 6, batch=2, verify=False)
    assert batches == [2, 2] and closed == [] and costs == [3.0, 2.0, 0.0, 5.0]


def test_open_loop_batches_simulate_fewer_steps_on_a_passage():
    song = window(load_song("bach-chorale-bwv66-6"), 0.0, 3.0)
    steps = {}
    for batch in (0, 1):
        options = RefineOptions(open_loop=True, threads=0, open_loop_batch=batch)
        refiner = Refiner(options=options)
        play(song, refiner, physics="fast", seed=0)
        steps[batch] = refiner.simulated_steps
    assert steps[1] < steps[0]


def test_a_finger_pushing_a_soft_note_is_not_perturbed():
    """On the crescendo (soft notes pushed and loud ones struck by the planner's prediction),
    with a perturbation made to win every step: wherever a finger's command was predicted,
    its action is the planner's own, and the other fingers' are perturbed."""
    song = window(load_song("crescendo-scale"), 0.0, 2.0)
    planner = IKPlanner()
    proposals: list[np.ndarray] = []
    propose = planner.act

    def recording(observation=None):
        proposals.append(propose(observation))
        return proposals[-1]

    planner.act = recording  # type: ignore[method-assign]
    refiner = Refiner(planner, RefineOptions(candidates=1, sigma=0.3, horizon_steps=1))
    # The planner's own look-ahead costs more than any perturbation's.
    refiner._unperturbed = lambda *args: (1.0, np.ones(10))  # type: ignore[method-assign]
    refiner._look_ahead = lambda *args: (0.0, np.zeros(10))  # type: ignore[method-assign]
    env = make_env(song, refiner, physics="fast")
    obs, _ = env.reset(seed=0)
    refiner.reset(env, seed=0)
    pushed_steps = 0
    for _ in range(env.unwrapped.goal.num_frames):
        first = len(proposals)
        action = refiner.act(obs)
        pushing = planner.predicted_action_dims()
        proposal = proposals[first]
        if pushing.size:
            pushed_steps += 1
            np.testing.assert_array_equal(action[pushing], proposal[pushing])
            others = np.setdiff1d(refiner.dims, pushing)
            assert not np.allclose(action[others], proposal[others])
        obs, *_ = env.step(action)
    assert pushed_steps >= 5
