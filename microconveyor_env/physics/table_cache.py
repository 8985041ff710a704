"""The contact tables' caches: in memory (:data:`_MEMO`) and on disk (``ke-table-<key>.npz`` in
:func:`cache_dir`), keyed by everything the base table depends on (:func:`table_key`).

:func:`base_table` looks in memory, then on disk, then builds
(:func:`.table_build.build_base_table`). A file on disk is trusted only if its key matches and its
content is one the builder could have made (:func:`consistent`); anything else (corrupt,
truncated, tampered) is rebuilt and rewritten. Files are written atomically; an unwritable cache
folder is not an error.

Tests that replace the memory cache or the builder patch them here (``table_cache._MEMO``,
``table_cache.build_base_table``): :mod:`.contact_table` only re-exports the names.
"""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from . import asperity, rough_surface
from .materials import ContactParams, ParameterError, check_range
from .table_build import DEFAULT_LOAD_RATIO, DEFAULT_SPACING, BaseTable, build_base_table

TABLE_FORMAT = 4                # bump when the stored layout or the quadrature changes (4: portable math)


def cache_dir() -> Path:
    """User cache directory (``$MICROCONVEYOR_CACHE_DIR`` overrides)."""
    env = os.environ.get("MICROCONVEYOR_CACHE_DIR")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_cache_dir("microconveyor-env"))


@functools.lru_cache(maxsize=1)
def _code_hash() -> str:
    """Hash of the source of every module the table's numbers come from: an edit to any of them
    (a fit, the quadrature, the portable arithmetic, the derived contact quantities, the builder,
    this cache) invalidates cached tables by itself, without relying on someone bumping
    TABLE_FORMAT."""
    here = Path(__file__).parent
    h = hashlib.sha256()
    # by file, not by import: contact_table imports this module (no import circle)
    for name in ("asperity", "rough_surface", "gauss_rules", "portable_math", "materials",
                 "table_build", "contact_table"):
        h.update((here / f"{name}.py").read_bytes())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()[:16]


def table_key(params: ContactParams, spacing: float, load_ratio: float) -> str:
    """Hash of everything the base table depends on (not beta, not friction_scale); ``spacing``
    [-] in d / sigma, ``load_ratio`` [-]."""
    inputs = params.as_dict()
    inputs["surface"].pop("beta")
    inputs.pop("friction_scale")
    inputs["part"].pop("mass")
    inputs["part"].pop("area")
    quadrature = {k: getattr(rough_surface, k)
                  for k in ("H_MAX", "GL_ORDER", "JACOBI_ORDER", "GAP_DS", "TAIL")}
    blob = json.dumps({"inputs": inputs, "spacing": spacing, "load_ratio": load_ratio,
                       "format": TABLE_FORMAT, "fits": repr(asperity.KE_FITS),
                       "quadrature": quadrature, "code": _code_hash()},
                      sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()[:32]


def _load_cached(path: Path, key: str) -> BaseTable | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                return None
            fields = {k: z[k] for k in BaseTable.__dataclass_fields__}
        for k in ("n_min", "d_pull", "d_balance", "build_seconds"):
            fields[k] = float(fields[k])
        t = BaseTable(**fields)
        return t if consistent(t) else None
    except Exception:  # corrupt, truncated, wrong layout: rebuild, never trust
        return None


def consistent(t: BaseTable) -> bool:
    """Whether a (cached) table is one :func:`build_base_table` could have made: finite 1-d arrays
    of one size, the stable branch from pull-off (u = 0, d = d_A, n = n_min < 0) with n rising,
    d falling, u = sqrt(n - n_min), friction q >= 0, and the balance point inside the branch."""
    arrays = (t.u, t.d, t.d_u, t.q, t.q_u, t.n)
    scalars = (t.n_min, t.d_pull, t.d_balance, t.build_seconds)
    if (any(a.ndim != 1 for a in arrays) or len({a.size for a in arrays}) != 1 or t.u.size < 16
            or not all(np.all(np.isfinite(a)) for a in arrays)
            or not all(math.isfinite(x) for x in scalars)):
        return False
    with np.errstate(all="ignore"):
        return bool(
            t.n_min < 0 and t.u[0] == 0 and t.n[0] == t.n_min and t.d[0] == t.d_pull
            and np.all(np.diff(t.u) > 0) and np.all(np.diff(t.n) > 0) and np.all(np.diff(t.d) < 0)
            and np.all(t.d_u < 0) and np.all(t.q >= 0)
            and t.d[-1] <= t.d_balance <= t.d_pull
            and np.allclose(t.u, np.sqrt(np.maximum(t.n - t.n_min, 0.0)), rtol=1e-9,
                            atol=1e-12 * math.sqrt(abs(t.n_min))))


def _store(path: Path, key: str, table: BaseTable) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, key=np.array(key), **table.arrays())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def base_table(params: ContactParams, spacing: float = DEFAULT_SPACING,
               load_ratio: float = DEFAULT_LOAD_RATIO, use_cache: bool = True) -> BaseTable:
    """Cached :func:`build_base_table` (memory, then disk, then build); ``spacing`` [-] in
    d / sigma, ``load_ratio`` [-] in pull-off forces."""
    spacing = check_range("ContactTable", "spacing", spacing, 1e-4, 0.5)  # <= ~1e5 nodes
    load_ratio = check_range("ContactTable", "load_ratio", load_ratio, 10.0, 1e8)
    key = table_key(params, spacing, load_ratio)
    if key in _MEMO:
        return _MEMO[key]
    path = cache_dir() / f"ke-table-{key}.npz"
    table = _load_cached(path, key) if use_cache else None
    if table is None:
        try:
            table = build_base_table(params, spacing, load_ratio)
        except (RuntimeError, ArithmeticError, ValueError, MemoryError) as exc:
            raise ParameterError(
                f"no contact table for these contact parameters ({exc}); each is within its own "
                f"range but together they are outside what the model supports: "
                f"{_describe(params)}") from None
        if use_cache:
            try:
                _store(path, key, table)
            except OSError:
                pass  # a read-only cache is not an error: the table is still correct
    _MEMO[key] = table
    return table


_MEMO: dict[str, BaseTable] = {}


def _describe(params: ContactParams) -> str:
    d = params.as_dict()
    return ", ".join(f"{group}.{k} = {v:g}" for group in ("materials", "surface")
                     for k, v in d[group].items())
