"""Imports point one way along the data flow (ARCHITECTURE.md), and importing is cheap."""

import ast
import subprocess
import sys
from pathlib import Path

import pianist

PACKAGE = Path(pianist.__file__).parent
# Modules at the bottom of the flow that every subpackage may import.
BASE = {"files"}
# Which subpackages each may import.
ALLOWED = {
    "music": set(),
    "sim": set(),
    "env": {"music", "sim"},
    "control": {"music", "sim", "env"},
    "eval": {"music", "sim", "env", "control"},
    "media": {"music", "sim", "env", "eval"},
    "agents": {"music", "sim", "env", "control", "eval"},
    "data": {"music", "sim", "env", "control", "eval", "agents"},
    "sweep": {"music", "sim", "env", "control", "eval", "media", "agents", "data"},
}


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pianist."):
            found.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("pianist."):
                    found.add(alias.name.split(".")[1])
    return found


def test_subpackages_import_only_upstream():
    for sub, allowed in ALLOWED.items():
        for path in (PACKAGE / sub).rglob("*.py"):
            wrong = _imports(path) - allowed - BASE - {sub}
            assert not wrong, f"{path.relative_to(PACKAGE)} imports {sorted(wrong)}"


def test_import_pianist_does_not_load_mujoco():
    code = "import sys, pianist; print('mujoco' in sys.modules, 'gymnasium' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_make_env_from_the_top_level_api():
    env = pianist.make_env("c-major-chords", physics="fast", lookahead=2)
    obs, _ = env.reset(seed=0)
    assert obs["goal"].shape == (3, 89)


def _module_name(path: Path) -> str:
    parts = ("pianist", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported_modules(path: Path, modules: set[str]) -> set[str]:
    """The ``pianist`` modules ``path`` imports, at module level or inside functions.

    ``from pianist.x import y`` is an import of module ``pianist.x.y`` when that is a module,
    else of ``pianist.x``.
    """
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "pianist")
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: resolve against this module's package
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            if base.split(".")[0] != "pianist":
                continue
            for alias in node.names:
                child = f"{base}.{alias.name}"
                found.add(child if child in modules else base)
    return found


def test_no_import_cycles_between_modules():
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        edges = _imported_modules(path, set(paths)) - {name}
        if path.name == "__init__.py":
            # A package's __init__ may gather its own submodules, which import it in turn.
            edges = {m for m in edges if not m.startswith(name + ".")}
        graph[name] = sorted(m for m in edges if m in paths)
    cycles = []
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(module: str, trail: list[str]) -> None:
        state[module] = 1
        for target in graph[module]:
            if state.get(target) == 1:
                cycles.append(" -> ".join([*trail[trail.index(target) :], target]))
            elif target not in state:
                visit(target, [*trail, target])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def _attribute_uses(path: Path, attribute: str) -> list[int]:
    tree = ast.parse(path.read_text())
    return [
        n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == attribute
    ]


def _calls(path: Path, name: str) -> list[int]:
    tree = ast.parse(path.read_text())
    return [
        n.lineno
        for n in ast.walk(tree)
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == name
    ]


def test_controllers_read_the_simulator_through_a_control_handle():
    # Only the environment package unwraps environments (pianist.env.handle.control_handle).
    for path in PACKAGE.rglob("*.py"):
        if path.relative_to(PACKAGE).parts[0] != "env":
            lines = _attribute_uses(path, "unwrapped")
            assert not lines, f"{path.relative_to(PACKAGE)} reads env.unwrapped at lines {lines}"


def test_environments_for_controllers_are_built_in_one_place():
    # A controller's declared environment options are applied by pianist.eval.session only;
    # the agents build their training task's environment from its TaskConfig.
    builders = {Path("eval/session.py"), Path("agents/envs.py"), Path("__init__.py")}
    for path in PACKAGE.rglob("*.py"):
        relative = path.relative_to(PACKAGE)
        if relative.parts[0] != "env" and relative not in builders:
            lines = _calls(path, "PianoEnv")
            assert not lines, f"{relative} builds a PianoEnv itself at lines {lines}"
