"""The registry of controller kinds: one parser for every kind's string form, round trips,
one-line refusals, lazy registration, and the help listing each kind's options."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from typing import ClassVar

import numpy as np
import pytest

from pianist.control import BaseController
from pianist.control.registry import (
    KINDS,
    ControllerSpec,
    controller_help,
    field_docs,
    parse_controller,
    register,
    spec_class,
)
from pianist.control.specs import MPCSpec, PlannerSpec, RefineSpec, SearchSpec, refined

#: A spec string of every kind, options set where the kind has them.
EXAMPLES = {
    "planner": "planner:push_below_velocity=90",
    "refine": "refine:candidates=16,horizon_steps=6,sigma=0.2,keep_previous=false",
    "search": "search:refine,segment_steps=5,variants=plain+stiff-wrist,push_below_velocity=80",
    "mpc": "mpc:tenth,iterations=2,seed=3,interpolation=linear",
    "generalist": "generalist:forearm=policy",
    "policy": "policy:runs/twinkle",
    "bc": "bc:/tmp/policies/bc one",
    "random": "random",
    "zero": "zero",
    "replay": "replay:out/actions.npy",
}


def test_every_kind_has_an_example():
    assert set(EXAMPLES) == set(KINDS)


@pytest.mark.parametrize("kind", sorted(EXAMPLES))
def test_every_kind_round_trips(kind):
    spec = parse_controller(EXAMPLES[kind])
    assert spec.kind == kind and type(spec) is spec_class(kind)
    assert parse_controller(str(spec)) == spec
    defaults = spec_class(kind)()
    if spec_class(kind).path_field is None:
        assert parse_controller(str(defaults)) == defaults
        assert str(defaults) == kind  # the defaults are the bare kind


def test_strings_round_trip_exactly_where_they_are_canonical():
    for text in (
        "refine:candidates=16,horizon_steps=6",
        "search:refine,variants=plain+stiff-wrist",
        "mpc:tenth,iterations=2",
        "generalist:forearm=policy",
        "replay:a,b=c.npy",  # a path is taken whole, commas and all
    ):
        assert str(parse_controller(text)) == text


def test_values_are_typed():
    refine = parse_controller("refine:candidates=16,sigma=0.2,open_loop=yes")
    assert isinstance(refine, RefineSpec)
    assert (refine.candidates, refine.sigma, refine.open_loop) == (16, 0.2, True)
    mpc = parse_controller("mpc:tenth,num-samples=30,seed=none")
    assert isinstance(mpc, MPCSpec)
    assert (mpc.num_samples, mpc.sigma, mpc.seed) == (30, 0.2, None)  # the preset's sigma
    search = parse_controller("search:variants=plain+low-hover")
    assert isinstance(search, SearchSpec) and search.variants == ("plain", "low-hover")


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("planner9000", "unknown controller 'planner9000'; use planner"),
        ("refine:samples=3", "unknown refine option 'samples'; use candidates, horizon_steps"),
        ("refine:candidates=many", "refine option candidates needs a whole number, not 'many'"),
        ("refine:sigma=loud", "refine option sigma needs a finite number"),
        ("refine:open_loop=maybe", "needs true or false"),
        ("refine:fast", "refine option 'fast' needs NAME=VALUE; options: candidates"),
        ("refine:", "nothing after the colon"),
        ("refine:horizon_steps=0", "horizon_steps >= 1"),
        ("mpc:fancy", "or, first, a preset .paper, tenth."),
        ("mpc:interpolation=bogus", "needs one of zero, linear, cubic, not 'bogus'"),
        ("search:mpc", "search option base needs one of planner, refine, not 'mpc'"),
        ("search:variants=plain+louder", "unknown search variants"),
        ("generalist:forearm=sideways", "needs one of plan, policy"),
        ("planner:fast=1", "unknown planner option 'fast'; use push_below_velocity"),
        ("planner:push_below_velocity=-3", "MIDI velocity from 0 to 128, not -3"),
        ("refine:push_below_velocity=200", "refine option push_below_velocity needs a MIDI"),
        ("policy:", "needs a path: policy:RUN_DIR"),
        ("mpc:horizon_s=inf", "mpc option horizon_s needs a finite number, not 'inf'"),
        ("refine:wrong_weight=nan", "needs a finite number"),
        ("refine:sigma=1e400", "needs a finite number"),
        ("refine:candidates=2,candidates=3", "refine option candidates is given twice"),
        ("random:seed=1", "random takes no options: use random"),
        ("mpc:iterations=1,tenth", "a preset .tenth. comes first"),
        ("replay: ", "needs a path: replay:ACTIONS"),
    ],
)
def test_bad_specs_are_one_line_naming_what_is_allowed(text, words):
    with pytest.raises(ValueError, match=words) as caught:
        parse_controller(text)
    assert "\n" not in str(caught.value)


def test_unknown_kinds_list_every_kind():
    with pytest.raises(ValueError) as caught:
        parse_controller("nope")
    for kind in KINDS:
        assert kind in str(caught.value)


def test_every_option_has_help_and_the_help_lists_them():
    text = controller_help()
    verbose = controller_help(options_help=True)
    for kind in KINDS:
        cls = spec_class(kind)
        assert cls.__doc__, kind
        assert f"\n{kind}" in f"\n{text}"
        docs = field_docs(cls)
        for field in dataclasses.fields(cls):
            assert docs.get(field.name), f"{kind}.{field.name} has no help"
            if cls.path_field is None:
                assert f"{field.name}=" in text and f"{field.name}=" in verbose
            else:
                assert f"{kind}:{field.name.upper()}" in text
    assert "candidates=8" in text  # with the defaults
    assert ":mod:" not in text and "``" not in text  # docstring markup made plain


def test_cli_help_of_controller_lists_the_registry(capsys):
    from pianist.cli import main

    with pytest.raises(SystemExit):
        main(["play", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for kind in KINDS:
        assert kind in out
    for option in (
        "horizon_steps=4",
        "segment_steps=10",
        "num_samples=10",
        "forearm=none(plan|policy)",
    ):
        assert option in out.replace("│", "").replace(" ", "") or option in out


def test_refined_puts_the_refiner_in_the_planners_place():
    assert refined(PlannerSpec()) == RefineSpec()
    # The planner's loudness option goes with it, into the refiner's planner.
    spec = refined(PlannerSpec(push_below_velocity=90))
    assert spec == RefineSpec(push_below_velocity=90)
    assert spec.build().planner.config.strikes.push_below_velocity == 90
    search = SearchSpec(base="refine", push_below_velocity=70).build()
    assert search.base.planner.config.strikes.push_below_velocity == 70
    assert refined(RefineSpec(candidates=3)) == RefineSpec(candidates=3)
    assert refined(SearchSpec(segment_steps=5)) == SearchSpec(base="refine", segment_steps=5)
    with pytest.raises(ValueError, match="--refine refines the planner, not --controller mpc"):
        refined(MPCSpec())


class _Hold(BaseController):
    def __init__(self, level: float) -> None:
        self.level = level

    def reset(self, env, seed=None) -> None:
        self.action = np.full(env.action_space.shape, self.level, dtype=np.float32)

    def act(self, observation) -> np.ndarray:
        return self.action


@dataclasses.dataclass(frozen=True)
class _HoldSpec(ControllerSpec):
    """Every actuator held at one action."""

    kind: ClassVar[str] = "hold-test"
    level: float = 0.0
    """The action held, in [-1, 1]."""

    def build(self) -> _Hold:
        return _Hold(self.level)


def test_a_new_kind_is_one_registration_and_plays():
    import pianist.control.registry as registry
    from pianist.eval.session import play

    register("hold-test", _HoldSpec)
    try:
        spec = parse_controller("hold-test:level=0.25")
        assert spec == _HoldSpec(level=0.25) and str(spec) == "hold-test:level=0.25"
        result = play("twinkle-twinkle", spec.build(), physics="fast", seed=0)
        assert np.all(result.episode.actions == np.float32(0.25))
    finally:
        KINDS.pop("hold-test")
        registry._loaded.pop("hold-test")


def test_reading_any_spec_loads_no_simulator_and_the_planner_no_jax():
    code = (
        "import sys\n"
        "from pianist.control.registry import KINDS, parse_controller, controller_help\n"
        "controller_help()\n"
        "[parse_controller(k + ':x' if k in ('policy', 'bc', 'replay') else k) for k in KINDS]\n"
        "assert 'mujoco' not in sys.modules and 'gymnasium' not in sys.modules, 'sim loaded'\n"
        "parse_controller('planner').build()\n"
        "assert 'jax' not in sys.modules, 'jax loaded'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_installed_package_declares_a_kind_by_entry_point(monkeypatch):
    from importlib.metadata import EntryPoint

    import pianist.control.registry as registry

    point = EntryPoint("hold-test", f"{__name__}:_HoldSpec", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry, "_plugins_read", False)
    monkeypatch.setattr(
        "importlib.metadata.entry_points",
        lambda group: [point] if group == registry.ENTRY_POINT_GROUP else [],
    )
    try:
        assert parse_controller("hold-test:level=0.5") == _HoldSpec(level=0.5)
        assert "hold-test: Every actuator held at one action." in controller_help()
    finally:
        KINDS.pop("hold-test", None)
        registry._loaded.pop("hold-test", None)


def test_a_broken_plugin_is_named_in_the_help_and_breaks_nothing_else(monkeypatch):
    monkeypatch.setitem(KINDS, "broken-test", "no_such_module_here:Spec")
    text = controller_help()
    assert "broken-test: cannot be loaded" in text and "planner: " in text
    with pytest.raises(ValueError, match="'broken-test' cannot be loaded from no_such_module"):
        parse_controller("broken-test")
    # An unknown kind is still named as such, the broken one listed among the kinds.
    with pytest.raises(ValueError, match="unknown controller 'nope'; use planner"):
        parse_controller("nope")
