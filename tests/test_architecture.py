"""The layers import downward only (docs/architecture.md): each room may import the rooms listed
for it and nothing above. Read from the source with ``ast``, so a new import that climbs fails
here with the file and line, not in review."""
from pathlib import Path

from support.imports import imports

ROOT = Path(__file__).resolve().parents[1]
# room -> rooms it may import (besides itself); "mce" is microconveyor_env
# package infrastructure: any room may use it, it imports no room
INFRA = {"mce.jit_cache", "mce.env_ids", "mce.safe_files"}
ALLOWED = {
    "mce.jit_cache": set(),
    "mce.safe_files": set(),
    "mce.env_ids": set(),
    "mce.physics": set(),
    "mce.presets": {"mce.physics"},
    "mce.plots": {"mce.physics"},
    "mce.envs": {"mce.physics", "mce.presets"},
    "mce.studies": {"mce.physics", "mce.presets", "mce.envs", "mce.plots"},
    "mce.cli": {"mce.physics", "mce.presets", "mce.envs", "mce.plots", "mce.studies"},
    "mce": {"mce.physics", "mce.presets", "mce.envs", "mce.plots", "mce.studies", "mce.cli"},
    "agents.planning": {"mce.physics", "mce.presets", "mce.envs"},
    "agents.openloop": {"agents.planning", "mce.physics", "mce.presets", "mce.envs"},
    "agents.rl": {"mce.physics", "mce.presets", "mce.envs"},
    "agents.mpc": {"agents.planning", "agents.openloop", "agents.rl", "mce.physics", "mce.presets", "mce.envs"},
    "agents.imitation": {"agents.planning", "agents.rl", "agents.mpc", "mce.physics", "mce.presets", "mce.envs"},
    "agents.plots": {"mce.physics", "mce.envs"},
    "agents.experiments": {"agents.planning", "agents.openloop", "agents.rl", "agents.mpc", "agents.plots",
                           "mce.physics", "mce.presets", "mce.envs"},
    "agents.cli": {"agents.planning", "agents.openloop", "agents.rl", "agents.mpc", "agents.imitation", "agents.plots",
                   "agents.experiments",
                   "mce.cli", "mce.physics", "mce.presets", "mce.envs"},
    "agents": set(),
}


def _room(module: str) -> str | None:
    parts = module.split(".")
    top = {"microconveyor_env": "mce", "agents": "agents"}.get(parts[0])
    if top is None:
        return None
    sub = parts[1] if len(parts) > 1 else ""
    name = f"{top}.{sub}" if sub else top
    return name if name in ALLOWED else top




def violations(root: Path) -> list[str]:
    """Every import under ``root`` that goes to a room its room may not import."""
    bad = []
    files = sorted(root.glob("microconveyor_env/**/*.py")) + sorted(root.glob("agents/**/*.py"))
    for path in files:
        for module, target, line in imports(path, root):
            src, dst = _room(module), _room(target)
            if src is None or dst is None or src == dst:
                continue
            if dst not in ALLOWED[src] and dst not in INFRA:
                bad.append(f"{path.relative_to(root)}:{line}: {src} imports {target} ({dst})")
    return bad


def test_layers_import_downward_only():
    assert len(list(ROOT.glob("microconveyor_env/**/*.py"))) > 40
    bad = violations(ROOT)
    assert not bad, "imports that climb a layer:\n" + "\n".join(bad)


def test_the_checker_reports_climbing_imports(tmp_path):
    """Not vacuous: relative and absolute imports that climb are both reported."""
    phys = tmp_path / "microconveyor_env" / "physics"
    phys.mkdir(parents=True)
    (phys / "__init__.py").write_text("")
    (phys / "bad.py").write_text("from ..envs import step\nimport agents.rl.training.train\n"
                                 "from . import forces\nimport numpy\n")
    bad = violations(tmp_path)
    assert len(bad) == 2 and "mce.envs" in bad[0] and "agents" in bad[1]


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the modules it imports (module-level or inside a function), for the package
    modules and, between themselves, the scripts (which import each other by file name)."""
    files = (sorted(root.glob("microconveyor_env/**/*.py")) + sorted(root.glob("agents/**/*.py")))
    modules = {}
    for path in files:
        rel = path.relative_to(root).with_suffix("")
        modules[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = path
    scripts = {p.stem: p for p in sorted(root.glob("scripts/*.py"))}
    graph: dict[str, set[str]] = {m: set() for m in [*modules, *scripts]}
    for module, path in [*modules.items(), *scripts.items()]:
        for _, target, _ in imports(path, root):
            if module in scripts:
                if target in scripts and target != module:
                    graph[module].add(target)
                continue
            parts = target.split(".")
            while parts and ".".join(parts) not in modules:
                parts.pop()
            found = ".".join(parts)
            # a module importing its own package (or a package its own module) is no circle
            if found and found != module and not module.startswith(found + ".") \
                    and not found.startswith(module + "."):
                graph[module].add(found)
    return graph


def import_circles(root: Path) -> list[list[str]]:
    """Every circle of imports (:func:`import_graph`): its strongly connected components of
    more than one module, each sorted (Tarjan's algorithm)."""
    graph = import_graph(root)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while (w := stack.pop()) != v:
                comp.append(w)
            if comp:
                circles.append(sorted([*comp, v]))

    for v in graph:
        if v not in index:
            visit(v)
    return circles


def test_no_import_circles():
    circles = import_circles(ROOT)
    assert not circles, "modules that import each other (directly or through others):\n" + \
        "\n".join(" <-> ".join(c) for c in circles)


def test_the_circle_checker_finds_circles(tmp_path):
    """Not vacuous: a circle through a function-level import, and one between scripts."""
    pkg = tmp_path / "microconveyor_env" / "envs"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from . import b\n")
    (pkg / "b.py").write_text("def f():\n    from .c import x\n")
    (pkg / "c.py").write_text("from microconveyor_env.envs.a import y\n")
    (pkg / "d.py").write_text("from . import a\n")                   # reaches it, not in it
    (tmp_path / "scripts").mkdir()
    (tmp_path / "scripts" / "one.py").write_text("from two import g\n")
    (tmp_path / "scripts" / "two.py").write_text("def g():\n    import one\n")
    found = import_circles(tmp_path)
    assert sorted(found) == [["microconveyor_env.envs.a", "microconveyor_env.envs.b",
                              "microconveyor_env.envs.c"], ["one", "two"]]
