"""The planner's settings: one group per stage, every field documented, changed by name."""

from __future__ import annotations

import ast
import dataclasses
import inspect

import pytest

from pianist.control.planner import (
    FingerConfig,
    IKConfig,
    PlanConfig,
    PlannerConfig,
    StrikeConfig,
)
from pianist.control.planner import config as config_module


def _group_classes() -> dict[str, type]:
    defaults = PlannerConfig()
    return {
        f.name: type(getattr(defaults, f.name))
        for f in dataclasses.fields(PlannerConfig)
        if dataclasses.is_dataclass(getattr(defaults, f.name))
    }


def test_the_settings_are_split_by_stage_with_unique_names():
    groups = _group_classes()
    assert set(groups) == {"keys", "poses", "forearm", "fingers", "strikes", "plan", "ik"}
    names = [f.name for cls in groups.values() for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names))  # a field's name says which group it is in
    assert len(names) > 60


def test_every_setting_has_a_docstring():
    # Each field's unit is in its name or its docstring, and its docstring says why.
    tree = ast.parse(inspect.getsource(config_module))
    classes = {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}
    missing = []
    for cls in [*_group_classes().values(), PlannerConfig]:
        body = classes[cls.__name__].body
        for i, node in enumerate(body):
            if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                if node.target.id in _group_classes():
                    continue  # a group: its class has the docstring
                documented = (
                    i + 1 < len(body)
                    and isinstance(body[i + 1], ast.Expr)
                    and isinstance(getattr(body[i + 1], "value", None), ast.Constant)
                )
                if not documented:
                    missing.append(f"{cls.__name__}.{node.target.id}")
    assert missing == []


def test_fields_are_changed_by_their_own_names():
    config = PlannerConfig().with_fields(
        hover_height_m=0.005, damping=0.02, hand_planning="piece", push_below_velocity=90
    )
    assert config.fingers == FingerConfig(hover_height_m=0.005)
    assert config.ik == IKConfig(damping=0.02)
    assert config.plan == PlanConfig(hand_planning="piece")
    assert config.strikes == StrikeConfig(push_below_velocity=90)
    assert config.keys == PlannerConfig().keys  # the other groups as they were
    built = PlannerConfig(
        fingers=FingerConfig(hover_height_m=0.005),
        ik=IKConfig(damping=0.02),
        plan=PlanConfig(hand_planning="piece"),
        strikes=StrikeConfig(push_below_velocity=90),
    )
    assert config == built and hash(config) == hash(built)  # it keys the caches
    assert PlannerConfig().with_fields(full_hand=True).full_hand
    # Lists (as from JSON) are kept as tuples: the config keys the caches.
    listed = PlannerConfig().with_fields(
        best_candidates=["frame", "piece-f1"], reach_poses=[[-0.44, 0.28, 0.0, 0.0]]
    )
    assert listed == PlannerConfig().with_fields(
        best_candidates=("frame", "piece-f1"), reach_poses=((-0.44, 0.28, 0.0, 0.0),)
    )
    assert hash(listed) == hash(
        PlannerConfig().with_fields(
            best_candidates=("frame", "piece-f1"), reach_poses=((-0.44, 0.28, 0.0, 0.0),)
        )
    )
    with pytest.raises(ValueError, match="no field 'hover_height'"):
        PlannerConfig().with_fields(hover_height=0.005)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"push_below_velocity": 200}, "push_below_velocity"),
        ({"best_candidates": ("nonsense",)}, "best_candidates"),
        ({"reach_poses": ((0.1, 0.2),)}, "reach_poses"),
        ({"pose_change_s": 0.0}, "pose_change_s"),
        ({"shift_delay_max_frames": -1}, "shift_delay_max_frames"),
    ],
)
def test_each_group_refuses_its_bad_values(changes, message):
    with pytest.raises(ValueError, match=message):
        PlannerConfig().with_fields(**changes)
