"""Tabulated KE contact law: net load N(d), pull-off, and the inversion N -> d -> Q(d).

:class:`ContactTable` is the contact law of one parameter set in physical units: the per-asperity
base table (built in :mod:`.table_build` from :mod:`.rough_surface`, cached by
:mod:`.table_cache`) scaled by the asperity count and the friction calibration. Lookup is a binary
search plus one cubic Hermite in ``u = sqrt(N - N_min)``: no root finding.

The builder's and the cache's public names stay importable from here (``base_table``,
``build_base_table``, ``table_key``, ``cache_dir``, ``TABLE_FORMAT``, ...); to replace the memory
cache or the builder (tests), patch :mod:`.table_cache`, which is where they are looked up.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicHermiteSpline

from .materials import ContactParams, ParameterError
from .rough_surface import Normalised, SurfaceIntegrals
# the builder's and the cache's public names, importable from here too (re-exports)
from .table_build import DEFAULT_LOAD_RATIO, DEFAULT_SPACING, BaseTable, _per_asperity, \
    build_base_table  # noqa: F401
from .table_cache import TABLE_FORMAT, base_table, cache_dir, consistent, table_key  # noqa: F401


class DetachmentError(RuntimeError):
    """A load below the pull-off force (N < -F_pull): the part leaves the surface."""

    def __init__(self, load: float, pull_off: float) -> None:
        self.load = float(load)
        self.pull_off = float(pull_off)
        super().__init__(f"load N = {self.load:.6g} N is below -F_pull = {-self.pull_off:.6g} N: "
                         "the part detaches (no contact state exists)")


class TableRangeError(ValueError):
    """A load above the largest tabulated load (rebuild with a larger ``load_ratio``)."""


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
