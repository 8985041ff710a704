"""numba's per-file cache invalidation is extended to all compiled sources (jit_cache)."""
from pathlib import Path

from microconveyor_env.physics import dynamics_kernel as K
from microconveyor_env.physics.jit_cache import refresh, sources_digest


def test_stale_stamp_flushes_and_is_rewritten():
    assert refresh(vars(K)) is False  # imported already: stamp current
    stamp = Path(K.run._cache.cache_path) / f"{K.__name__}.sources.sha256"
    stamp.write_text("stale")
    assert refresh(vars(K)) is True
    assert stamp.read_text() == sources_digest()
    assert refresh(vars(K)) is False
    # the flushed kernel still runs (recompiles or reloads) and gives the same answer
    from microconveyor_env.physics.schedule import Schedule
    from microconveyor_env.physics.simulator import Simulator

    r = Simulator("seed").simulate(Schedule.single(950.0, 200e-6), x0=0.125e-3)
    assert r.outcome == "rest" and abs(r.displacement_m + 1.1642e-3) < 2e-6


def test_digest_covers_every_compiled_module():
    import microconveyor_env.envs.task as task
    import microconveyor_env.physics.forces as forces
    import microconveyor_env.physics.kinematics as kin

    for mod in (K, task, forces, kin):
        src = Path(mod.__file__).read_text()
        assert "refresh_jit_cache(globals())" in src, mod.__name__
