"""Gauss–Legendre and Gauss–Jacobi rules computed in decimal arithmetic: the same bits everywhere.

scipy's ``roots_legendre``/``roots_jacobi`` start from LAPACK eigenvalues, whose last bits depend on
the BLAS kernel. Here scipy only supplies the starting points; Newton's method on the three-term
recurrences then runs in 50-digit decimal arithmetic (Python's :mod:`decimal`, software arithmetic,
identical on every CPU) until the step is below 1e-40, and the nodes and weights are rounded to
float64 once. The contact table (:mod:`.rough_surface`) uses these rules.
"""
from __future__ import annotations

import functools
from decimal import Context, Decimal

import numpy as np
from scipy.special import roots_jacobi

_CTX = Context(prec=50)
_TOL = Decimal("1e-40")


def _jacobi_and_derivative(n: int, beta: Decimal, x: Decimal) -> tuple[Decimal, Decimal]:
    """P_n^(0, beta)(x) and its derivative (standard normalisation), by the three-term
    recurrence (DLMF 18.9.1 with alpha = 0) and DLMF 18.9.16 for the derivative."""
    c = _CTX
    a = Decimal(0)
    p_prev, p = Decimal(1), c.add(c.divide(c.subtract(a, beta), 2),
                                  c.multiply(c.divide(c.add(a + beta, 2), 2), x))
    if n == 0:
        return Decimal(1), Decimal(0)
    for k in range(2, n + 1):
        s = c.add(2 * k, beta)                     # 2k + alpha + beta
        a1 = c.multiply(c.multiply(2 * k, c.add(k, beta)), c.subtract(s, 2))
        a2 = c.multiply(c.subtract(s, 1), c.subtract(Decimal(0), c.multiply(beta, beta)))
        a3 = c.multiply(c.multiply(c.subtract(s, 1), s), c.subtract(s, 2))
        a4 = c.multiply(c.multiply(c.multiply(2, k - 1), c.add(k - 1, beta)), s)
        p_prev, p = p, c.divide(c.subtract(c.multiply(c.add(a2, c.multiply(a3, x)), p),
                                           c.multiply(a4, p_prev)), a1)
    s = c.add(2 * n, beta)
    # (2n + b)(1 - x^2) P_n' = n [(-b) - (2n + b) x] P_n + 2 (n)(n + b) P_{n-1}   (alpha = 0)
    num = c.add(c.multiply(c.multiply(n, c.subtract(c.minus(beta), c.multiply(s, x))), p),
                c.multiply(c.multiply(2 * n, c.add(n, beta)), p_prev))
    dp = c.divide(num, c.multiply(s, c.subtract(1, c.multiply(x, x))))
    return p, dp


@functools.cache
def gauss_jacobi(n: int, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes [-] and weights [-] of the n-point rule for ``int_-1^1 (1 + x)^beta f(x) dx``
    (``beta = 0``: Gauss–Legendre), ascending, identical bits on every machine."""
    if n < 1 or not beta > -1:
        raise ValueError(f"need n >= 1 and beta > -1, got n={n}, beta={beta}")
    c = _CTX
    b = Decimal(beta)
    guesses, _ = roots_jacobi(n, 0.0, beta)
    nodes, weights = [], []
    two_b1 = c.power(Decimal(2), c.add(b, 1)) if beta != 0 else Decimal(2)
    for g in sorted(guesses):
        x = Decimal(float(g))
        for _ in range(60):
            p, dp = _jacobi_and_derivative(n, b, x)
            step = c.divide(p, dp)
            x = c.subtract(x, step)
            if abs(step) < _TOL:
                break
        else:  # pragma: no cover - Newton from scipy's float roots converges in 3-4 steps
            raise RuntimeError(f"Gauss-Jacobi node did not converge (n={n}, beta={beta})")
        _, dp = _jacobi_and_derivative(n, b, x)
        w = c.divide(two_b1, c.multiply(c.subtract(1, c.multiply(x, x)), c.multiply(dp, dp)))
        nodes.append(x)
        weights.append(w)
    xs = np.array([float(v) for v in nodes])
    if np.any(np.diff(xs) <= 0):  # pragma: no cover - two guesses met the same root
        raise RuntimeError(f"Gauss-Jacobi nodes not distinct (n={n}, beta={beta})")
    xs.flags.writeable = False
    ws = np.array([float(v) for v in weights])
    ws.flags.writeable = False
    return xs, ws


def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes [-] and weights [-] of the n-point Gauss–Legendre rule on [-1, 1]."""
    return gauss_jacobi(n, 0.0)
