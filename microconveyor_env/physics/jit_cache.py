"""Keep numba's on-disk cache consistent across the compiled modules.

``@njit(cache=True)`` invalidates a function's cached machine code only when *its own* source file
changes, but a compiled caller embeds its callees: after an edit of ``kinematics.py`` (or a package
upgrade that changes it) the cached ``dynamics_kernel.run`` would still run the old kinematics.
Each compiled module therefore calls :func:`refresh` at import: a hash over all compiled-source
files is stamped next to the module's cache, and on a mismatch the module's cache index is
flushed, so it recompiles once.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
COMPILED_SOURCES = ("physics/kinematics.py", "physics/forces.py", "physics/dynamics_kernel.py",
                    "envs/task.py")


def sources_digest() -> str:
    h = hashlib.sha256()
    for rel in COMPILED_SOURCES:
        h.update(rel.encode())
        h.update((_ROOT / rel).read_bytes())
    return h.hexdigest()


def _dispatchers(module_globals: dict) -> list:
    name = module_globals["__name__"]
    out = []
    for obj in module_globals.values():
        cache = getattr(obj, "_cache", None)
        py_func = getattr(obj, "py_func", None)
        if cache is not None and hasattr(cache, "flush") and getattr(py_func, "__module__", "") == name:
            out.append(obj)
    return out


def refresh(module_globals: dict) -> bool:
    """Flush the module's numba cache if any compiled source changed; True if it flushed."""
    disp = _dispatchers(module_globals)
    if not disp:
        return False  # JIT disabled, or nothing cached
    try:
        stamp = Path(disp[0]._cache.cache_path) / f"{module_globals['__name__']}.sources.sha256"
    except AttributeError:
        return False
    digest = sources_digest()
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    for d in disp:
        try:
            d._cache.flush()
        except OSError:
            pass
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=stamp.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(digest)
        os.replace(tmp, stamp)
    except OSError:
        pass
    return True
