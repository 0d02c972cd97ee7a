"""The planner's soft strike (``PlannerConfig.soft_velocity``): a soft note's finger rests on
its key and presses it shallower and earlier, so the key goes down slower and sounds softer."""

import numpy as np

from pianist.control.planner import IKPlanner, PlannerConfig
from pianist.eval.session import make_env, play
from pianist.media.results import played_dynamics

SOFT = PlannerConfig(soft_velocity=70, soft_hover_m=0.0, soft_depth_ratio=0.3, soft_lead_frames=1)


def _velocities(config: PlannerConfig) -> tuple[np.ndarray, np.ndarray]:
    """(performed, score) MIDI velocities of voiced-melody's matched notes (95 over 40)."""
    result = play("voiced-melody", IKPlanner(config), physics="fast", seed=0)
    pairs = played_dynamics(result)[2]
    return np.array([p.velocity for p, _ in pairs]), np.array([s.velocity for _, s in pairs])


def test_soft_notes_sound_softer_than_the_loud_ones_and_than_without():
    performed, score = _velocities(SOFT)
    plain, plain_score = _velocities(PlannerConfig())
    soft = score < 70
    assert soft.any() and (~soft).any()
    assert np.median(performed[soft]) <= np.median(performed[~soft]) - 15
    assert np.median(performed[soft]) <= np.median(plain[plain_score < 70]) - 10


def test_a_song_of_one_velocity_has_no_soft_notes():
    planner = IKPlanner(SOFT)
    env = make_env("c-major-chords", planner, physics="fast")
    env.reset(seed=0)
    planner.setup(env)
    assert planner.goal.keys.any() and not planner.soft.any()
    planner = IKPlanner(SOFT)
    env = make_env("voiced-melody", planner, physics="fast")
    env.reset(seed=0)
    planner.setup(env)
    soft = planner.soft[planner.goal.keys]
    assert soft.any() and not soft.all()
