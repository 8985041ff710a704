"""Kogut–Etsion rough-surface integrals by accurate, vectorised quadrature
(docs/physics.md §2.3).

All integrals are computed in lengths normalised by ``sigma`` (starred quantities) and *per asperity*
(i.e. divided by ``eta A_n``)::

    I_P(d*) = int_{d*}^inf  P_asp(w)/P_c   phi(z*) dz*          (contact load)
    I_C(d*) = int_{d*}^inf  f_c(w)/F_s0    phi(z*) dz*          (adhesion of touching asperities)
    I_G(d*) = int_-inf^{d*} f_nc(h)/F_s0   phi(z*) dz*          (Lennard-Jones adhesion across the gap)
    I_Q(d*) = int_{d*}^{d*+6 w_c*} Q_asp(w)/P_c phi(z*) dz*     (maximum static friction)

with ``w = (z* - d*)/omega_c*`` and ``phi`` the standard normal pdf. Physical forces are
``P = eta A_n P_c I_P``, ``F_s = eta A_n F_s0 (I_C + I_G)``, ``Q = eta A_n P_c I_Q``.

Method: every integral is split at the fit boundaries (w = 1, 6, 110, the kinks where the adhesion
fit meets its floor, the root of the friction polynomial). The first piece [0, 1], where the
integrand behaves like ``w^a`` (a = 1.5 or 0.982), uses Gauss–Jacobi nodes with that weight, the other
pieces composite Gauss–Legendre with sub-intervals no longer than ``H_MAX`` sigma. Pieces that begin
beyond ``w_top`` (where the Gaussian factor is below ``phi(TAIL)``) are left out, and when ``w_top < 1``
the Gauss–Jacobi rule covers ``[0, w_top]``: at small plasticity indices (``omega_c* = psi^-2``
large) all contacts are elastic and the node count stays bounded. The Lennard-Jones
gap integral, whose integrand peaks over ``eps`` (~0.02 sigma) and decays like ``h^-2``, is taken in
``s = ln(h/eps)``, which makes it smooth. The same nodes give the first and second derivatives in
``d*`` (``phi' = -z phi``, ``phi'' = (z^2 - 1) phi``), which the contact table uses for Hermite
interpolation. Accuracy is checked against ``scipy.integrate.quad`` in the tests.

*Same bits on every machine*: the nodes come from :mod:`.gauss_rules` (decimal Newton,
not LAPACK), ``exp``/``power`` from :mod:`.portable_math` (IEEE basic operations only, not numpy's
CPU-dispatched ufuncs) and every sum over nodes runs in index order
(:func:`.portable_math.ordered_dot`, not a BLAS dgemv), so the contact table, and everything
computed from it, is bit-identical whatever the BLAS kernel or CPU features.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from . import asperity
from .gauss_rules import gauss_jacobi, gauss_legendre
from .materials import ContactParams
from .portable_math import exp, log, ordered_dot, power, spow

H_MAX = 0.25        # longest Gauss–Legendre sub-interval [sigma]
GL_ORDER = 20       # nodes per sub-interval
JACOBI_ORDER = 40   # nodes on the singular first piece
GAP_DS = 0.1        # sub-interval length in s = ln(h/eps)
TAIL = 12.0         # integrate the Gaussian out to 12 sigma beyond where it matters
_SQRT2PI = math.sqrt(2 * math.pi)


@dataclass(frozen=True)
class Normalised:
    """The dimensionless inputs of the surface integrals."""

    omega_c_star: float      # omega_c / sigma
    eps_star: float          # eps / sigma
    eps_over_omega_c: float
    K: float

    @classmethod
    def from_params(cls, params: ContactParams) -> Normalised:
        """The normalised inputs of ``params``."""
        oc = params.critical_interference
        eps = params.surface.eps
        return cls(oc / params.surface.sigma, eps / params.surface.sigma, eps / oc, params.materials.K)


def _gl_nodes(a: float, b: float, h_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss–Legendre nodes/weights on [a, b] (sub-intervals <= h_max)."""
    if b <= a:
        return np.empty(0), np.empty(0)
    x, wts = gauss_legendre(GL_ORDER)
    n = max(1, math.ceil((b - a) / h_max))
    edges = np.linspace(a, b, n + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[:-1] + edges[1:])
    nodes = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    weights = (half[:, None] * wts[None, :]).ravel()
    return nodes, weights


def _jacobi_unit(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes/weights for int_0^1 w^alpha f(w) dw = sum W_i f(w_i)."""
    x, wts = gauss_jacobi(JACOBI_ORDER, alpha)
    return 0.5 * (1 + x), wts * spow(2.0, -alpha - 1)


def _pieces(breaks: list[float]) -> list[tuple[float, float]]:
    b = sorted(set(float(v) for v in breaks))
    return list(zip(b[:-1], b[1:], strict=True))


class SurfaceIntegrals:
    """Evaluates I_P, I_C, I_G, I_Q (and d*-derivatives) on arrays of normalised separations.

    ``load_model="elastic"`` replaces the KE load fits by Hertz (``w^1.5`` everywhere): the
    Greenwood–Williamson limit used to verify the quadrature.
    """

    def __init__(self, norm: Normalised, load_model: str = "ke") -> None:
        if load_model not in ("ke", "elastic"):
            raise ValueError(f"load_model must be 'ke' or 'elastic', got {load_model!r}")
        self.norm = norm
        self.load_model = load_model
        self._rules: dict[tuple[str, float], tuple[np.ndarray, np.ndarray]] = {}

    # ---- node sets in w (interference ratio); weights already include d(z*) = omega_c* dw ----
    def _w_rule(self, kind: str, w_top: float) -> tuple[np.ndarray, np.ndarray]:
        key = (kind, w_top)
        if key not in self._rules:   # the table's many scalar evaluations share w_top
            self._rules[key] = self._make_w_rule(kind, w_top)
        return self._rules[key]

    def _make_w_rule(self, kind: str, w_top: float) -> tuple[np.ndarray, np.ndarray]:
        oc = self.norm.omega_c_star
        h_w = H_MAX / oc  # sub-interval length in w
        nodes: list[np.ndarray] = []
        weights: list[np.ndarray] = []
        values: list[np.ndarray] = []

        def add(a: float, b: float, fun: Callable[[np.ndarray], np.ndarray],
                singular_alpha: float | None = None) -> None:
            if b <= a or a >= w_top:   # beyond w_top the Gaussian factor is below phi(TAIL)
                return
            if singular_alpha is not None:
                assert a == 0.0 and b == 1.0
                x, wt = _jacobi_unit(singular_alpha)
                if w_top < 1.0:   # the Gaussian ends inside [0, 1]: the rule on [0, w_top]
                    x, wt = w_top * x, wt * spow(w_top, singular_alpha + 1.0)
                val = fun(x) / power(np.maximum(x, 1e-300), singular_alpha)
            else:
                x, wt = _gl_nodes(a, b, h_w)
                val = fun(x)
            nodes.append(x)
            weights.append(wt * oc)
            values.append(val)

        if kind == "P":
            if self.load_model == "elastic":
                add(0.0, 1.0, lambda w: power(np.abs(w), 1.5), 1.5)
                for a, b in _pieces([1.0, w_top]):
                    add(a, b, lambda w: power(w, 1.5))
            else:
                K = self.norm.K
                add(0.0, 1.0, lambda w: asperity.load(w, K), 1.5)
                for a, b in _pieces([1.0, 6.0, asperity.LOAD_PLASTIC_FROM, max(w_top, 110.0)]):
                    add(a, b, lambda w: asperity.load(w, K))
        elif kind == "C":
            k = self.norm.eps_over_omega_c
            kinks = [c for c in asperity.adhesion_floor_crossings(k) if c < w_top]
            for a, b in _pieces([0.0, 1.0, 6.0, w_top] + kinks):
                if a >= w_top:
                    continue
                add(a, min(b, w_top), lambda w: asperity.adhesion_contact(w, k))
        elif kind == "Q":
            add(0.0, 1.0, asperity.friction, asperity.FRICTION_LOW[1])
            add(1.0, asperity.friction_mid_root(), asperity.friction)
        else:  # pragma: no cover
            raise ValueError(kind)
        return np.concatenate(nodes), np.concatenate(weights) * np.concatenate(values)

    def _gap_rule(self, h_top: float) -> tuple[np.ndarray, np.ndarray]:
        """Nodes in h* (gap + eps) and weights for int f_nc(h) phi(d* + eps* - h*) dh*."""
        e = self.norm.eps_star
        s_top = float(log(max(h_top, 2 * e) / e))
        s, ws = _gl_nodes(0.0, s_top, GAP_DS)
        h = e * exp(s)
        return h, ws * h * asperity.adhesion_gap(h / e)

    # ---- evaluation ----
    def evaluate(self, d_star: npt.ArrayLike, derivatives: int = 0,
                 chunk: int = 256) -> dict[str, np.ndarray]:
        """Return {'P','C','G','Q'} arrays [-] at normalised separations ``d_star`` = d / sigma [-]
        (and 'dP', ... up to the requested derivative order); ``chunk`` [-] separations at a time."""
        d = np.atleast_1d(np.asarray(d_star, dtype=float))
        if not np.all(np.isfinite(d)):
            raise ValueError("normalised separations must be finite")
        oc, e = self.norm.omega_c_star, self.norm.eps_star
        w_top = (TAIL + max(0.0, -float(d.min()))) / oc
        rules = {k: self._w_rule(k, w_top) for k in ("P", "C", "Q")}
        h_top = float(d.max()) - (min(float(d.min()), 0.0) - TAIL) + e
        gap_h, gap_w = self._gap_rule(h_top)
        out: dict[str, np.ndarray] = {}
        for key in ("P", "C", "G", "Q"):
            for order in range(derivatives + 1):
                out[("d" * order) + key] = np.empty_like(d)
        for i in range(0, d.size, chunk):
            dd = d[i:i + chunk, None]
            for key in ("P", "C", "Q", "G"):
                if key == "G":
                    z = dd + e - gap_h[None, :]
                    wt = gap_w
                else:
                    w_nodes, wt = rules[key]
                    z = dd + oc * w_nodes[None, :]
                phi = exp(-0.5 * z * z) / _SQRT2PI
                out[key][i:i + chunk] = ordered_dot(phi, wt)
                if derivatives >= 1:
                    out["d" + key][i:i + chunk] = ordered_dot(-z * phi, wt)
                if derivatives >= 2:
                    out["dd" + key][i:i + chunk] = ordered_dot((z * z - 1.0) * phi, wt)
        return out


def surface_forces(params: ContactParams, d: npt.ArrayLike,
                   load_model: str = "ke") -> dict[str, np.ndarray]:
    """P, F_s, N = P - F_s and Q [N] at separations ``d`` [m] by direct quadrature.

    Q includes ``params.friction_scale``. Returns a dict of arrays with keys
    ``P_N, Fs_N, N_N, Q_N``.
    """
    norm = Normalised.from_params(params)
    res = SurfaceIntegrals(norm, load_model).evaluate(np.asarray(d, dtype=float) / params.surface.sigma)
    n = params.asperity_count
    P = n * params.critical_load * res["P"]
    Fs = n * params.adhesion_force_scale * (res["C"] + res["G"])
    Q = n * params.critical_load * params.friction_scale * res["Q"]
    return {"P_N": P, "Fs_N": Fs, "N_N": P - Fs, "Q_N": Q}
