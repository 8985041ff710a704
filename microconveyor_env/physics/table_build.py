"""Building the KE contact table: the stable branch of the net load N(d), its pull-off point, and
the friction along it, tabulated per asperity in normalised separation (docs/physics.md §2.4).

*Stable branch.* ``N(d) = P(d) - F_s(d)`` has its minimum ``N_min = -F_pull`` at ``d_A``; on
``d < d_A`` it falls monotonically. Near ``d_A`` the inverse ``d(N)`` has a square-root singularity,
so the table is parametrised by ``u = sqrt(N - N_min)`` (in which ``d`` and ``Q`` are smooth) and
interpolated with cubic Hermite polynomials whose node slopes come from the exact quadrature
derivatives (``dd/du = 2u / N'(d)``, and ``-sqrt(2 / N''(d_A))`` at the pull-off point).

*Scaling.* All forces are proportional to ``eta A_n`` (hence to ``beta``) and ``Q`` also to
``friction_scale``. The base table is per asperity and independent of both, so a calibration
(which fits exactly these two) never rebuilds it. Caching: :mod:`.table_cache`; the physical-unit
table: :class:`.contact_table.ContactTable`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import brentq, minimize_scalar

from .materials import ContactParams
from .rough_surface import Normalised, SurfaceIntegrals

DEFAULT_SPACING = 0.01          # node spacing in d* = d / sigma
DEFAULT_LOAD_RATIO = 1e4        # table covers loads up to this many pull-off forces ...
D_STAR_MIN = -3.0               # ... or up to the load at this separation d / sigma, if less
MIN_LOAD_RATIO = 10.0           # a table must reach at least this many pull-off forces


@dataclass(frozen=True)
class BaseTable:
    """Per-asperity stable-branch table in normalised separation (no beta, no friction scale).

    Arrays run from the pull-off point (u = 0, d* = d_A*) to the most compressed node. Forces are
    per asperity [N]: ``n = N / (eta A_n)``, ``q = Q / (eta A_n friction_scale)``.
    """

    u: np.ndarray        # sqrt(n - n_min) [sqrt(N)]
    d: np.ndarray        # d* at the nodes
    d_u: np.ndarray      # dd*/du
    q: np.ndarray        # q at the nodes
    q_u: np.ndarray      # dq/du
    n: np.ndarray        # n at the nodes
    n_min: float         # minimum of n (= -pull-off per asperity)
    d_pull: float        # d_A*
    d_balance: float     # d* where P = F_s
    build_seconds: float

    def arrays(self) -> dict[str, Any]:
        """The fields by name (arrays and SI scalars), as stored in the cache."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _per_asperity(params: ContactParams, ints: SurfaceIntegrals, d: npt.ArrayLike,
                  derivatives: int = 0) -> dict[str, np.ndarray]:
    r = ints.evaluate(d, derivatives)
    pc, fs0 = params.critical_load, params.adhesion_force_scale
    out = {"n": pc * r["P"] - fs0 * (r["C"] + r["G"]), "q": pc * r["Q"]}
    if derivatives >= 1:
        out["n_d"] = pc * r["dP"] - fs0 * (r["dC"] + r["dG"])
        out["q_d"] = pc * r["dQ"]
    if derivatives >= 2:
        out["n_dd"] = pc * r["ddP"] - fs0 * (r["ddC"] + r["ddG"])
    return out


def build_base_table(params: ContactParams, spacing: float = DEFAULT_SPACING,
                     load_ratio: float = DEFAULT_LOAD_RATIO) -> BaseTable:
    """Locate balance and pull-off points and tabulate the stable branch (no caching); ``spacing``
    [-] in d / sigma, ``load_ratio`` [-] in pull-off forces.

    The branch runs from pull-off to ``load_ratio`` pull-off forces, or to the separation
    ``d* = D_STAR_MIN`` (3 sigma past the mean asperity height: nearly every asperity touching) if
    that load is smaller, which happens on smooth, strongly adhesive surfaces (sigma of a few nm,
    where the pull-off force is ~1e5-1e6 weights of the part). Such a table must still reach
    ``MIN_LOAD_RATIO`` pull-off forces; ``ContactTable.max_load`` says where it ends."""
    t0 = time.perf_counter()
    ints = SurfaceIntegrals(Normalised.from_params(params))

    def n_of(x: float) -> float:
        return float(_per_asperity(params, ints, [x])["n"][0])

    lo, hi = -3.0, 12.0
    if not (n_of(lo) > 0 > n_of(hi)):
        raise RuntimeError("net load does not change sign on d* in [-3, 12]: adhesion or load "
                           "parameters outside the range this table supports")
    d_bal = brentq(n_of, lo, hi, xtol=1e-13, rtol=1e-13)
    # minimum of N beyond the balance point; bracket by scanning
    grid = d_bal + np.linspace(0.0, 6.0, 241)
    ng = _per_asperity(params, ints, grid)["n"]
    k = int(np.argmin(ng))
    if k == 0 or k == grid.size - 1:
        raise RuntimeError("could not bracket the pull-off point (net-load minimum)")
    res = minimize_scalar(n_of, bracket=(grid[k - 1], grid[k], grid[k + 1]),
                          method="brent", options={"xtol": 1e-12})
    d_pull = float(res.x)
    at_pull = _per_asperity(params, ints, [d_pull], derivatives=2)
    n_min, curv = float(at_pull["n"][0]), float(at_pull["n_dd"][0])
    if not curv > 0:
        raise RuntimeError("net load has no proper minimum at the pull-off point")
    n_max = load_ratio * abs(n_min)
    d_lo = d_bal
    while n_of(d_lo) < n_max and d_lo > D_STAR_MIN:
        d_lo = max(d_lo - 0.25, D_STAR_MIN)
    if n_of(d_lo) < MIN_LOAD_RATIO * abs(n_min):
        raise RuntimeError(f"the net load at d* = {D_STAR_MIN:g} (the most compressed separation "
                           f"the table reaches) is below {MIN_LOAD_RATIO:g} pull-off forces")
    m = max(16, math.ceil((d_pull - d_lo) / spacing))
    d = np.linspace(d_pull, d_lo, m + 1)          # from pull-off towards compression
    f = _per_asperity(params, ints, d, derivatives=1)
    n = f["n"]
    n[0] = n_min
    if np.any(np.diff(n) <= 0):
        raise RuntimeError("net load is not monotone on the tabulated stable branch")
    u = np.sqrt(np.maximum(n - n_min, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        d_u = np.where(u > 0, 2 * u / f["n_d"], -math.sqrt(2.0 / curv))
    d_u[0] = -math.sqrt(2.0 / curv)
    q_u = f["q_d"] * d_u
    return BaseTable(u=u, d=d, d_u=d_u, q=f["q"], q_u=q_u, n=n, n_min=n_min, d_pull=d_pull,
                     d_balance=float(d_bal), build_seconds=time.perf_counter() - t0)
