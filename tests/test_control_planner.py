"""The inverse-kinematics planner plays fingered songs with no training."""

import mujoco
import numpy as np
import pytest

from pianist.control import make_controller
from pianist.control.planner import ENV_OPTIONS, FingerState, IKPlanner, PlannerConfig
from pianist.control.planner.forearm import plan_commands
from pianist.control.planner.hand_plan import HandPlan
from pianist.control.planner.ik import finger_controls, solve_fingers
from pianist.control.planner.plans import Plan
from pianist.control.planner.postures import set_wrist
from pianist.control.planner.targets import fingertip_targets
from pianist.env import PianoEnv
from pianist.env.piano_env import action_to_ctrl
from pianist.eval import run_episode
from pianist.eval.session import make_env
from pianist.music import Note, Song, load_song
from pianist.music.transforms import window
from pianist.sim.constants import BLACK_KEY_MASK, FINGERTIP_CAPSULE_RADIUS_M


def _targets(planner, now, hover_end, hand=0):
    """Hand ``hand``'s fingertip targets and active fingers at step ``now`` as the planner's
    step makes them (in the pose it holds then); the planner's memory of its fingers is
    updated as a step updates it."""
    arrays = planner.plan.hands[hand]
    pose = planner.poses[hand][int(arrays.pose_held[now])]
    targets, active, memory = fingertip_targets(
        planner, planner.hands[hand], arrays, pose.lift_tips, planner.memories[hand], now, hover_end
    )
    planner.memories[hand] = memory
    return targets, active


def _solve(planner, targets, active, cfg=None, hand=0, pose=0, bent_up=0.0):
    """Hand ``hand``'s finger angles (5, D) for ``targets`` in pose ``pose`` (set in the
    planner's scratch state), with the planner's memory of its fingers."""
    return solve_fingers(
        planner.model,
        planner.scratch,
        planner.hands[hand],
        planner.poses[hand][pose].batch,
        targets,
        active,
        planner.memories[hand],
        bent_up,
        pose > 0,
        cfg or planner.config,
    )


def _play(song, physics="fast"):
    env = PianoEnv(song, physics=physics, **ENV_OPTIONS)
    episode = run_episode(env, IKPlanner(), seed=0)
    return env, episode


@pytest.mark.parametrize("finger", range(5))
def test_each_right_hand_finger_presses_a_white_and_a_black_key(finger):
    # C4 (white, pitch 60) then D#4 (black, 63), each held 1 s, with one finger.
    if finger == 0:
        pitches = (60, 62)  # the thumb cannot reach the front of a black key: two white keys
    else:
        pitches = (60, 63)
    notes = tuple(
        Note(pitch, 0.5 + 1.5 * i, 1.5 + 1.5 * i, finger=finger) for i, pitch in enumerate(pitches)
    )
    _, episode = _play(Song(notes, name=f"finger-{finger}"))
    played = episode.performance().notes
    for pitch in pitches:
        assert any(n.pitch == pitch for n in played), (finger, pitch, played)
    metrics = episode.metrics()
    assert metrics["precision"] >= 0.95 and metrics["recall"] >= 0.7, metrics


def test_a_repeated_key_is_struck_again():
    # Four quarter notes on one key (the goal lets the key up for one frame between them).
    notes = tuple(Note(64, 0.5 + 0.5 * i, 1.0 + 0.5 * i, finger=2) for i in range(4))
    _, episode = _play(Song(notes, name="repeats"))
    strikes = [n for n in episode.performance().notes if n.pitch == 64]
    assert len(strikes) == 4, strikes


@pytest.mark.parametrize("song", ["twinkle-twinkle", "c-major-scale-both"])
def test_the_planner_reaches_the_target_on_debug_songs(song):
    # The project's target is F1 >= 0.95 on every debug song. These two meet it with a margin
    # (measured 0.967 and 0.966 on this preset, 0.967 and 0.967 faithful); the others are
    # held to regression floors in the tests below and measured in benchmarks/.
    metrics = _play(song)[1].metrics()
    assert metrics["f1"] >= 0.95, metrics
    assert metrics["precision"] >= 0.95, metrics


def test_same_song_same_actions():
    song = Song(tuple(Note(60 + 2 * i, 0.2 * i, 0.2 * i + 0.3, finger=1 + i % 3) for i in range(5)))
    env = PianoEnv(song, physics="fast", **ENV_OPTIONS)
    first = run_episode(env, IKPlanner(), seed=0).actions
    second = run_episode(env, IKPlanner(), seed=1).actions
    np.testing.assert_array_equal(first, second)


def test_unfingered_song_is_refused():
    env = PianoEnv(Song((Note(60, 0.0, 0.5),), name="bare"), physics="fast")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finger for every note"):
        make_controller("planner").reset(env)


def test_actions_are_normalised_with_the_goal_pedal():
    env, episode = _play("c-major-chords")
    assert np.all(np.abs(episode.actions) <= 1.0)
    pedal_down = episode.actions[:, -1] > 0
    # The pedal action follows the goal one frame ahead.
    np.testing.assert_array_equal(pedal_down[:-1], env.goal.sustain[1 : len(pedal_down)])


def test_the_papers_scene_without_the_height_slide_still_plays_the_fingers():
    # Index, middle and ring on C4, D4, E4: the wrist is flexed so they reach the key bottoms.
    notes = tuple(Note(60 + 2 * i, 0.5 + 0.6 * i, 1.0 + 0.6 * i, finger=1 + i) for i in range(3))
    env = PianoEnv(Song(notes, name="fingers"), physics="fast")  # forearm slides tx, ty only
    episode = run_episode(env, IKPlanner(), seed=0)
    assert {n.pitch for n in episode.performance().notes} == {60, 62, 64}
    # No other key is touched (a key may go down a frame early: that costs precision here).
    pressed = np.flatnonzero(np.asarray(episode.active_keys).any(axis=0))
    assert set(pressed.tolist()) == {60 - 21, 62 - 21, 64 - 21}
    assert episode.metrics()["precision"] >= 0.9
    # Asked for the paper's embodiment, the planner declares that scene.
    paper = IKPlanner(PlannerConfig(paper_embodiment=True))
    paper_env = make_env(Song(notes), paper, physics="fast")
    assert paper_env.unwrapped.config.scene.hand.forearm_dofs == (
        "tx",
        "ty",
    )
    assert IKPlanner().env_options()["forearm_dofs"] == ("tx", "ty", "tz")


def test_in_the_full_action_space_the_joints_of_the_reduced_hand_alone_are_moved():
    # The full hand has THJ5, THJ1 and LFJ5 besides, and THJ2 down to -0.698 rad. The planner
    # holds them as the reduced hand has them (commanded 0, THJ2 >= 0) and plays Twinkle as
    # it does there (0.967; moving them, 0.823).
    song = load_song("twinkle-twinkle")
    env = PianoEnv(song, physics="fast", reduced_action_space=False, **ENV_OPTIONS)
    names = env.unwrapped.action_names
    held = [i for i, name in enumerate(names) if name.endswith(("THJ5", "THJ1", "LFJ5"))]
    thj2 = [i for i, name in enumerate(names) if name.endswith("THJ2")]
    assert len(held) == 6 and len(thj2) == 2
    episode = run_episode(env, IKPlanner(), seed=0)
    actions = np.asarray(episode.actions)[:, :-1]
    ctrlrange = env.unwrapped.model.actuator_ctrlrange
    ctrl = action_to_ctrl(actions, ctrlrange)
    assert np.allclose(ctrl[:, held], 0.0, atol=1e-6)
    assert ctrl[:, thj2].min() >= -1e-6 and ctrl[:, thj2].max() > 0.1  # the thumb still moves
    assert episode.metrics()["f1"] >= 0.94
    # Whatever else was commanded there (a residual policy's correction, say), the
    # planner's next command is 0 again.
    planner = IKPlanner()
    env.reset(seed=0)
    planner.reset(env, seed=0)
    for _ in range(3):
        action = planner.act(None)
        assert np.allclose(action_to_ctrl(action[:-1], ctrlrange)[held], 0.0, atol=1e-6)
        action[held] = 0.5
        env.step(action)
    # Asked to move them too, the planner does.
    moving = run_episode(env, IKPlanner(PlannerConfig(full_hand=True)), seed=0)
    assert np.ptp(np.asarray(moving.actions)[:, held], axis=0).max() > 0.1


FRAME = PlannerConfig().with_fields(hand_planning="frame")


def _step_planner(song, frames, physics="fast", config=None):
    """Play ``frames`` steps; returns the env, the planner and each step's (qpos copy)."""
    env = PianoEnv(song, physics=physics, **ENV_OPTIONS)
    planner = IKPlanner(config)
    observation, _ = env.reset(seed=0)
    planner.reset(env, seed=0)
    qpos = []
    for _ in range(frames):
        observation, *_ = env.step(planner.act(observation))
        qpos.append(env.data.qpos.copy())
    return env, planner, np.array(qpos)


def test_the_forearm_reaches_the_first_note_from_home_within_a_few_frames():
    # Twinkle's first note is due at once, 12 cm from the right hand's home position; the
    # servo on its own would still be ~4 cm short after four frames.
    _, planner, qpos = _step_planner("twinkle-twinkle", 4)
    hand, arrays = planner.hands[0], planner.plan.hands[0]
    assert abs(arrays.tx_plan[0]) > 0.08
    assert abs(qpos[-1, hand.tx_qpos] - arrays.tx_plan[3]) < 0.005


def test_a_chord_does_not_lift_the_hand():
    # The keys of a held three-note chord push the hand up; the height command resists.
    env, planner, qpos = _step_planner("c-major-chords", 18)
    hand = planner.hands[0]
    height = qpos[8:, hand.tz_qpos]
    assert np.all(np.abs(height - planner.config.forearm.hand_height_m) < 0.005), height


def test_a_wide_chord_keeps_every_finger_within_its_reach():
    # With no margin left unused, the frame-by-frame plan fits every chord of the song under
    # one hand position; the resting places alone (the default for single notes) put the
    # thumb out of reach of C4 under C-F-A.
    env = PianoEnv("c-major-chords", physics="fast", **ENV_OPTIONS)
    env.reset(seed=0)
    planner = IKPlanner(PlannerConfig().with_fields(reach_margin=0.0, hand_planning="frame"))
    planner.reset(env)
    goal = env.goal
    for hand, arrays, poses in zip(planner.hands, planner.plan.hands, planner.poses, strict=True):
        for t in np.flatnonzero(arrays.busy):
            keys = np.flatnonzero(goal.keys[t])
            fingers = goal.fingers[t, keys]
            if len(set(fingers)) < len(fingers):
                continue  # where one chord meets the next, a finger has two keys: no position
            for key in keys:
                finger = goal.fingers[t, key] - hand.finger_offset
                if not 0 <= finger < 5:
                    continue
                low, high = poses[0].reach[finger, int(BLACK_KEY_MASK[key])]
                offset = planner.key_point[key, 1] - arrays.tx_plan[t]
                assert low - 1e-9 <= offset <= high + 1e-9, (hand.side, t, key, finger)


def test_the_chord_song_is_played_well():
    metrics = _play("c-major-chords")[1].metrics()
    # Measured 0.927 (faithful 0.923); 0.81 before the height feedback, 0.88 before the
    # wrist feedback and the low path between keys.
    assert metrics["f1"] >= 0.9, metrics


def test_with_a_lead_in_the_chord_song_meets_the_target():
    # The chord song makes its first chord due in the first step, with the hands at home 15 cm
    # away: that cold start is most of what it loses. Given half a second first (the
    # original's initial_buffer_time), its own steps reach the target (measured 0.960).
    env = PianoEnv("c-major-chords", physics="fast", initial_buffer_s=0.5, **ENV_OPTIONS)
    metrics = run_episode(env, IKPlanner(), seed=0).metrics()
    assert metrics["lead_in_steps"] == 10
    assert metrics["song_f1"] >= 0.95, metrics


def test_a_finger_on_the_keys_with_far_to_go_comes_up_for_the_jump():
    # The original's progression ends with a 9 cm jump of the right hand from G-B-D to C-E-G.
    # Skimming towards C4, the thumb used to catch F4 and hold it, and the hand, for the whole
    # last chord (3 complete frames of its last 19, 9 with a wrong key; F1 0.803).
    env, episode = _play("CMajorChordProgressionTwoHands")
    last = slice(62, None)
    right = np.all(episode.active_keys[last] == episode.goal_keys[last], axis=1)
    wrong = np.any(episode.active_keys[last] & ~episode.goal_keys[last], axis=1)
    assert right.sum() >= 12 and wrong.sum() <= 4, (right.sum(), wrong.sum())
    assert episode.metrics()["f1"] >= 0.85  # measured 0.867


def test_a_thumb_that_cannot_line_up_at_hover_height_presses_from_where_it_stands():
    # With the hand 1 cm right of where the thumb rests over C4, the thumb cannot get over the
    # key at hover height (it stood there for the whole note before); at key depth it can.
    song = Song((Note(60, 0.5, 1.5, finger=0), Note(84, 2.0, 2.5, finger=0)), name="thumb")
    env = PianoEnv(song, physics="fast", **ENV_OPTIONS)
    planner = IKPlanner(PlannerConfig().with_fields(hand_planning="frame"))
    observation, _ = env.reset(seed=0)
    planner.reset(env)
    hand, arrays = planner.hands[0], planner.plan.hands[0]
    course = HandPlan(
        arrays.tx_plan + 0.01,
        arrays.busy,
        np.full_like(arrays.skip, -1, dtype=int),
        arrays.skip,
        0.0,
        arrays.pose_plan,
    )
    moved = plan_commands(hand, course, planner.dt, planner.config, multi_step=False)
    others = planner.plan.hands[1:]
    planner.plan = Plan(planner.plan.kind, planner.plan.fingers, (moved, *others))
    key = 60 - 21
    down = []
    for _ in range(31):
        observation, *_ = env.step(planner.act(observation))
        down.append(env.data.qpos[planner.key_qpos[key]] >= planner.key_threshold[key])
    assert sum(down[10:31]) >= 10, down


def _wrist_swing(feedback, frames=range(31, 40)):
    """Mean |WRJ2| of the right hand over ``frames`` of the C major scale (fast physics)."""
    env = PianoEnv("c-major-scale-right", physics="fast", **ENV_OPTIONS)
    planner = IKPlanner(PlannerConfig().with_fields(wrist_feedback=feedback))
    observation, _ = env.reset(seed=0)
    planner.reset(env, seed=0)
    qpos = planner.hands[0].wrist[0][1]
    swing = []
    for t in range(max(frames) + 1):
        observation, *_ = env.step(planner.act(observation))
        if t in frames:
            swing.append(abs(float(np.mean(env.data.qpos[qpos]))))
    return float(np.mean(swing))


def test_the_wrist_is_held_straight_after_a_shift():
    # The thumb passes under to F4 at frame 30 with a 6 cm shift of the hand; the shift swings
    # the hand on its soft wrist servo. With the feedback the wrist is back at its pose within
    # a step or two; without, it drifts off by several mm at the fingertips.
    held, loose = _wrist_swing((2.0, 0.0)), _wrist_swing((0.0, 0.0))
    assert held < 0.01, held
    assert loose > 1.5 * held, (held, loose)


def test_the_hand_stays_put_while_the_fingers_reach():
    env = PianoEnv("c-major-scale-right", physics="fast", **ENV_OPTIONS)
    env.reset(seed=0)
    moves = {}
    for lazy in (0.0, 0.02):
        planner = IKPlanner(PlannerConfig().with_fields(lazy_m=lazy))
        planner.reset(env)
        arrays, home = planner.plan.hands[0], planner.poses[0][0]
        moves[lazy] = int(np.count_nonzero(np.abs(np.diff(arrays.tx_plan)) > 1e-9))
        for t in np.flatnonzero(arrays.busy):
            keys = np.flatnonzero(env.goal.keys[t])
            reach = home.reach[env.goal.fingers[t, keys], BLACK_KEY_MASK[keys].astype(int)]
            y = planner.key_point[keys, 1]
            low, high = np.max(y - reach[:, 1]), np.min(y - reach[:, 0])
            if low <= high:  # (where the thumb passes under, no position reaches both keys)
                assert low - 1e-9 <= arrays.tx_plan[t] <= high + 1e-9, (lazy, t, keys)
    # Measured 28 position changes re-centring on every note, 6 staying put.
    assert moves[0.02] < moves[0.0] / 2, moves


def test_no_finger_strains_for_a_key_beyond_the_next_shift():
    # C major scale: the thumb plays F4 at frame 30, after the hand's shift at frame 29. At
    # frame 25 it is within the hover lead of F4 but must not reach for it from here: the
    # thumb cannot, and on its way it dipped onto D4.
    hovering = {}
    for stop in (True, False):
        env = PianoEnv("c-major-scale-right", physics="fast", **ENV_OPTIONS)
        planner = IKPlanner(PlannerConfig().with_fields(hover_stops_at_shift=stop))
        observation, _ = env.reset(seed=0)
        planner.reset(env, seed=0)
        for _ in range(25):
            observation, *_ = env.step(planner.act(observation))
        free = planner.plan.hands[0].free
        assert free[29] and not free[25:29].any()
        assert env.goal.fingers[30, 65 - 21] == 0  # F4, thumb
        _, active = _targets(planner, 25, 32)
        hovering[stop] = bool(active[0])
    assert hovering == {True: False, False: True}


def test_a_finger_changing_keys_in_a_chord_change_skims_low():
    # C-E-G then C-F-A at frame 20: the middle finger goes straight from E4 to F4. Off its
    # new key it travels just above the keys, not at the hover height (the song's fingering,
    # planned frame by frame).
    env, planner, _ = _step_planner("c-major-chords", 21, config=FRAME)
    hand = planner.hands[0]
    assert planner.memories[0].last_key[2] == 64 - 21  # it pressed E4 last
    targets, active = _targets(planner, 21, 27)
    key = 65 - 21
    assert active[2] and not planner.memories[0].pressing[2]
    top = planner.key_top_z[key] + FINGERTIP_CAPSULE_RADIUS_M
    height = targets[2, 2] + planner.scratch.xpos[hand.forearm_body][2] - top
    assert height == pytest.approx(planner.config.fingers.transfer_height_m, abs=1e-9)
    assert planner.config.fingers.transfer_height_m < planner.config.fingers.hover_height_m


@pytest.mark.parametrize(
    ("low", "high", "fingers", "kept"), [(36, 48, (9, 5), 36), (60, 72, (0, 4), 72)]
)
def test_a_chord_wider_than_the_hand_keeps_its_outer_voice(low, high, fingers, kept):
    # An octave is beyond the Shadow hand's span (thumb to little finger). Planned frame by
    # frame, the hand plays the bass in the left hand, the top in the right, for the whole
    # note; before, it put the hand halfway and hit neither key but their neighbours.
    notes = (Note(low, 0.5, 1.5, finger=fingers[0]), Note(high, 0.5, 1.5, finger=fingers[1]))
    env = PianoEnv(Song(notes, name="octave"), physics="fast", **ENV_OPTIONS)
    planner = IKPlanner(PlannerConfig().with_fields(hand_planning="frame"))
    episode = run_episode(env, planner, seed=0)
    down = np.asarray(episode.active_keys)
    dropped = ({low, high} - {kept}).pop()
    assert np.flatnonzero(down.any(axis=0)).tolist() == [kept - 21]
    assert down[:, kept - 21].sum() >= 18  # of its 21 frames
    assert any(arrays.skip[:, dropped - 21].any() for arrays in planner.plan.hands)


@pytest.mark.parametrize(("low", "high", "fingers"), [(36, 48, (9, 5)), (60, 72, (0, 4))])
def test_a_chord_wider_than_the_hand_is_shared_with_the_other_hand(low, high, fingers):
    # With the wrist held straight (no reach poses), the whole-piece plan gives the key one
    # hand cannot reach to the other, free, hand: both keys of the octave sound for the
    # whole note. (With reach poses one hand turns its wrist: test_control_poses.py.)
    notes = (Note(low, 0.5, 1.5, finger=fingers[0]), Note(high, 0.5, 1.5, finger=fingers[1]))
    env = PianoEnv(Song(notes, name="octave"), physics="fast", **ENV_OPTIONS)
    planner = IKPlanner(PlannerConfig().with_fields(reach_poses=()))
    episode = run_episode(env, planner, seed=0)
    assert planner.plan_kind[:2] == ("piece", True)
    down = np.asarray(episode.active_keys)
    assert np.flatnonzero(down.any(axis=0)).tolist() == [low - 21, high - 21]
    assert down[:, low - 21].sum() >= 18 and down[:, high - 21].sum() >= 18  # of 21 frames
    due = np.flatnonzero(env.goal.keys.any(axis=1))
    hands = {int(planner.fingers[t, k]) // 5 for t in due for k in (low - 21, high - 21)}
    assert hands == {0, 1}  # one key in each hand


@pytest.mark.parametrize(("key", "finger", "presses"), [(73 - 21, 3, True), (74 - 21, 4, False)])
def test_only_a_white_key_is_let_go_by_a_finger_too_far_back_along_it(key, finger, presses):
    # D major scale, frame 65: the ring finger holds C#5 (black); at frame 75 the little finger
    # holds D5 (white). Moving the press point 3 cm towards the player leaves the fingertip
    # that far behind it. On a white key that is over a black one: the finger comes up to try
    # again. On a black key it is still on the key: it keeps pressing (it used to come up,
    # and C#5 fell silent for two frames where a finger slid back on it).
    frame = 65 if presses else 75
    env, planner, _ = _step_planner("d-major-scale-right", frame)
    assert env.goal.fingers[frame, key] == finger and planner.memories[0].pressing[finger]
    planner.key_point[key, 0] += 0.03
    _targets(planner, frame, frame + 5)
    assert planner.memories[0].pressing[finger] == presses


@pytest.mark.parametrize(("back_m", "presses"), [(0.005, True), (0.03, False)])
def test_a_finger_in_front_of_a_black_key_does_not_press_it(back_m, presses):
    # D major scale, frame 65: the ring finger holds C#5, its tip 1.6 cm behind the press
    # point. With the press point moved 3 cm back into the keyboard, the tip is 1.4 cm in
    # front of it, over the white key before C#5 (pressing there, chorales' inner voices
    # stood on the white key for whole notes): it hovers on. Moved 5 mm, it still presses.
    key, finger, frame = 73 - 21, 3, 65
    env, planner, _ = _step_planner("d-major-scale-right", frame)
    assert planner.memories[0].pressing[finger]
    planner.key_point[key, 0] -= back_m
    _targets(planner, frame, frame + 5)
    assert planner.memories[0].pressing[finger] == presses


def test_every_black_key_of_the_d_major_scale_sounds_on_time():
    # The black keys (F#, C#) used to sound a frame late: with the hand still settling from a
    # move, the finger was more than the old black-key tolerance (4.5 mm) off and hovered.
    # Measured, both hands, fast preset: 4 due frames of black keys silent (the F#4 cut
    # short where the thumb passes under), 8 before.
    env, episode = _play("d-major-scale-both")
    down, due = np.asarray(episode.active_keys), env.goal.keys
    silent = int(np.count_nonzero(due[:, BLACK_KEY_MASK] & ~down[:, BLACK_KEY_MASK]))
    assert silent <= 5, silent
    assert episode.metrics()["f1"] >= 0.93, episode.metrics()


def test_a_shift_holds_the_keys_before_it_as_long_as_it_can():
    # D major scale: the middle finger holds F#4 through frame 30, where the thumb takes G4 and
    # the hand shifts 6 cm in two moves (halfway for frame 30, where both are due, then over
    # G4 for frame 31). The fingers let go for them in steps 29 and 30, one step before each
    # frame; F#4 still sounds at frame 28. Moving a frame earlier, it fell silent at 28 too.
    env = PianoEnv("d-major-scale-right", physics="fast", **ENV_OPTIONS)
    held = {}
    for lead in (0, 1):
        planner = IKPlanner(PlannerConfig().with_fields(shift_lead_frames=lead))
        down = np.asarray(run_episode(env, planner, seed=0).active_keys)
        assert list(np.flatnonzero(planner.plan.hands[0].free[:60])) == [29 - lead, 30 - lead]
        held[lead] = bool(down[28, 66 - 21])
    assert held == {0: True, 1: False}
    with pytest.raises(ValueError, match="shift_lead_frames"):
        IKPlanner(PlannerConfig().with_fields(shift_lead_frames=2)).reset(env)


def test_a_rest_between_two_notes_keeps_the_hand_over_its_keys():
    # The right hand plays G4 and B4 three times with a frame's rest between; the left hand
    # waits for its one note (C5, at 2.5 s) where that note will be, closer to the right
    # forearm than the two may come. In the rests neither hand plays: the hand whose next
    # note comes first keeps its place. (Both used to give way equally: the right hand left
    # its keys for every rest and came back, a shift each time: 42 of the 56 key-frames.)
    notes = [Note(72, 2.5, 3.0, finger=5)]
    for i in range(3):
        for key, finger in ((67, 1), (71, 3)):
            notes.append(Note(key, 0.5 + 0.5 * i, 0.95 + 0.5 * i, finger=finger))
    env = PianoEnv(Song(tuple(notes), name="rests"), physics="fast", **ENV_OPTIONS)
    planner = IKPlanner()
    episode = run_episode(env, planner, seed=0)
    right = planner.plan.hands[[hand.side for hand in planner.hands].index("right")]
    due = env.goal.keys[:, [67 - 21, 71 - 21]]
    frames = np.flatnonzero(due.any(axis=1))
    assert len(np.unique(right.tx_plan[frames[0] : frames[-1] + 1])) == 1
    # No shift in between (the hand may make way for the left one from its last frame on).
    assert not right.free[frames[0] : frames[-1]].any()
    down = np.asarray(episode.active_keys)[:, [67 - 21, 71 - 21]]
    assert int((down & due).sum()) >= 52, int((down & due).sum())  # of 56


def _held_then_leap() -> Song:
    """The right hand holds E4 and G4 (0.5-1.6 s) while a melody two octaves up starts at
    1.2 s; the left hand is busy with a bass far below, so it cannot take either."""
    notes = [Note(64, 0.5, 1.6, finger=1), Note(67, 0.5, 1.6, finger=3)]
    for i, key in enumerate((84, 86, 88, 86, 84, 86, 88, 86)):
        notes.append(Note(key, 1.2 + 0.25 * i, 1.4 + 0.25 * i, finger=(1, 2, 3, 2)[i % 4]))
    for i in range(12):
        notes.append(Note((36, 43)[i % 2], 0.5 + 0.25 * i, 0.7 + 0.25 * i, finger=(6, 8)[i % 2]))
    return Song(tuple(notes), name="held-then-leap")


def test_a_shift_leaves_later_when_the_keys_it_holds_outweigh_the_notes_it_moves_for():
    # Moving up for the melody on time lets the held chord go for the jump's frames; leaving
    # later keeps it and loses the melody's notes until the hand is there instead.
    song = _held_then_leap()
    held, free, f1 = {}, {}, {}
    for delay in (0, 8):
        env = PianoEnv(song, physics="fast", **ENV_OPTIONS)
        planner = IKPlanner(PlannerConfig().with_fields(shift_delay_max_frames=delay))
        episode = run_episode(env, planner, seed=0)
        right = planner.plan.hands[0]
        assert planner.plan_kind[0] == "piece" and planner.hands[0].side == "right"
        down = np.asarray(episode.active_keys)
        held[delay] = int(down[:, 64 - 21].sum() + down[:, 67 - 21].sum())
        free[delay] = np.flatnonzero(right.free)
        f1[delay] = episode.metrics()["f1"]
        # The plan as followed holds the old place through the shift's note frame (the path
        # ends moves a frame early), and through the shift's delay.
        moved = np.flatnonzero(right.tx_held != right.tx_plan)
        assert len(moved) == free[delay][0] - free[0][0] + 1
    assert free[8][0] > free[0][0] and len(free[8]) == len(free[0])  # the same jump, later
    assert held[8] >= held[0] + 6  # E4 and G4 sound for longer (both keys, 3 frames or more)
    assert f1[8] > f1[0]
    with pytest.raises(ValueError, match="shift_delay_max_frames"):
        PlannerConfig().with_fields(shift_delay_max_frames=-1)


def test_posture_samples_are_made_once_per_scene_and_reused_exactly(monkeypatch):
    from pianist.control.planner import postures as module

    monkeypatch.setattr(module, "_POSTURES", {})
    calls = []
    sample = module._sample_postures
    monkeypatch.setattr(module, "_sample_postures", lambda *a: calls.append(1) or sample(*a))
    song = Song(tuple(Note(60 + 2 * i, 0.2 * i, 0.2 * i + 0.15, finger=i) for i in range(5)))
    poses = len(PlannerConfig().poses.hand_poses(has_tz=True))  # each pose has its own samples
    first = _play(song)[1].actions  # samples the postures
    again = _play(song)[1].actions  # a new environment and planner of the same scene
    assert len(calls) == poses and len(module._POSTURES) == poses
    np.testing.assert_array_equal(first, again)
    # A scene built otherwise (one hand) has postures of its own.
    env = PianoEnv(song, physics="fast", hands="right", **ENV_OPTIONS)
    run_episode(env, IKPlanner(), seed=0)
    assert len(calls) == 2 * poses and len(module._POSTURES) == 2 * poses


@pytest.mark.parametrize(
    ("song", "floor"), [("clara-schumann-polonaise-op1-no1", 0.72), ("bach-chorale-bwv66-6", 0.77)]
)
def test_real_pieces_play_above_a_floor(song, floor):
    # open-etude-12, fast preset: 0.40 and 0.60 planned frame by frame with the song's
    # fingering (octaves and chords wider than the Shadow hand skipped, jumps late); with the
    # whole-piece plan, its own fingering and keys shared between the hands: 0.69 and 0.69;
    # with the thumb's lateral IK weight, unwedging and keep-sounding: 0.749 and 0.799.
    planner = IKPlanner()
    env = make_env(song, planner, physics="fast")
    assert run_episode(env, planner, seed=0).metrics()["f1"] >= floor
    assert planner.plan_kind[:2] == ("piece", True)


def test_a_new_episode_reuses_the_plan_exactly():
    env = make_env("c-major-chords", IKPlanner(), physics="fast")
    first, again = IKPlanner(), IKPlanner()
    actions = run_episode(env, first, seed=0).actions
    assert np.array_equal(run_episode(env, again, seed=0).actions, actions)
    for a, b in zip(first.plan.hands, again.plan.hands, strict=True):
        assert a.tx_path is b.tx_path  # made once, for the first episode


def test_a_finger_whose_key_does_not_sound_is_pushed_harder():
    # C major scale, frame 50: the middle finger holds E4. Told that the key has not sounded
    # for two steps while it pressed, the IK sends the fingertip further down.
    env, planner, _ = _step_planner("c-major-scale-right", 50)
    hand = planner.hands[0]
    finger = 2
    assert planner.memories[0].pressing[finger]
    # The count: a key that does not go down while its finger keeps pressing it.
    planner.key_threshold = planner.key_threshold + 1.0  # no key counts as sounding
    _targets(planner, 50, 55)
    assert planner.memories[0].unsounded[finger] == 1
    _targets(planner, 50, 55)
    assert planner.memories[0].unsounded[finger] == 2
    heights = {}
    targets, active = _targets(planner, 50, 55)
    for count in (0, 2):
        planner.memories[0].unsounded[finger] = count
        angles = _solve(planner, targets, active)
        # Where the commanded angles (the servo targets) put the fingertip.
        hand.fingers[finger].set(planner.scratch, angles[finger, : hand.fingers[finger].dof])
        mujoco.mj_kinematics(env.model, planner.scratch)
        heights[count] = planner.scratch.site_xpos[hand.sites[finger], 2]
    assert heights[2] < heights[0] - 0.003, heights  # 4.6 mm lower


def test_the_plan_is_returned_as_arrays_that_cover_the_played_keys():
    planner = IKPlanner()
    env = make_env("c-major-scale-both", planner, physics="fast")
    episode = run_episode(env, planner, seed=0)
    plan = planner.plan_arrays()
    T = env.unwrapped.num_steps
    assert plan["hand_key_span"].shape == (T, 2, 2) and plan["hand_sides"].tolist() == [
        "right",
        "left",
    ]
    assert plan["planned_fingers"].shape == (T, 88)
    # Each key played while due lies within the span of the hand whose finger plays it.
    frames, keys = np.nonzero(episode.active_keys & env.unwrapped.goal.keys)
    hand = plan["planned_fingers"][frames, keys] // 5
    low, high = plan["hand_key_span"][frames, hand].T
    inside = (keys >= low - 0.5) & (keys <= high + 0.5)
    assert inside.mean() > 0.95, inside.mean()


def test_each_finger_goes_through_named_states_as_it_plays():
    # Four repeated quarter notes with the middle finger: it hovers before the first, presses
    # each note, is let up between them to strike again, and is lifted after the last.
    notes = tuple(Note(64, 0.5 + 0.5 * i, 1.0 + 0.5 * i, finger=2) for i in range(4))
    planner = IKPlanner()
    env = PianoEnv(Song(notes, name="repeats"), physics="fast", **ENV_OPTIONS)
    episode = run_episode(env, planner, seed=0)
    states = planner.plan_arrays()["finger_states"]
    assert states.shape == (env.num_steps, 10)
    middle = states[:, 2]
    key = 64 - 21  # E4: keys are numbered from A0, MIDI pitch 21
    due = env.goal.keys[:, key]
    assert set(np.unique(middle[due])) <= {FingerState.PRESSING, FingerState.PUSHING}
    assert (middle == FingerState.RESTRIKING).sum() == 3  # once before each repeat
    assert FingerState.HOVERING in middle[: np.argmax(due)]
    assert middle[0] == FingerState.LIFTED  # far from its first note
    others = np.delete(states, 2, axis=1)
    assert not np.isin(others, [FingerState.PRESSING, FingerState.PUSHING]).any()
    # What the states say is what the keys did: the key is down in the steps it is pressed.
    pressed = np.isin(middle, [FingerState.PRESSING, FingerState.PUSHING])
    assert episode.active_keys[pressed, key].mean() > 0.8


def test_fingers_travel_during_a_jump():
    # Two notes 40 cm apart with the index finger and no time between them: a shift.
    notes = (Note(48, 0.3, 0.8, finger=1), Note(72, 0.8, 1.5, finger=1))
    planner = IKPlanner()
    env = PianoEnv(Song(notes, name="jump"), physics="fast", **ENV_OPTIONS)
    run_episode(env, planner, seed=0)
    states = planner.plan_arrays()["finger_states"][:, :5]
    right = planner.plan.hands[[hand.side for hand in planner.hands].index("right")]
    shifting = np.flatnonzero(right.free)
    assert shifting.size > 0
    assert np.all(states[shifting] != FingerState.PRESSING)
    assert (states[shifting, 1] == FingerState.TRAVELLING).any()


def test_the_joint_plan_of_both_hands_plays_with_its_own_split():
    # hand_planning="split": each key goes to the hand the joint plan gives it, with a finger
    # of that hand, and the chord song still plays (0.818 measured; 0.927 with "best").
    planner = IKPlanner(PlannerConfig().with_fields(hand_planning="split"))
    env = make_env("c-major-chords", planner, physics="fast")
    episode = run_episode(env, planner, seed=0)
    assert planner.plan_kind[:2] == ("split", True)
    assert episode.metrics()["f1"] >= 0.75
    goal = env.unwrapped.goal
    due = goal.keys & ~np.any([arrays.skip for arrays in planner.plan.hands], axis=0)
    assert np.all(planner.fingers[due] >= 0)  # one finger (of one hand) for each


def test_a_thumb_pressing_past_its_reach_gives_up_depth_not_lining_up():
    # C major scale, frame 4: the hand is over C4, which the thumb plays. A target 2-3 cm
    # below the key's top is past the thumb's reach: unweighted, the inverse kinematics gave
    # up 1.6-3 mm across the keys for it (in the pieces up to ~8 mm: the tip pressed the
    # crack between two keys); with the thumb's lateral weight it stays over the key.
    env, planner, _ = _step_planner("c-major-scale-right", 4)
    hand, m, scratch = planner.hands[0], planner.model, planner.scratch
    key = 60 - 21
    assert env.goal.fingers[3, key] == 0
    errors = {}
    for weight in (1.0, 4.0):
        config = planner.config.with_fields(thumb_lateral_weight=weight)
        for depth in (0.02, 0.03):
            target = planner.key_point[key].copy()
            target[0] = config.keys.thumb_white_press_x_m
            target[2] = planner.key_top_z[key] - depth
            scratch.qpos[:] = env.data.qpos
            mujoco.mj_kinematics(m, scratch)
            targets = np.zeros((5, 3))
            targets[0] = target - scratch.xpos[hand.forearm_body]
            _solve(planner, targets, np.array([True, False, False, False, False]), config)
            mujoco.mj_kinematics(m, scratch)
            errors[weight, depth] = abs(scratch.site_xpos[hand.fingers[0].site, 1] - target[1])
    for depth in (0.02, 0.03):
        assert errors[1.0, depth] > 0.0012, errors
        assert errors[4.0, depth] < 0.0005, errors


@pytest.mark.parametrize("unwedge", [True, False])
def test_a_thumb_wedged_between_two_keys_comes_free(unwedge):
    # K545 allegro, frames 77-91: the left thumb goes from G4 to A4 low over the keys and
    # catches below A4's top, touching both keys, 19 mm short of it; pushing sideways it stayed
    # there for 10 frames. Lifted clear for a step once it stands still there, it presses A4
    # from frame 80.
    env = PianoEnv(load_song("mozart-sonata-k545-allegro"), physics="fast", **ENV_OPTIONS)
    # The whole-piece plan with its own fingering, counting key-frames, as when this was seen.
    planner = IKPlanner(PlannerConfig().with_fields(unwedge=unwedge, best_candidates=("piece",)))
    observation, _ = env.reset(seed=0)
    planner.reset(env, seed=0)
    key = 69 - 21
    down = []
    for _ in range(92):
        observation, *_ = env.step(planner.act(observation))
        down.append(env.data.qpos[planner.key_qpos[key]] >= planner.key_threshold[key])
    due = np.flatnonzero(env.goal.keys[:92, key])
    assert due.min() == 77 and due.size == 12
    sounded = np.flatnonzero(np.array(down)[due])
    first = int(due[sounded[0]]) if sounded.size else 99
    if unwedge:
        assert first <= 81 and sounded.size >= 8, (first, sounded.size)
    else:
        assert first >= 85, first  # stuck for the first 8 frames of the note


@pytest.mark.parametrize("keep_sounding", [True, False])
def test_a_finger_holding_its_key_down_keeps_pressing_though_its_tip_slid(keep_sounding):
    # D major scale, frame 65: the ring finger holds C#5 down. With the key's press point
    # moved 2 cm across the keys (as the thumb's tip slides when it presses), the finger is far
    # off it, but its key sounds: it keeps pressing instead of coming up to line up again.
    key, finger, frame = 73 - 21, 3, 65
    env, planner, _ = _step_planner("d-major-scale-right", frame)
    assert planner.memories[0].pressing[finger]
    assert env.data.qpos[planner.key_qpos[key]] >= planner.key_threshold[key]
    planner.config = planner.config.with_fields(keep_sounding=keep_sounding)
    planner.key_point[key, 1] += 0.02
    _targets(planner, frame, frame + 5)
    assert planner.memories[0].pressing[finger] == keep_sounding


@pytest.mark.parametrize(
    ("pose", "home_push", "reach_push", "pushed"),
    [(0, 1.0, 0.0, True), (0, 0.0, 2.0, False), (1, 0.0, 2.0, True), (1, 1.0, 0.0, False)],
)
def test_a_pressing_finger_pushes_harder_when_the_keys_bend_the_wrist_up(
    pose, home_push, reach_push, pushed
):
    # D major scale, frame 65: the ring finger presses C#5. With the wrist bent up 0.15 rad
    # (as a chord's keys bend it), its command goes further down by the push per radian
    # along the direction that lowers its tip (``bent_wrist_push`` in the home pose,
    # ``reach_bent_wrist_push`` in a reach pose); with the wrist straight, not at all.
    frame, finger = 65, 3
    env, planner, _ = _step_planner("d-major-scale-right", frame)
    planner.config = planner.config.with_fields(
        bent_wrist_push=home_push, reach_bent_wrist_push=reach_push
    )
    hand, m, scratch = planner.hands[0], planner.model, planner.scratch
    targets, active = _targets(planner, frame, frame + 5)
    assert planner.memories[0].pressing[finger]
    wrist, ty = planner.poses[0][pose].wrist, planner.poses[0][pose].ty
    tips = {}
    for bent in (0.0, 0.15):
        scratch.qpos[:] = env.data.qpos
        set_wrist(scratch, None, hand, wrist, ty, planner.config)
        angles = _solve(planner, targets, active, pose=pose, bent_up=bent)
        hand.fingers[finger].set(scratch, angles[finger, : hand.fingers[finger].dof])
        mujoco.mj_kinematics(m, scratch)
        tips[bent] = scratch.site_xpos[hand.sites[finger]].copy()
    if pushed:
        assert tips[0.15][2] < tips[0.0][2] - 0.002, tips
    else:
        np.testing.assert_allclose(tips[0.15], tips[0.0])


def test_a_re_strike_is_pushed_down_again_from_its_first_step():
    # The mazurka's repeated chords (3-7 s: 43 keys struck again a frame after they were let
    # up). Pushed from the first step of the re-strike (``restrike_push_rad``), more of them
    # sound on time than with the servo alone (measured 35 against 31; F1 0.808 / 0.777).
    song = window(load_song("chopin-mazurka-op6-no2"), 3.0, 7.0)
    on_time, f1 = [], []
    for push in (PlannerConfig().ik.restrike_push_rad, (0.0,) * 5):
        env = PianoEnv(song, physics="fast", **ENV_OPTIONS)
        planner = IKPlanner(PlannerConfig().with_fields(restrike_push_rad=push))
        episode = run_episode(env, planner, seed=0)
        goal = env.goal.keys
        again = np.zeros_like(goal)
        again[2:] = goal[2:] & ~goal[1:-1] & goal[:-2]  # due, let up a frame before
        on_time.append(int((episode.active_keys & again).sum()))
        f1.append(episode.metrics()["f1"])
        states = planner.plan_arrays()["finger_states"]
        pushed_again = (states[1:] == FingerState.PUSHING) & (states[:-1] == FingerState.RESTRIKING)
        assert pushed_again.any() == any(p > 0 for p in push)
    assert again.sum() == 43
    assert on_time[0] >= on_time[1] + 2 and f1[0] > f1[1]


def _reference_ik(hand, pose, m, scratch, targets, active, cfg):
    """The IK solved one finger at a time, as ``ik.py`` documents it (no push)."""
    angles = {}
    for f, finger in enumerate(hand.fingers):
        if active[f]:
            samples, sample_tips, _ = pose.samples[f]
            tips = sample_tips - targets[f]
            angles[f] = samples[np.argmin((tips**2).sum(axis=1))].copy()
        else:
            angles[f] = pose.lift[f].copy()
        finger.set(scratch, angles[f])
    jacp = np.zeros((3, m.nv))
    for _ in range(cfg.ik.iterations):
        mujoco.mj_kinematics(m, scratch)
        mujoco.mj_comPos(m, scratch)
        origin = scratch.xpos[hand.forearm_body]
        for f in np.flatnonzero(active):
            finger = hand.fingers[f]
            error = targets[f] - (scratch.site_xpos[finger.site] - origin)
            mujoco.mj_jacSite(m, scratch, jacp, None, finger.site)
            J = finger.jacobian(jacp)
            if f == 0:
                weights = np.array([1.0, cfg.ik.thumb_lateral_weight, 1.0])
                J, error = J * weights[:, None], error * weights
            A = J.T @ J + (cfg.ik.damping**2 + cfg.ik.rest_weight) * np.eye(finger.dof)
            step = np.clip(
                np.linalg.solve(A, J.T @ error), -cfg.ik.step_limit_rad, cfg.ik.step_limit_rad
            )
            angles[f] = np.clip(angles[f] + step, finger.low, finger.high)
            finger.set(scratch, angles[f])
    return np.concatenate([angles[f] for f in range(len(hand.fingers))])


def test_the_fingers_solved_together_match_each_finger_solved_alone():
    # The IK pads the five fingers to one width and solves them in one batch; every finger
    # must end where the one-at-a-time solve puts it, for any subset of active fingers.
    # The full action space, its joints all moved: the thumb has five actuators, the little
    # finger four.
    env = PianoEnv("c-major-scale-both", physics="fast", **ENV_OPTIONS, reduced_action_space=False)
    planner = IKPlanner(PlannerConfig(full_hand=True))
    env.reset(seed=0)
    planner.reset(env, seed=0)
    m, scratch, cfg = env.model, planner.scratch, planner.config
    rng = np.random.default_rng(3)
    for h, hand in enumerate(planner.hands):
        planner.memories[h].pressing[:] = False  # the push after the solve is checked elsewhere
        home = planner.poses[h][0]
        assert len({finger.dof for finger in hand.fingers}) > 1  # padding is exercised
        for trial in range(6):
            active = rng.random(5) < 0.6
            active[trial % 5] = True
            # Targets around the fingers' resting places, some beyond their reach.
            targets = home.rest_tips + rng.normal(0.0, 0.015, (5, 3))
            start = env.data.qpos.copy()
            scratch.qpos[:] = start
            batched = finger_controls(hand, _solve(planner, targets, active, hand=h))
            solved_qpos = scratch.qpos.copy()
            scratch.qpos[:] = start
            reference = _reference_ik(hand, home, m, scratch, targets, active, cfg)
            np.testing.assert_allclose(batched, reference, atol=1e-9)
            np.testing.assert_allclose(solved_qpos, scratch.qpos, atol=1e-9)
