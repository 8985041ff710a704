"""Tabulated KE contact law: net load N(d), pull-off, and the inversion N -> d -> Q(d).

The table is built once per material set from :mod:`.rough_surface` and cached on disk.

*Stable branch.* ``N(d) = P(d) - F_s(d)`` has its minimum ``N_min = -F_pull`` at ``d_A``; on
``d < d_A`` it falls monotonically. Near ``d_A`` the inverse ``d(N)`` has a square-root singularity,
so the table is parametrised by ``u = sqrt(N - N_min)`` (in which ``d`` and ``Q`` are smooth) and
interpolated with cubic Hermite polynomials whose node slopes come from the exact quadrature
derivatives (``dd/du = 2u / N'(d)``, and ``-sqrt(2 / N''(d_A))`` at the pull-off point). Lookup is a
binary search plus one cubic: no root finding.

*Scaling.* All forces are proportional to ``eta A_n`` (hence to ``beta``) and ``Q`` also to
``friction_scale``. The cached base table is stored per asperity and independent of both, so a
calibration (which fits exactly these two) never rebuilds it.
"""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicHermiteSpline
from scipy.optimize import brentq, minimize_scalar

from . import asperity
from .materials import ContactParams, ParameterError, check_range
from . import rough_surface
from .rough_surface import Normalised, SurfaceIntegrals

TABLE_FORMAT = 4                # bump when the stored layout or the quadrature changes (4: portable math)
DEFAULT_SPACING = 0.01          # node spacing in d* = d / sigma
DEFAULT_LOAD_RATIO = 1e4        # table covers loads up to this many pull-off forces


class DetachmentError(RuntimeError):
    """A load below the pull-off force (N < -F_pull): the part leaves the surface."""

    def __init__(self, load: float, pull_off: float) -> None:
        self.load = float(load)
        self.pull_off = float(pull_off)
        super().__init__(f"load N = {self.load:.6g} N is below -F_pull = {-self.pull_off:.6g} N: "
                         "the part detaches (no contact state exists)")


class TableRangeError(ValueError):
    """A load above the largest tabulated load (rebuild with a larger ``load_ratio``)."""


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
    [-] in d / sigma, ``load_ratio`` [-] in pull-off forces."""
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
    while n_of(d_lo) < n_max:
        d_lo -= 0.25
        if d_lo < -3.0:
            raise RuntimeError("table cannot reach the requested maximum load")
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


# ----------------------------------------------------------------------------- caching
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
    (a fit, the quadrature, the portable arithmetic) invalidates cached tables by itself, without
    relying on someone bumping TABLE_FORMAT."""
    from . import gauss_rules, portable_math

    h = hashlib.sha256()
    for mod in (asperity, rough_surface, gauss_rules, portable_math):
        h.update(Path(str(mod.__file__)).read_bytes())
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


# ----------------------------------------------------------------------------- public table
class ContactTable:
    """The contact law of one parameter set, in physical units.

    Parameters
    ----------
    params : ContactParams
    spacing : node spacing of the table in ``d / sigma`` [-].
    load_ratio : the table covers compressive loads up to ``load_ratio * F_pull`` [-].
    use_cache : read/write the on-disk cache.
    """

    def __init__(self, params: ContactParams, spacing: float = DEFAULT_SPACING,
                 load_ratio: float = DEFAULT_LOAD_RATIO, use_cache: bool = True) -> None:
        self.params = params
        self.base = base_table(params, spacing, load_ratio, use_cache)
        self.n_asp = params.asperity_count
        self._sigma = params.surface.sigma
        self._qscale = self.n_asp * params.friction_scale
        self._sqrt_n = math.sqrt(self.n_asp)
        b = self.base  # d(u) and q(u): the cubic Hermite interpolants the kernel evaluates too
        self._d_of_u = CubicHermiteSpline(b.u, b.d, b.d_u)
        self._q_of_u = CubicHermiteSpline(b.u, b.q, b.q_u)

    # ---- scalar characteristics [SI] ----
    @property
    def pull_off_force(self) -> float:
        """F_pull = -min N [N]."""
        return -self.n_asp * self.base.n_min

    @property
    def pull_off_separation(self) -> float:
        """d_A [m]."""
        return self.base.d_pull * self._sigma

    @property
    def balance_separation(self) -> float:
        """Separation where P = F_s (N = 0) [m]."""
        return self.base.d_balance * self._sigma

    @property
    def max_load(self) -> float:
        """Largest tabulated compressive load [N]."""
        return self.n_asp * float(self.base.n[-1])

    def check_weight(self) -> None:
        """ParameterError (naming Part.mass) if the part's weight is beyond the table."""
        part = self.params.part
        if part.weight > self.max_load:
            raise ParameterError(
                f"Part.mass = {part.mass!r} is invalid for this contact: its weight "
                f"{part.weight:.3g} N is beyond the contact table ({self.max_load:.3g} N); use a "
                "lighter part, or more adhesion or contact (Part.area, Surface.beta, "
                "Surface.dgamma)")

    # ---- lookups ----
    def _u(self, load: npt.ArrayLike) -> np.ndarray:
        N = np.asarray(load, dtype=float)
        if not np.all(np.isfinite(N)):
            raise ValueError("load must be finite")
        if np.any(N < -self.pull_off_force):
            bad = float(np.min(N))
            raise DetachmentError(bad, self.pull_off_force)
        if np.any(N > self.max_load):
            raise TableRangeError(f"load {float(np.max(N)):.6g} N exceeds the tabulated maximum "
                                  f"{self.max_load:.6g} N; build the table with a larger load_ratio")
        return np.sqrt(np.maximum(N / self.n_asp - self.base.n_min, 0.0))

    def is_detached(self, load: npt.ArrayLike) -> np.ndarray:
        """True where the load [N] is below -F_pull."""
        return np.asarray(load, dtype=float) < -self.pull_off_force

    def separation(self, load: npt.ArrayLike) -> np.ndarray:
        """Separation d [m] on the stable branch carrying load N [N] (raises DetachmentError)."""
        return self._d_of_u(self._u(load)) * self._sigma

    def friction(self, load: npt.ArrayLike) -> np.ndarray:
        """Maximum static friction Q [N] at load N [N] (raises DetachmentError)."""
        return self._qscale * self._q_of_u(self._u(load))

    def kernel_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Arrays for the compiled kernel: (u_nodes, q_nodes, q_slopes, n_min) in SI, so that
        ``Q(N) = hermite(sqrt(N - n_min))`` with ``n_min = -F_pull`` [N]."""
        b = self.base
        s = self._sqrt_n
        return (b.u * s, b.q * self._qscale, b.q_u * self._qscale / s, -self.pull_off_force)

    # ---- reports ----
    def report(self) -> dict[str, Any]:
        """The contact characteristics in SI units (keys carry unit suffixes)."""
        p = self.params
        w = p.part.weight
        self.check_weight()
        return {
            "pull_off_force_N": self.pull_off_force,
            "pull_off_separation_m": self.pull_off_separation,
            "balance_separation_m": self.balance_separation,
            "weight_N": w,
            "separation_at_weight_m": float(self.separation(w)),
            "friction_at_weight_N": float(self.friction(w)),
            "friction_at_zero_load_N": float(self.friction(0.0)),
            "slip_acceleration_flat_m_s2": float(self.friction(w)) / p.part.mass,
            "asperity_radius_m": p.asperity_radius,
            "critical_interference_m": p.critical_interference,
            "asperity_density_per_m2": p.eta,
            "beta": p.surface.beta,
            "friction_scale": p.friction_scale,
            "max_tabulated_load_N": self.max_load,
            "table_nodes": int(self.base.u.size),
        }


def tabulation_error(table: ContactTable, samples: int = 2000) -> dict[str, Any]:
    """Measure the table against direct quadrature over the whole stable branch.

    Test separations are spread over (d_lo, d_A) away from the nodes; for each, the load N and
    friction Q come from quadrature, then the table's inversion is asked for d(N) and Q(N).
    Returns the largest relative errors [-] of Q and of the separation (and its largest absolute
    error in d / sigma [-]) over ``samples`` [-] test points.
    """
    b = table.base
    rng = np.random.default_rng(12345)
    d = np.sort(rng.uniform(b.d[-1], b.d[0], samples))
    ints = SurfaceIntegrals(Normalised.from_params(table.params))
    f = _per_asperity(table.params, ints, d)
    N = np.maximum(f["n"] * table.n_asp, -table.pull_off_force)
    Q_ref = f["q"] * table._qscale
    Q_tab = table.friction(N)
    d_tab = table.separation(N) / table._sigma
    rel_q = np.abs(Q_tab - Q_ref) / np.abs(Q_ref)
    return {"max_rel_error_Q": float(rel_q.max()),
            "max_abs_error_d_over_sigma": float(np.abs(d_tab - d).max()),
            "max_rel_error_d": float((np.abs(d_tab - d) / np.abs(d)).max()),
            "samples": samples}
