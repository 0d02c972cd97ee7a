"""Controller kinds and their specs: the one place where a controller's string form is read.

A *spec* is a frozen dataclass deriving from :class:`ControllerSpec`: its fields are the
kind's options (typed, with a default, and a docstring that is their help) and
:meth:`ControllerSpec.build` makes the controller. From Python a spec is an object
(``RefineSpec(candidates=16).build()``); on the command line and in sweep grids it is a
string, which :func:`parse_controller` reads and ``str(spec)`` writes back:

- ``KIND``: the defaults (``planner``, ``refine``, ``random``);
- ``KIND:NAME=VALUE,...``: options by name (``refine:candidates=16,horizon_steps=6``); a
  value is parsed by its field's type: a number, ``true``/``false``, one of a literal's
  names, ``none`` for an optional field, and ``A+B`` for a tuple of names;
- a bare item sets the kind's :attr:`~ControllerSpec.positional` field
  (``search:refine,segment_steps=5``) or, first, names one of its
  :attr:`~ControllerSpec.presets` (``mpc:tenth,iterations=2``);
- ``KIND:PATH`` for a kind with a :attr:`~ControllerSpec.path_field` (``policy:RUN_DIR``):
  the rest of the string, whole.

The kinds are listed once, in :data:`KINDS`, by the import path of their spec class: a spec
module is only imported when its kind is asked for, so the planner never imports JAX. A kind
outside the package is added with :func:`register`, or, for the command line, by the package
that holds it as an entry point of the group ``pianist.controllers``
(``hold = "mypackage.hold:HoldSpec"``), read when the kinds are first listed or looked up.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import json
import math
import re
import textwrap
import types
from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Union, get_args, get_origin

if TYPE_CHECKING:
    from pianist.control.base import Controller

#: Every controller kind, and the spec class that reads it (``module:Class``), in the order
#: the help lists them.
KINDS: dict[str, str] = {
    "planner": "pianist.control.specs:PlannerSpec",
    "refine": "pianist.control.specs:RefineSpec",
    "search": "pianist.control.specs:SearchSpec",
    "mpc": "pianist.control.specs:MPCSpec",
    "generalist": "pianist.agents.specs:GeneralistSpec",
    "policy": "pianist.agents.specs:PolicySpec",
    "bc": "pianist.agents.specs:BCSpec",
    "random": "pianist.control.specs:RandomSpec",
    "zero": "pianist.control.specs:ZeroSpec",
    "replay": "pianist.control.specs:ReplaySpec",
}


@dataclasses.dataclass(frozen=True)
class ControllerSpec:
    """A controller kind's options; subclasses are frozen dataclasses of them.

    Class attributes a subclass sets:
        kind: its name in the string form (``refine``).
        positional: the field a bare item sets (``search:refine``), if any.
        path_field: the field that takes the whole text after ``KIND:`` (a path), if any.
        presets: named sets of field values a bare first item selects (``mpc:tenth``).
        needs_fingering: whether it plays only songs with a finger for every note (the
            planner and what is built on it).
    """

    kind: ClassVar[str] = ""
    positional: ClassVar[str | None] = None
    path_field: ClassVar[str | None] = None
    presets: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    needs_fingering: ClassVar[bool] = False

    def build(self) -> Controller:
        """The controller these options describe."""
        raise NotImplementedError(f"{type(self).__name__} does not build a controller")

    def uses_seed(self) -> bool:
        """Whether the episode's seed changes what this controller plays (in an environment
        that does not randomise its start, the default): False for a deterministic one, so
        that a sweep over seeds can say its rows will be the same. True unless a kind says
        otherwise."""
        return True

    def __str__(self) -> str:
        return format_controller(self)


def register(kind: str, target: str | type[ControllerSpec]) -> None:
    """Add a controller kind: ``target`` is its spec class or its import path
    (``"mypackage.hold:HoldSpec"``, imported when the kind is first used)."""
    if not kind or not kind.replace("-", "").replace("_", "").isalnum():
        raise ValueError(f"a controller kind is a name of letters, digits, - and _, not {kind!r}")
    if isinstance(target, str):
        KINDS[kind] = target
        _loaded.pop(kind, None)  # imported from there when next asked for
    else:
        KINDS[kind] = f"{target.__module__}:{target.__qualname__}"
        _loaded[kind] = target


_loaded: dict[str, type[ControllerSpec]] = {}

#: The entry-point group installed packages declare their controller kinds in.
ENTRY_POINT_GROUP = "pianist.controllers"
_plugins_read = False


def _read_plugins() -> None:
    """Add the kinds installed packages declare (:data:`ENTRY_POINT_GROUP`), once; a kind of
    the package's own is never replaced."""
    global _plugins_read
    if _plugins_read:
        return
    _plugins_read = True
    from importlib.metadata import entry_points

    for point in entry_points(group=ENTRY_POINT_GROUP):
        KINDS.setdefault(point.name, point.value)


def spec_class(kind: str) -> type[ControllerSpec]:
    """The spec class of ``kind`` (its module imported on first use).

    Raises:
        ValueError: an unknown kind, named with the kinds there are, or one whose spec
            cannot be imported (a broken plugin).
    """
    if kind not in KINDS:
        _read_plugins()
    if kind not in KINDS:
        raise ValueError(f"unknown controller {kind!r}; use {kinds_line()}")
    if kind not in _loaded:
        module, _, name = KINDS[kind].partition(":")
        try:
            cls = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as exc:
            raise ValueError(
                f"controller kind {kind!r} cannot be loaded from {KINDS[kind]} ({exc})"
            ) from None
        if not (isinstance(cls, type) and issubclass(cls, ControllerSpec)) or cls.kind != kind:
            raise TypeError(f"{KINDS[kind]} is not the ControllerSpec of kind {kind!r}")
        _loaded[kind] = cls
    return _loaded[kind]


def parse_controller(text: str | ControllerSpec) -> ControllerSpec:
    """The spec a controller string names (see the module docstring); a spec is returned as
    it is.

    Raises:
        ValueError: an unknown kind, option, preset or value, in one line naming what is
            allowed, or options the kind refuses together.
    """
    if isinstance(text, ControllerSpec):
        return text
    kind, colon, rest = text.strip().partition(":")
    cls = spec_class(kind)
    if cls.path_field is not None:
        if not rest.strip():
            raise ValueError(f"--controller {kind}: needs a path: {kind}:{cls.path_field.upper()}")
        return cls(**{cls.path_field: rest.strip()})
    if colon and not rest.strip():
        raise ValueError(f"--controller {text!r}: nothing after the colon; use {kind}")
    hints = _field_types(cls)
    values: dict[str, Any] = {}
    items = [item.strip() for item in rest.split(",") if item.strip()]
    if items and not hints:
        raise ValueError(f"{kind} takes no options: use {kind}")
    if items and "=" not in items[0] and items[0] in cls.presets:
        values.update(cls.presets[items.pop(0)])
    given: set[str] = set()
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip().replace("-", "_")
        if not sep:
            if item in cls.presets:
                raise ValueError(f"{kind}: a preset ({item}) comes first, before the options")
            if cls.positional is None:
                extra = f" or, first, a preset ({', '.join(cls.presets)})" if cls.presets else ""
                raise ValueError(
                    f"{kind} option {item!r} needs NAME=VALUE{extra}; options: {', '.join(hints)}"
                )
            name, value = cls.positional, item
        elif name not in hints:
            raise ValueError(f"unknown {kind} option {name!r}; use {', '.join(hints)}")
        if name in given:
            raise ValueError(f"{kind} option {name} is given twice")
        given.add(name)
        values[name] = _parse_value(kind, name, hints[name], value.strip())
    return cls(**values)


def format_controller(spec: ControllerSpec) -> str:
    """The string form of ``spec`` (:func:`parse_controller` reads it back to an equal spec):
    its kind, the preset nearest to it, and each option that differs from that."""
    cls = type(spec)
    if cls.path_field is not None:
        return f"{cls.kind}:{getattr(spec, cls.path_field)}"
    values = {f.name: getattr(spec, f.name) for f in dataclasses.fields(spec)}
    defaults = {f.name: getattr(cls(), f.name) for f in dataclasses.fields(spec)}
    best: tuple[str | None, dict[str, Any]] = (None, defaults)
    for name, preset in cls.presets.items():
        base = {**defaults, **preset}
        if len(_differing(values, base)) < len(_differing(values, best[1])):
            best = (name, base)
    items = [best[0]] if best[0] is not None else []
    for name in _differing(values, best[1]):
        if name == cls.positional:  # after the preset, which comes first
            items.insert(1 if best[0] is not None else 0, _format_value(values[name]))
        else:
            items.append(f"{name}={_format_value(values[name])}")
    return cls.kind + (":" + ",".join(items) if items else "")


def build_controller(spec: str | ControllerSpec) -> Controller:
    """The controller of a spec or its string form (:func:`parse_controller`)."""
    return parse_controller(spec).build()


def kinds_line() -> str:
    """The kinds with the shape of their options, for an error message."""
    _read_plugins()
    forms = []
    for kind in KINDS:
        path = _path_form(kind)
        forms.append(f"{kind}:{path}" if path else f"{kind}[:...]")
    return ", ".join(forms)


def controller_help(options_help: bool = False, width: int = 96) -> str:
    """Every kind with its summary and its options with their defaults, for ``--help``;
    with ``options_help`` each option on a line of its own with the first sentence of its
    help."""
    _read_plugins()
    lines = []
    for kind in list(KINDS):
        try:
            cls = spec_class(kind)
        except (ValueError, TypeError) as exc:  # a plugin that is broken
            lines.append(f"{kind}: cannot be loaded ({exc})")
            continue
        summary = _plain(_first_sentence(inspect.getdoc(cls) or "")) + _speed_text(kind)
        if cls.path_field is not None:
            lines.append(f"{kind}:{cls.path_field.upper()}: {summary}")
            continue
        presets = f" Presets: {', '.join(cls.presets)}." if cls.presets else ""
        lines.append(f"{kind}: {summary}{presets}")
        defaults = cls()
        docs = field_docs(cls)
        hints = _field_types(cls)
        values = [
            (f.name, _format_value(getattr(defaults, f.name)) + _choices(hints[f.name]))
            for f in dataclasses.fields(cls)
        ]
        if options_help:
            for name, value in values:
                text = f"  {name}={value}: {_plain(_first_sentence(docs.get(name, '')))}"
                lines.append(textwrap.shorten(text, width, placeholder="..."))
        elif values:
            lines.append("  options: " + ", ".join(f"{name}={value}" for name, value in values))
    return "\n".join(lines)


#: The measured speeds (``benchmarks/bench_speeds.py --write``), beside this module.
SPEEDS_FILE = Path(__file__).with_name("speeds.json")


@cache
def measured_speeds() -> dict[str, Any]:
    """``speeds.json``: per controller string, the median real-time factor per physics preset
    (``kinds``), and when, where and on what it was measured; empty if it is missing."""
    try:
        speeds = json.loads(SPEEDS_FILE.read_text())
    except (OSError, ValueError):
        return {}
    return speeds if isinstance(speeds, dict) else {}


def speeds_table(speeds: dict[str, Any]) -> str:
    """The README's table of the measured speeds (Markdown), from :func:`measured_speeds`."""
    lines = [
        "| controller | real time, faithful / fast (median; above 1x: faster than the music) |",
        "|---|---|",
    ]
    for kind, row in speeds.get("kinds", {}).items():
        faithful, fast = (row.get(p) for p in ("faithful", "fast"))
        text = [realtime_text(x) if x is not None else "-" for x in (faithful, fast)]
        lines.append(f"| `{kind}` | {text[0]} / {text[1]} |")
    lines += [
        "",
        f"Measured by `python benchmarks/bench_speeds.py --write` on {speeds.get('date')} "
        f"({speeds.get('machine')}; {speeds.get('what')}).",
    ]
    return "\n".join(lines)


def _speed_text(kind: str) -> str:
    """`` Measured: 7.2x real time faithful, 11x fast.`` for a kind in the speeds file."""
    row = measured_speeds().get("kinds", {}).get(kind)
    if not row:
        return ""
    parts = [f"{realtime_text(value)} {preset}" for preset, value in row.items()]
    return f" Measured: {', '.join(parts)} (real time)."


def realtime_text(factor: float) -> str:
    """A real-time factor to two significant figures: ``0.044x``, ``0.50x``, ``1.0x``,
    ``12x``."""
    if not math.isfinite(factor):
        return "inf x"
    if factor >= 9.95:
        return f"{factor:.0f}x"
    return f"{factor:#.2g}".rstrip(".") + "x"


def _choices(annotation: Any) -> str:
    """`` (plan|policy)`` for a field whose values are a literal's names."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin in (Union, types.UnionType):
        args = tuple(a for a in args if a is not type(None))
        if len(args) == 1:
            origin, args = get_origin(args[0]), get_args(args[0])
    return f" ({'|'.join(map(str, args))})" if origin is Literal else ""


def _plain(text: str) -> str:
    """Docstring markup as plain text: roles (:mod:`x`) and literals (``x``) unwrapped."""
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)
    return text.replace("``", "")


def field_docs(cls: type) -> dict[str, str]:
    """Each field's docstring (the string literal written under it) in ``cls`` and its
    bases; empty where the source cannot be read."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        docs.update(_own_field_docs(klass))
    return docs


@cache
def _own_field_docs(cls: type) -> dict[str, str]:
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    docs = {}
    for first, second in zip(body, body[1:], strict=False):
        if (
            isinstance(first, ast.AnnAssign)
            and isinstance(first.target, ast.Name)
            and isinstance(second, ast.Expr)
            and isinstance(second.value, ast.Constant)
            and isinstance(second.value.value, str)
        ):
            docs[first.target.id] = " ".join(second.value.value.split())
    return docs


def _first_sentence(text: str) -> str:
    text = " ".join(text.split())
    end = text.find(". ")
    return text if end < 0 else text[: end + 1]


def _path_form(kind: str) -> str | None:
    """``RUN_DIR`` for ``policy``: the path a path kind takes (None for the others), read
    without importing the kind's module where its class is already loaded."""
    cls = _loaded.get(kind)
    if cls is None:
        try:
            cls = spec_class(kind)
        except (ValueError, TypeError):  # a broken plugin: listed without its form
            return None
    return cls.path_field.upper() if cls.path_field else None


def _field_types(cls: type[ControllerSpec]) -> dict[str, Any]:
    """Field name -> type, in field order."""
    import typing

    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)}


def _differing(values: dict[str, Any], base: dict[str, Any]) -> list[str]:
    return [name for name, value in values.items() if value != base[name]]


def _parse_value(kind: str, name: str, annotation: Any, text: str) -> Any:
    """``text`` as a value of ``annotation`` (bool, int, float, str, a Literal, an optional
    one of those, or a tuple of names written ``A+B``)."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin in (Union, types.UnionType) and type(None) in args:
        if text.lower() == "none":
            return None
        (annotation,) = [a for a in args if a is not type(None)]
        origin, args = get_origin(annotation), get_args(annotation)
    try:
        if origin is Literal:
            if text not in args:
                raise ValueError(f"one of {', '.join(map(str, args))}")
            return text
        if origin is tuple:
            return tuple(filter(None, (part.strip() for part in text.split("+"))))
        if annotation is bool:
            words = {"true": True, "1": True, "yes": True, "false": False, "0": False, "no": False}
            if text.lower() not in words:
                raise ValueError("true or false")
            return words[text.lower()]
        if annotation is int:
            return int(text)
        if annotation is float:
            number = float(text)
            if not math.isfinite(number):
                raise ValueError("a finite number")
            return number
        if annotation is str:
            return text
    except ValueError as exc:
        wanted = str(exc) if origin is Literal or annotation is bool else annotation.__name__
        if annotation in (int, float):
            wanted = "a whole number" if annotation is int else "a finite number"
        raise ValueError(f"{kind} option {name} needs {wanted}, not {text!r}") from None
    raise TypeError(f"{kind} option {name}: no string form for {annotation!r}")


def _format_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "none"
    if isinstance(value, tuple):
        return "+".join(map(str, value))
    return repr(value) if isinstance(value, float) else str(value)
