"""Piano-roll plot of an episode: counts of correct, wrong and missed key-steps, PNG output."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pianist.eval import Episode
from pianist.media import MediaError, pianoroll_counts, plot_pianoroll

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _episode(sustain: bool = False) -> Episode:
    steps = 10
    goal = np.zeros((steps, 88), dtype=bool)
    active = np.zeros((steps, 88), dtype=bool)
    goal[0:6, 39] = True  # C4 due for 6 steps ...
    active[2:6, 39] = True  # ... played for the last 4: 4 correct, 2 missed
    goal[4:10, 43] = True  # E4 due for 6 steps, never played: 6 missed
    active[7:9, 50] = True  # B4 played for 2 steps, never due: 2 wrong
    active[9, 39] = True  # C4 again after it ended: 1 wrong
    terms = {
        "key_press": np.linspace(0, 1, steps),
        "energy": np.full(steps, 150.0),  # raw energy is large: symlog axis
    }
    return Episode(
        actions=np.zeros((steps, 3)),
        active_keys=active,
        sustain=np.arange(steps) >= 5 if sustain else np.zeros(steps, dtype=bool),
        goal_keys=goal,
        goal_sustain=np.arange(steps) >= 3 if sustain else np.zeros(steps, dtype=bool),
        rewards=terms["key_press"] - 0.005 * terms["energy"],
        reward_terms=terms,
        note_events=np.zeros((0, 3)),
        control_timestep_s=0.05,
        end_time_s=0.5,
    )


def test_counts_match_a_hand_built_episode() -> None:
    assert pianoroll_counts(_episode()) == {"correct": 4, "wrong": 3, "missed": 8}


def test_plot_writes_a_png_and_returns_the_counts(tmp_path) -> None:
    import matplotlib.image

    path = tmp_path / "roll.png"
    counts = plot_pianoroll(_episode(), path, title="hand-built", size_in=(8.0, 5.0), dpi=50)
    assert counts == {"correct": 4, "wrong": 3, "missed": 8}
    assert path.read_bytes()[:8] == PNG_MAGIC
    image = matplotlib.image.imread(path)
    assert image.shape[:2] == (250, 400) and image.shape[2] in (3, 4)
    assert not list(tmp_path.glob(".roll.png.*"))  # no temporary file left behind


def test_plot_with_pedal_lane_and_weights(tmp_path) -> None:
    path = tmp_path / "pedal.png"
    weights = {"key_press": 1.0, "energy": -0.005}
    plot_pianoroll(_episode(sustain=True), path, weights=weights, dpi=40)
    assert path.read_bytes()[:8] == PNG_MAGIC


def test_plot_of_an_episode_with_no_keys(tmp_path) -> None:
    ep = _episode()
    ep = dataclasses.replace(
        ep, goal_keys=np.zeros_like(ep.goal_keys), active_keys=np.zeros_like(ep.active_keys)
    )
    assert plot_pianoroll(ep, tmp_path / "empty.png", dpi=40) == {
        "correct": 0,
        "wrong": 0,
        "missed": 0,
    }


def test_bad_episodes_raise(tmp_path) -> None:
    ep = _episode()
    with pytest.raises(MediaError, match="active_keys"):
        plot_pianoroll(dataclasses.replace(ep, active_keys=ep.active_keys[:5]), tmp_path / "a.png")
    empty = dataclasses.replace(
        ep,
        active_keys=np.zeros((0, 88), bool),
        goal_keys=np.zeros((0, 88), bool),
        sustain=np.zeros(0, bool),
        goal_sustain=np.zeros(0, bool),
    )
    with pytest.raises(MediaError, match="no steps"):
        plot_pianoroll(empty, tmp_path / "b.png")
    bad_terms = dataclasses.replace(ep, reward_terms={"key_press": np.zeros(3)})
    with pytest.raises(MediaError, match="reward series"):
        plot_pianoroll(bad_terms, tmp_path / "c.png")
    with pytest.raises(MediaError, match="cannot write"):
        plot_pianoroll(ep, tmp_path / "missing" / "d.png")
    assert not list(tmp_path.glob("*.png"))


def test_the_planned_hand_spans_are_shaded_on_the_roll(tmp_path) -> None:
    import matplotlib.image

    plain, shaded = tmp_path / "plain.png", tmp_path / "shaded.png"
    plot_pianoroll(_episode(), plain, size_in=(8.0, 5.0), dpi=50)
    episode = _episode()
    span = np.zeros((10, 1, 2))
    span[:, 0] = (30.0, 45.0)  # the right hand reaches keys 30-45 throughout
    episode.extra.update(hand_key_span=span, hand_sides=np.array(["right"]))
    plot_pianoroll(episode, shaded, size_in=(8.0, 5.0), dpi=50)
    a, b = matplotlib.image.imread(plain), matplotlib.image.imread(shaded)
    changed = np.abs(a - b).sum(axis=-1) > 0.05
    assert changed.sum() > 1000  # the band (and its legend entry) is drawn


def test_the_planned_wrist_turns_are_hatched_on_the_roll(tmp_path) -> None:
    import matplotlib.image

    straight, turned = tmp_path / "straight.png", tmp_path / "turned.png"
    span = np.zeros((10, 1, 2))
    span[:, 0] = (30.0, 45.0)
    images = []
    for path, poses in ((straight, np.zeros((10, 1), int)), (turned, np.ones((10, 1), int))):
        episode = _episode()
        episode.extra.update(hand_key_span=span, hand_sides=np.array(["right"]), hand_pose=poses)
        plot_pianoroll(episode, path, size_in=(8.0, 5.0), dpi=50)
        images.append(matplotlib.image.imread(path))
    changed = np.abs(images[0] - images[1]).sum(axis=-1) > 0.05
    assert changed.sum() > 200  # the hatching over the band (and its legend entry)
