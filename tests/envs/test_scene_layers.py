"""The scenes stand on one core (docs/architecture.md, the envs row): ``envs/core`` imports no
scene, ``envs/rail`` (what the line and the positioner share) imports the core alone, and a scene
imports the core, the rail it stands on and itself, never another scene. Read from the source
with ``ast``, every import (module-level or inside a function)."""
from pathlib import Path

from support.imports import imports

ENVS = Path(__file__).resolve().parents[2] / "microconveyor_env" / "envs"
# subpackage -> the subpackages of envs it may import (besides itself)
MAY_IMPORT = {"core": set(), "rail": {"core"}, "line": {"core", "rail"},
              "positioner": {"core", "rail"}, "plane": {"core"}}


def _targets(path: Path, envs: Path = ENVS):
    """(line, envs subpackage) of every import of ``path`` (under ``envs``) that reaches into
    ``envs``."""
    for _, name, line in imports(path, envs.parents[1]):
        parts = name.split(".")
        if parts[:2] == ["microconveyor_env", "envs"] and len(parts) > 2:
            yield line, parts[2]


def crossings(envs: Path = ENVS) -> list[str]:
    """Every import from one envs subpackage into one it may not import."""
    bad = []
    for sub, allowed in MAY_IMPORT.items():
        for path in sorted((envs / sub).rglob("*.py")):
            for line, target in _targets(path, envs):
                if target != sub and target not in allowed:
                    bad.append(f"{path.relative_to(envs)}:{line} imports envs.{target}")
    return bad


def test_the_core_imports_no_scene_and_no_scene_imports_another():
    assert (ENVS / "core").is_dir() and (ENVS / "rail").is_dir()
    bad = crossings()
    assert not bad, "imports across scenes:\n" + "\n".join(bad)


def test_the_checker_reports_a_crossing():
    """Not vacuous: the checker sees relative imports, absolute ones and imports in functions."""
    found = list(_targets(ENVS / "line" / "env.py"))
    assert ("core" in {t for _, t in found}) and ("rail" in {t for _, t in found})
    assert any(t == "rail" for _, t in _targets(ENVS / "positioner" / "env.py"))
