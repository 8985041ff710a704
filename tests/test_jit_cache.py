"""numba's per-file cache invalidation is extended to all compiled sources (jit_cache)."""
from pathlib import Path

from microconveyor_env.physics import dynamics_kernel as K
from microconveyor_env.physics.jit_cache import refresh, sources_digest


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
    import microconveyor_env.envs.task as task
    import microconveyor_env.physics.forces as forces
    import microconveyor_env.physics.kinematics as kin

    for mod in (K, task, forces, kin):
        src = Path(mod.__file__).read_text()
        assert "refresh_jit_cache(globals())" in src, mod.__name__
