"""Elementary functions and sums that give the same bits on every machine.

The contact table (:mod:`.contact_table`) is stored data: the env's trajectories, the stored
rollouts and every policy evaluation depend on its last bit. Two things would make it depend on
the machine:

* **sums by BLAS** (``phi @ wt`` is a dgemv whose blocking and SIMD width differ per CPU kernel:
  10-155 ULP between OpenBLAS core types);
* **transcendental ufuncs**: numpy's ``exp``/``log``/``power`` dispatch to SIMD implementations
  (AVX-512 machines take vectorised versions, others libm), and libm itself picks FMA or non-FMA
  variants at load time. They are accurate to about an ULP, but not the *same* ULP everywhere.

This module uses only IEEE-754 operations that are correctly rounded by definition (``+ - * /``,
``floor``, ``frexp``, ``ldexp``), each applied element-wise by numpy, so every CPU path gives the
same result; and sums in a fixed order (one column after the other), never through BLAS.
Accuracy: ``exp`` within 1 ULP and ``log`` within 2 ULP of the correctly rounded result on the
tests' random samples; ``power(x, y) = exp(y log x)`` loses about ``|y ln x|`` ULP more (1e-15
relative for the KE fits' exponents and ranges), far below the quadrature error (1e-10).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

# Cody-Waite split of ln 2 (fdlibm): LN2_HI has 21 trailing zero bits, so k * LN2_HI is exact
# for |k| < 2**21 and the reduced argument carries no rounding from it.
LN2_HI = 6.93147180369123816490e-01
LN2_LO = 1.90821492927058770002e-10
INV_LN2 = 1.44269504088896338700e+00
SQRT_HALF = 0.70710678118654757
# 1/k! for k = 13..0: Taylor series of exp on |r| <= ln2/2 (truncation 4e-18 relative)
_EXP_COEF = tuple(1.0 / float(np.prod(np.arange(1, k + 1, dtype=float))) for k in range(13, -1, -1))
# 1/(2k+1) for k = 12..1: 2 atanh(s) = 2s (1 + s^2/3 + s^4/5 + ...), |s| <= 0.1716 (s^26 < 1e-19)
_ATANH_COEF = tuple(1.0 / (2 * k + 1) for k in range(12, 0, -1))
_EXP_MAX, _EXP_MIN = 709.782712893384, -745.1332191019412


def exp(x: npt.ArrayLike) -> np.ndarray:
    """``e**x`` [-] for any float array ``x`` [-] (inf above 709.78, 0 below -745.13, NaN kept)."""
    x = np.asarray(x, dtype=float)
    xc = np.clip(np.where(np.isnan(x), 0.0, x), _EXP_MIN - 1.0, _EXP_MAX + 1.0)
    k = np.floor(xc * INV_LN2 + 0.5)
    r = (xc - k * LN2_HI) - k * LN2_LO
    p = np.full_like(r, _EXP_COEF[0])
    for c in _EXP_COEF[1:]:
        p = p * r + c
    with np.errstate(over="ignore", under="ignore"):
        out = np.ldexp(p, k.astype(np.int64))
    out = np.where(x > _EXP_MAX, np.inf, np.where(x < _EXP_MIN, 0.0, out))
    return np.where(np.isnan(x), np.nan, out)


def log(x: npt.ArrayLike) -> np.ndarray:
    """Natural logarithm [-] of a positive float array ``x`` [-] (-inf at 0, NaN below)."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x) & (x > 0)
    m, e = np.frexp(np.where(ok, x, 1.0))       # x = m 2^e, m in [0.5, 1)
    low = m < SQRT_HALF
    m = np.where(low, m * 2.0, m)               # m in [sqrt(1/2), sqrt(2)); m - 1 is exact
    e = np.where(low, e - 1, e).astype(float)
    f = m - 1.0
    s = f / (2.0 + f)
    z = s * s
    r = np.full_like(z, _ATANH_COEF[0])
    for c in _ATANH_COEF[1:]:
        r = r * z + c
    log_m = 2.0 * s + 2.0 * s * (z * r)
    out = e * LN2_HI + (e * LN2_LO + log_m)
    out = np.where(x == 0, -np.inf, np.where(x == np.inf, np.inf, out))
    return np.where(ok | (x == 0) | (x == np.inf), out, np.nan)


def power(x: npt.ArrayLike, y: float) -> np.ndarray:
    """``x**y`` [-] for ``x >= 0`` [-] and a real exponent ``y`` [-] (``0**y`` = 0 for y > 0)."""
    x = np.asarray(x, dtype=float)
    if y == 0.0:
        return np.ones_like(x)
    pos = x > 0
    out = exp(y * log(np.where(pos, x, 1.0)))
    return np.where(pos, out, np.where(x == 0, 0.0 if y > 0 else np.inf, np.nan))


def spow(x: float, y: float) -> float:
    """:func:`power` for one Python float: ``x**y`` [-]."""
    return float(power(x, y))


def ordered_dot(m: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``m @ w`` [-] for a 2-d ``m`` (rows x nodes) and 1-d ``w`` (nodes), summed in an order this
    function fixes: the same bits on every CPU (BLAS reorders the sum per kernel).

    The order is a pairwise tree over the nodes: terms ``2i`` and ``2i + 1`` are added, then the
    pairs of those sums, and so on (an odd count carries its last term up a level unchanged).
    Every level is one element-wise ``+``, exact per element; the tree's rounding error grows
    like ``log2(nodes)`` instead of ``nodes``.
    """
    t = m * w[None, :]                    # element-wise products: correctly rounded each
    while t.shape[1] > 1:
        n = t.shape[1]
        pairs = t[:, 0:n - 1:2] + t[:, 1:n:2]
        t = np.concatenate([pairs, t[:, n - 1:]], axis=1) if n % 2 else pairs
    return t[:, 0] if t.shape[1] else np.zeros(m.shape[0])
