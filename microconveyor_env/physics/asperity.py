"""Single-asperity Kogut–Etsion fits (KE 2002 contact, KE 2003 adhesion, KE 2004 friction).

All coefficients live in :data:`KE_FITS`, one table, so the (uncertain) choices are documented in one
place. ``w = omega / omega_c`` is the interference over the critical interference.

Choices made (docs/physics.md §2.2 gives the reasons):

* contact load ``P/P_c``: the four KE 2002 ranges; the fits are used as printed, so ``P`` jumps by
  3 % at ``w = 1`` (1.00 vs 1.03) -- the surface integrals smooth this out;
* adhesion of a touching asperity ``f/F_s0 = a w^b (eps/omega_c)^c``, floored at 1 (the value of the
  Lennard-Jones force at contact, ``h = eps``), because the printed fits vanish as ``w -> 0``;
* maximum static friction ``Q/P_c``: ``0.52 w^0.982`` up to 1, the printed quartic-like polynomial on
  1..6, clipped at 0 (it crosses 0 near ``w = 3.8``), and 0 beyond 6 (fully plastic asperities carry
  no tangential load).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq

from .portable_math import power, spow

# (lower w, upper w, coefficient, exponent) -- P/P_c = coef * w**exp on [lower, upper)
LOAD_RANGES = ((0.0, 1.0, 1.0, 1.5), (1.0, 6.0, 1.03, 1.425), (6.0, 110.0, 1.40, 1.263))
# beyond 110: P/P_c = (3/K) w  (fully plastic)
LOAD_PLASTIC_FROM = 110.0

# (lower w, upper w, a, b, c) -- f/F_s0 = a w**b (eps/omega_c)**c, floored at 1
ADHESION_RANGES = ((0.0, 1.0, 0.98, 0.298, -0.29), (1.0, 6.0, 0.79, 0.35, -0.321),
                   (6.0, np.inf, 1.19, 0.093, -0.332))

FRICTION_LOW = (0.52, 0.982)  # Q/P_c = 0.52 w^0.982 on [0, 1)
FRICTION_MID = ((0.851, 1.425), (-0.41, 2.425), (0.091, 3.425), (-0.011, 4.425))  # on [1, 6)
FRICTION_ZERO_FROM = 6.0

KE_FITS = {
    "load": LOAD_RANGES, "load_plastic_from": LOAD_PLASTIC_FROM,
    "adhesion": ADHESION_RANGES,
    "friction_low": FRICTION_LOW, "friction_mid": FRICTION_MID,
    "friction_zero_from": FRICTION_ZERO_FROM,
}


def load(w: npt.ArrayLike, K: float) -> np.ndarray:
    """Contact load of one asperity over ``P_c`` [-] at interference ratio ``w >= 0`` [-] (0 for
    w <= 0); ``K`` [-] the KE hardness coefficient."""
    w = np.asarray(w, dtype=float)
    out = np.where(w >= LOAD_PLASTIC_FROM, (3.0 / K) * w, 0.0)
    for lo, hi, coef, ex in LOAD_RANGES:
        m = (w > lo) & (w < hi) if lo == 0.0 else (w >= lo) & (w < hi)
        out = np.where(m, coef * power(np.abs(w), ex), out)
    return out


def adhesion_contact(w: npt.ArrayLike, eps_over_omega_c: float) -> np.ndarray:
    """Adhesion of a touching asperity over ``F_s0`` [-] (floored at 1) at interference ratio ``w``
    [-]; ``eps_over_omega_c`` [-]."""
    w = np.asarray(w, dtype=float)
    out = np.ones_like(w)
    for lo, hi, a, b, c in ADHESION_RANGES:
        m = (w >= lo) & (w < hi)
        out = np.where(m, np.maximum(1.0, a * power(np.abs(w), b) * spow(eps_over_omega_c, c)), out)
    return out


def adhesion_gap(h_over_eps: npt.ArrayLike) -> np.ndarray:
    """Lennard-Jones (DMT) adhesion of a non-touching asperity over ``F_s0`` [-]; ``h = d - z + eps``,
    ``h_over_eps`` [-]."""
    r = 1.0 / np.asarray(h_over_eps, dtype=float)
    r2 = r * r
    r4 = r2 * r2
    return (4.0 / 3.0) * (r2 - 0.25 * (r4 * r4))


def _friction_mid_raw(w: npt.ArrayLike) -> Any:  # an array, or a float for a scalar w
    return sum(c * power(np.abs(w), e) for c, e in FRICTION_MID)


def friction(w: npt.ArrayLike) -> np.ndarray:
    """Maximum static friction of one asperity over ``P_c`` [-] at interference ratio ``w`` [-]
    (KE 2004 fits as chosen above)."""
    w = np.asarray(w, dtype=float)
    low = FRICTION_LOW[0] * power(np.abs(w), FRICTION_LOW[1])
    mid = np.maximum(_friction_mid_raw(w), 0.0)
    return np.where(w <= 0, 0.0, np.where(w < 1.0, low, np.where(w < FRICTION_ZERO_FROM, mid, 0.0)))


def friction_mid_root() -> float:
    """Where the printed 1..6 friction polynomial crosses zero (w ~3.8 [-]); beyond it Q_asp = 0."""
    return float(brentq(_friction_mid_raw, 1.0, FRICTION_ZERO_FROM))


def adhesion_floor_crossings(eps_over_omega_c: float) -> list[float]:
    """Interference ratios [-] where an adhesion fit crosses its floor of 1 (kinks of the integrand);
    ``eps_over_omega_c`` [-]."""
    out: list[float] = []
    for lo, hi, a, b, c in ADHESION_RANGES:
        # a w^b k = 1  ->  w = (1 / (a k))^(1/b)
        w = spow(1.0 / (a * spow(eps_over_omega_c, c)), 1.0 / b)
        if lo < w < hi:
            out.append(float(w))
    return out
