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
