"""Keep numba's on-disk cache of the compiled modules consistent, verified and always usable.

*Cross-module staleness.* ``@njit(cache=True)`` invalidates a function's cached machine code only
when *its own* source file changes, but a compiled caller embeds its callees: after an edit of
``kinematics.py`` (or a package upgrade that changes it) the cached ``dynamics_kernel.run`` would
still run the old kinematics. Each compiled module therefore calls :func:`refresh` at import: a
hash over all compiled-source files is stamped next to the module's cache, and on a mismatch the
module's cache entries are discarded, so it recompiles once.

*Damage.* numba trusts its cache files: a truncated or altered index (``.nbi``) or data file
(``.nbc``) makes every later load fail (``EOFError``, ``UnpicklingError``, ...), for good, and a data
file swapped with another function's could even load the wrong code. :func:`refresh` therefore
wraps each dispatcher's cache in :class:`GuardedCache`: after numba saves an entry, the SHA-256 of
the function's cache files is written beside them (``<function>.nbi.sha256``); before a load the
files are checked against it. A mismatch, or any error while loading, discards that function's
entries, says so in one line on stderr and compiles afresh, once. Entries without a
checksum (written by an older version) are discarded quietly, like stale ones.

*Where caches live.* numba tries, in order: ``$NUMBA_CACHE_DIR``; the package's own
``__pycache__`` folders; numba's user-wide cache (``~/.cache/numba``). If none is writable (a
read-only install with an unwritable ``HOME``) numba would refuse to import the package ("no locator
available"); :class:`FallbackLocator` then uses a private per-user folder in the system temp
directory (:func:`fallback_dir`), and if that cannot be had either, the package runs uncached.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import stat
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from numba.core import caching as _nc

_ROOT = Path(__file__).resolve().parent
MARKER = "refresh_jit_cache(globals())"   # the call every compiled module makes at import
CHECKSUM_SUFFIX = ".sha256"


@functools.cache
def compiled_sources() -> tuple[str, ...]:
    """The package's compiled modules (paths relative to the package), found by the call to
    :func:`refresh` each makes: no list to keep in step with the code, and this infrastructure
    names no module of any layer."""
    return tuple(sorted(str(p.relative_to(_ROOT)) for p in _ROOT.rglob("*.py")
                        if p.name != "jit_cache.py" and MARKER in p.read_text(encoding="utf-8")))


@functools.cache
def sources_digest() -> str:
    """SHA-256 over every compiled module's path and source (once per process)."""
    h = hashlib.sha256()
    for rel in compiled_sources():
        h.update(rel.encode())
        h.update((_ROOT / rel).read_bytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------- read-only installs
def fallback_dir() -> Path | None:
    """A private, writable per-user folder in the temp directory for numba's cache, or None.

    Only a folder owned by this user and closed to others is used (cache files are unpickled, so
    one that others could write to would let them run code here).
    """
    try:
        user = str(os.getuid()) if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
        path = Path(tempfile.gettempdir()) / f"microconveyor-env-numba-{user}"
        path.mkdir(mode=0o700, exist_ok=True)
        st = path.lstat()
        if not stat.S_ISDIR(st.st_mode) or st.st_mode & 0o022:
            return None
        if hasattr(os, "getuid") and st.st_uid != os.getuid():
            return None
        tempfile.TemporaryFile(dir=path).close()
        return path
    except OSError:
        return None


def _in_package(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(_ROOT)
    except (OSError, ValueError):
        return False


class FallbackLocator(_nc._SourceFileBackedLocatorMixin, _nc._CacheLocator):
    """numba cache locator of last resort, for this package's files only (see module docstring)."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        base = fallback_dir()
        self.usable = base is not None
        root = base if base is not None else Path(tempfile.gettempdir()) / "unavailable"
        self._cache_path = str(root / self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self):
        return self._cache_path

    def ensure_cache_path(self):
        if self.usable:
            super().ensure_cache_path()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not os.path.exists(py_file) or not _in_package(py_file):
            return None
        return cls(py_func, py_file)


def _install_fallback_locator() -> None:
    classes = _nc.CacheImpl._locator_classes
    if not any(c.__name__ == FallbackLocator.__name__ and c.__module__ == __name__
               for c in classes):
        classes.append(FallbackLocator)


_install_fallback_locator()  # before the compiled modules' decorators run (they import us first)


def _install_index_guard() -> None:
    """Make numba treat an unreadable cache *index* as an empty one (so it recompiles and writes
    a good index) instead of raising. :class:`GuardedCache` covers the package's own dispatchers;
    this also covers the ones numba makes itself, e.g. for ``@overload(..., jit_options={"cache":
    True})`` implementations, whose truncated index used to end a run with ``UnpicklingError``."""
    cls = getattr(_nc, "IndexDataCacheFile", None)
    if cls is None or not hasattr(cls, "_load_index"):
        return  # a numba without this internal: test_jit_cache says so loudly
    if getattr(cls._load_index, "_microconveyor_guard", False):
        return
    original = cls._load_index

    def _load_index(self: Any) -> dict:
        try:
            return original(self)
        except Exception as exc:  # noqa: BLE001 - any unreadable index is rebuilt
            print(f"microconveyor-env: damaged numba cache index {self._index_path} "
                  f"({type(exc).__name__}); ignored, recompiling", file=sys.stderr)
            return {}

    _load_index._microconveyor_guard = True  # type: ignore[attr-defined]
    setattr(cls, "_load_index", _load_index)  # noqa: B010 - a patch of numba's method


_install_index_guard()


# ----------------------------------------------------------------------------- damage
def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class GuardedCache:
    """A numba ``FunctionCache`` whose entries are checksummed on save and verified on load.

    Any failure to verify or load discards the function's entries (so numba compiles afresh and
    saves a good copy); only a failure to *save* is left alone (the compiled code is still right).
    """

    def __init__(self, inner, label: str):
        self._inner = inner
        self._label = label
        files = getattr(inner, "_cache_file", None)
        self._index: Any = None       # Path of the index file, None: unknown numba layout
        self._data_glob: Any = None
        try:
            self._index = Path(files._index_path)  # type: ignore[union-attr]
            self._data_glob = files._data_name_pattern.replace(  # type: ignore[union-attr]
                "{number:d}", "*")
        except AttributeError:  # another numba layout: keep only the error catching
            self._index = None
            self._data_glob = None

    def __getattr__(self, name):
        return getattr(self._inner, name)

    def __repr__(self):
        return f"<GuardedCache {self._inner!r}>"

    @property
    def cache_path(self):
        return self._inner.cache_path

    # ---- files ----
    def _checksum_path(self) -> Path:
        return self._index.with_name(self._index.name + CHECKSUM_SUFFIX)

    def _files(self) -> list[Path]:
        data = sorted(self._index.parent.glob(self._data_glob)) if self._index.parent.is_dir() else []
        return ([self._index] if self._index.exists() else []) + data

    def discard(self) -> None:
        """Remove this function's index, data files and checksum."""
        if self._index is None:
            try:
                self._inner.flush()
            except OSError:
                pass
            return
        for p in self._files() + [self._checksum_path()]:
            try:
                p.unlink(missing_ok=True)
            except OSError:
                pass

    def _verify(self) -> str | None:
        """None if the files match their checksums (or there is nothing to load), else the
        problem; ``""`` means "no checksum yet" (discard without a warning)."""
        if self._index is None or not self._index.exists():
            return None
        try:
            recorded = json.loads(self._checksum_path().read_text())
            if not isinstance(recorded, dict):
                raise ValueError("not a mapping")
        except FileNotFoundError:
            return ""
        except (OSError, ValueError) as exc:
            return f"unreadable checksum file ({exc})"
        present = {p.name: p for p in self._files()}
        if self._index.name not in recorded:
            return "index not covered by its checksum file"
        for name, digest in recorded.items():
            p = present.get(name)
            try:
                ok = p is not None and _sha256(p) == digest
            except OSError:
                ok = False
            if not ok:
                return f"{name} does not match its checksum"
        return None

    def _record(self) -> None:
        if self._index is None:
            return
        try:
            sums = {p.name: _sha256(p) for p in self._files()}
            _write_atomic(self._checksum_path(), json.dumps(sums, sort_keys=True))
        except OSError:
            pass  # unverifiable entries are discarded at the next load: never trusted

    def _recover(self, problem: str) -> None:
        self.discard()
        if problem:
            print(f"microconveyor-env: damaged numba cache for {self._label} ({problem}) in "
                  f"{self.cache_path}; discarded it, recompiling", file=sys.stderr, flush=True)

    # ---- numba's Cache interface ----
    def load_overload(self, sig, target_context):
        problem = self._verify()
        if problem:  # perhaps another process is between saving and recording: look again
            time.sleep(0.2)
            problem = self._verify()
        if problem is None:
            try:
                return self._inner.load_overload(sig, target_context)
            except Exception as exc:  # noqa: BLE001 - any damage: recompile, never fail
                problem = f"{type(exc).__name__}: {exc}"
        self._recover(problem)
        return None

    def save_overload(self, sig, data):
        try:
            self._inner.save_overload(sig, data)
        except OSError:
            return  # read-only or full disk: run uncached
        except Exception:  # noqa: BLE001 - a damaged index that numba reads back on save
            self.discard()
            try:
                self._inner.save_overload(sig, data)
            except Exception:  # noqa: BLE001
                self.discard()
                return
        self._record()

    def flush(self):
        self.discard()

    def enable(self):
        self._inner.enable()

    def disable(self):
        self._inner.disable()


# ----------------------------------------------------------------------------- per module
def _dispatchers(module_globals: dict) -> list:
    name = module_globals["__name__"]
    out = []
    for obj in module_globals.values():
        cache = getattr(obj, "_cache", None)
        py_func = getattr(obj, "py_func", None)
        if cache is not None and hasattr(cache, "flush") and getattr(py_func, "__module__", "") == name:
            out.append(obj)
    return out


def _guard(disp) -> None:
    cache = disp._cache
    if isinstance(cache, GuardedCache) or isinstance(cache, _nc.NullCache):
        return
    locator = getattr(getattr(cache, "_impl", None), "locator", None)
    if isinstance(locator, FallbackLocator) and not locator.usable:
        disp._cache = _nc.NullCache()  # nowhere writable: run uncached
        return
    disp._cache = GuardedCache(cache, f"{disp.py_func.__module__}.{disp.py_func.__qualname__}")


def refresh(module_globals: dict) -> bool:
    """Guard the module's numba caches and discard them if any compiled source changed; True if
    it discarded."""
    disp = _dispatchers(module_globals)
    for d in disp:
        _guard(d)
    disp = [d for d in disp if isinstance(d._cache, GuardedCache)]
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
        d._cache.discard()
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        _write_atomic(stamp, digest)
    except OSError:
        pass
    return True
