"""numba's per-file cache invalidation is extended to all compiled sources (jit_cache)."""
from pathlib import Path

from microconveyor_env.physics import dynamics_kernel as kernel
from microconveyor_env.jit_cache import refresh, sources_digest


def test_stale_stamp_flushes_and_is_rewritten(tmp_path, monkeypatch):
    """On a throw-away cached module (the package's own caches are left alone)."""
    (tmp_path / "tmp_jit_mod.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import tmp_jit_mod

    assert tmp_jit_mod.twice(3) == 6  # compiled and cached
    g = vars(tmp_jit_mod)
    assert refresh(g) is True          # no stamp yet: flushed once
    stamp = Path(tmp_jit_mod.twice._cache.cache_path) / "tmp_jit_mod.sources.sha256"
    assert stamp.read_text() == sources_digest()
    assert refresh(g) is False         # up to date
    stamp.write_text("stale")          # a compiled source changed
    assert refresh(g) is True and stamp.read_text() == sources_digest()
    assert tmp_jit_mod.twice(4) == 8


def test_digest_covers_every_compiled_module():
    import microconveyor_env.envs.line.task as task
    import microconveyor_env.physics.forces as forces
    import microconveyor_env.physics.kinematics as kin

    for mod in (kernel, task, forces, kin):
        src = Path(mod.__file__).read_text()
        assert "refresh_jit_cache(globals())" in src, mod.__name__


def test_every_compiled_module_is_in_the_digest():
    """Every module that compiles (``@njit``) calls refresh_jit_cache, so it is found and hashed
    (else an edit of it would leave stale machine code in its callers' caches)."""
    from microconveyor_env.jit_cache import compiled_sources

    root = Path(kernel.__file__).resolve().parents[1]
    compiling = {str(p.relative_to(root)) for p in root.rglob("*.py")
                 if "@njit" in p.read_text() and p.name != "jit_cache.py"}
    assert compiling and compiling <= set(compiled_sources())
    assert "physics/dynamics_kernel.py" in compiled_sources()
    assert "envs/line/step.py" in compiled_sources()


def test_numba_private_caching_api_is_what_jit_cache_expects():
    """jit_cache leans on numba's private caching internals (written against numba 0.68): if a
    numba release changes them, this fails loudly here instead of silently disabling the cache
    guard in a user's import."""
    import numba
    from numba.core import caching as nc

    from microconveyor_env.jit_cache import FallbackLocator, GuardedCache

    assert hasattr(nc, "_SourceFileBackedLocatorMixin") and hasattr(nc, "_CacheLocator")
    assert getattr(nc.IndexDataCacheFile._load_index, "_microconveyor_guard", False)
    assert isinstance(nc.CacheImpl._locator_classes, list)
    assert FallbackLocator in nc.CacheImpl._locator_classes, numba.__version__
    for name in ("load_overload", "save_overload", "flush", "enable", "cache_path"):
        assert hasattr(nc.FunctionCache, name), (name, numba.__version__)
    cache = kernel.run._cache
    assert isinstance(cache, GuardedCache), (type(cache), numba.__version__)
    inner = cache._inner
    files = inner._cache_file
    assert Path(files._index_path).name.endswith(".nbi")
    assert "{number:d}" in files._data_name_pattern
    assert getattr(inner._impl, "locator", None) is not None
