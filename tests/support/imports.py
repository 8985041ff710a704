"""Every import of a source file, read with ``ast`` (module-level or inside a function, absolute
or relative): what the layer checks read."""
from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path


def imports(path: Path, root: Path) -> Iterator[tuple[str, str, int]]:
    """(the module of ``path`` under ``root``, each module it imports, the line) for every import
    in ``path``; ``from . import x`` names the module ``package.x``."""
    rel = path.relative_to(root).with_suffix("")
    module = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
                names = [target] if node.module else [f"{target}.{a.name}" for a in node.names]
            else:
                names = [node.module or ""]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            yield module, name, node.lineno
