"""Every file of ``scripts/`` and ``benchmarks/`` imports (a script whose package import broke
fails here, not when someone reproduces a figure), and imports only public package code: no
``sys.path`` edits and no name with a leading underscore from ``microconveyor_env`` or
``agents``. Running them: tests/test_reproduce_commands.py."""
import ast
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FILES = sorted([*(ROOT / "scripts").glob("*.py"), *(ROOT / "benchmarks").glob("*.py")])
PACKAGES = ("microconveyor_env", "agents")


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_script_imports(path):
    pytest.importorskip("stable_baselines3")
    spec = importlib.util.spec_from_file_location(f"_script_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    spec.loader.exec_module(importlib.util.module_from_spec(spec))


def private_uses(source: str) -> list[str]:
    """What ``source`` takes from the package that is not public: a ``sys.path`` edit, a name
    with a leading underscore imported from it, or such an attribute of a module imported from
    it."""
    tree = ast.parse(source)
    out, modules = [], set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(PACKAGES):
            parts = [*(node.module or "").split("."), *(a.name for a in node.names)]
            out += [f"from {node.module} import {a.name}" for a in node.names
                    if any(p.startswith("_") and not p.startswith("__") for p in parts)]
            modules |= {a.asname or a.name for a in node.names}
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(PACKAGES):
                    modules.add(a.asname or a.name.split(".")[0])
                    if any(p.startswith("_") for p in a.name.split(".")):
                        out.append(f"import {a.name}")
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            if node.value.id == "sys" and node.attr == "path":
                out.append("sys.path")
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in modules and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            out.append(f"{node.value.id}.{node.attr}")
    return out


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_scripts_use_public_package_code_only(path):
    assert private_uses(path.read_text()) == []


def test_the_check_catches_what_it_names():
    assert private_uses("import sys\nsys.path.insert(0, 'x')\n") == ["sys.path"]
    assert private_uses("from agents.rl.training import train as T\nT._learn = 1\n") == [
        "T._learn"]
    assert private_uses("from agents.experiments.perturb import wilson as w\n") == []
    assert private_uses("from agents.mpc.control import _robust\n") == [
        "from agents.mpc.control import _robust"]
    assert private_uses("from microconveyor_env.envs.line import _x as y\n") == [
        "from microconveyor_env.envs.line import _x"]
