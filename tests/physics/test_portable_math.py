"""Portable arithmetic (issue 17): the contact table, and the env built on it, give the same bits
whatever the BLAS kernel or the CPU features numpy dispatches to."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.special import roots_jacobi

from microconveyor_env.physics import portable_math as pm
from microconveyor_env.physics.gauss_rules import gauss_jacobi, gauss_legendre

CHILD = Path(__file__).resolve().parents[1] / "support" / "fingerprint_child.py"
# sha256 of the dissertation preset's base table (TABLE_FORMAT 4). Recorded on an AVX2 machine
# (Xeon, numpy X86_V3) and identical under every setting below; a deliberate change of the
# quadrature or the fits changes it (update it together with TABLE_FORMAT).
TABLE_SHA256 = "bfad27e4a43b6497729ac5683bb6f1c7d74706c9299d444c97bbcd2bb4c41fe2"


def _ulps(a, b):
    return np.max(np.abs(a - b) / np.spacing(np.abs(b)))


def test_exp_log_power_are_accurate_to_a_few_ulp():
    rng = np.random.default_rng(0)
    x = rng.uniform(-745.0, 709.0, 100_000)
    assert _ulps(pm.exp(x), np.exp(x)) <= 1
    y = np.exp(rng.uniform(-700.0, 700.0, 100_000))
    assert _ulps(pm.log(y), np.log(y)) <= 2
    w = rng.uniform(0.0, 200.0, 100_000)
    for e in (1.5, 1.425, 1.263, 0.982, 0.298, -0.29, 4.425):
        # exp(y log x): |y ln x| ULP of amplification on top of log's 2 (<= 60 here)
        assert _ulps(pm.power(w, e), w ** e) <= 60, e


def test_special_values():
    np.testing.assert_array_equal(pm.exp([np.nan, np.inf, -np.inf, 800.0, -800.0, 0.0]),
                                  [np.nan, np.inf, 0.0, np.inf, 0.0, 1.0])
    np.testing.assert_array_equal(pm.log([0.0, -1.0, np.inf, np.nan, 1.0]),
                                  [-np.inf, np.nan, np.inf, np.nan, 0.0])
    np.testing.assert_allclose(pm.power([0.0, 1.0, 4.0], 1.5), [0.0, 1.0, 8.0], rtol=4.5e-16)
    assert pm.spow(2.0, 0.0) == 1.0 and pm.spow(0.0, -1.0) == np.inf


def test_ordered_dot_matches_a_correctly_rounded_sum():
    import math

    rng = np.random.default_rng(1)
    for n in (1, 2, 3, 7, 64, 1001):
        m, w = rng.normal(size=(5, n)), rng.normal(size=n)
        got = pm.ordered_dot(m, w)
        exact = [math.fsum(m[i] * w) for i in range(5)]
        scale = np.abs(m * w).sum(axis=1)
        assert np.all(np.abs(got - exact) <= 4 * np.log2(n + 1) * 2.2e-16 * scale + 1e-300), n
    assert pm.ordered_dot(np.zeros((3, 0)), np.zeros(0)).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("n, beta", [(20, 0.0), (40, 1.5), (40, 0.982)])
def test_gauss_rules_agree_with_scipy_and_integrate_exactly(n, beta):
    import math

    x, w = gauss_jacobi(n, beta)
    xs, ws = roots_jacobi(n, 0.0, beta)
    np.testing.assert_allclose(x, xs, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w, ws, rtol=1e-12)
    # int_-1^1 (1 + x)^beta dx and the x^2 moment, exactly (t = 1 + x)
    m0 = 2 ** (beta + 1) / (beta + 1)
    m2 = 2 ** (beta + 3) / (beta + 3) - 2 * 2 ** (beta + 2) / (beta + 2) + m0
    assert math.fsum(w) == pytest.approx(m0, rel=4e-16)
    assert math.fsum(w * x * x) == pytest.approx(m2, rel=1e-15)
    assert gauss_legendre(20)[0] is gauss_jacobi(20, 0.0)[0]  # cached, read-only
    with pytest.raises(ValueError):
        x[0] = 0.0


def _settings():
    """Child-process environments: BLAS core types this CPU can run (an older core type only
    uses a subset of its instructions) and numpy's dispatch with AVX2/FMA turned off."""
    flags = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    cores = ["Prescott", "Nehalem", "SandyBridge"] + (["Haswell"] if " avx2" in flags else [])
    out = [("default", {})]
    out += [(f"OPENBLAS_CORETYPE={c}", {"OPENBLAS_CORETYPE": c}) for c in cores]
    out += [("NPY_DISABLE_CPU_FEATURES=X86_V3", {"NPY_DISABLE_CPU_FEATURES": "X86_V3"}),
            ("Prescott + X86_V3 off", {"OPENBLAS_CORETYPE": "Prescott",
                                       "NPY_DISABLE_CPU_FEATURES": "X86_V3"})]
    return out


def _bits_agree(tmp_path, settings):
    results = {}
    for name, extra in settings:
        env = {**os.environ, **extra, "MICROCONVEYOR_CACHE_DIR": str(tmp_path / "cache")}
        r = subprocess.run([sys.executable, str(CHILD)], capture_output=True, text=True,
                           env=env, timeout=300)
        assert r.returncode == 0, (name, r.stderr[-2000:])
        results[name] = json.loads(r.stdout.strip().splitlines()[-1])
    assert {v["table"] for v in results.values()} == {TABLE_SHA256}, results
    assert len({v["rollout"] for v in results.values()}) == 1, results


X86_64 = pytest.mark.skipif(sys.platform != "linux" or os.uname().machine != "x86_64",
                            reason="the BLAS core types and numpy feature names are x86-64's")


@X86_64
def test_table_and_rollout_bits_do_not_depend_on_blas_or_cpu_features(tmp_path):
    """The defaults against the farthest setting from them (the oldest BLAS core type with
    numpy's AVX2/FMA dispatch off); every setting: the slow test below."""
    _bits_agree(tmp_path, [s for s in _settings() if s[0] in ("default", "Prescott + X86_V3 off")])


@pytest.mark.slow
@X86_64
def test_table_and_rollout_bits_agree_under_every_blas_core_type_and_cpu_feature_setting(tmp_path):
    _bits_agree(tmp_path, _settings())
