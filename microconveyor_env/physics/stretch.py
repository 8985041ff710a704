"""Stretch-dependent roughness (docs/physics.md §4): contact tables over a grid of sigma.

A uniformly strained active zone (strain ``e``) thins its asperities by Poisson contraction and
spreads them out::

    sigma_n = sigma (1 - nu1 e),   eta_n = eta (1 - e),   R unchanged

so ``psi_n = psi sqrt(sigma_n / sigma)`` and ``beta_n = beta (1 - e)(1 - nu1 e)``. The contact law
becomes two-dimensional, in (sigma, N). :class:`StretchContact` holds one :class:`ContactTable` per
node of a sigma grid (strains 0 .. ``max_strain``) and interpolates linearly in sigma; its
interpolation error is measured by :meth:`StretchContact.sigma_interpolation_error`.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .contact_table import ContactTable
from .materials import ContactParams, ParameterError, check_range


def params_at_strain(params: ContactParams, strain: float) -> ContactParams:
    """The contact parameters of the carrier stretched by ``strain`` [-] (0 <= e < 1)."""
    e = check_range("stretch", "strain", strain, 0.0, 1.0, hi_open=True)
    s = params.surface
    nu = params.materials.nu1
    ratio = 1.0 - nu * e
    return params.replace(surface__sigma=s.sigma * ratio, surface__psi=s.psi * math.sqrt(ratio),
                          surface__beta=s.beta * (1.0 - e) * ratio)


class StretchContact:
    """Contact tables over sigma for strains in [0, max_strain].

    Parameters
    ----------
    params : the unstretched contact parameters.
    max_strain : largest strain tabulated [-] (0 < max_strain < 1).
    n_sigma : number of sigma nodes [-] (uniform in strain).
    table_kw : passed on to :class:`ContactTable`.
    """

    def __init__(self, params: ContactParams, max_strain: float = 0.4, n_sigma: int = 21,
                 **table_kw: Any) -> None:
        check_range("StretchContact", "max_strain", max_strain, 0.0, 1.0, True, True)
        if isinstance(n_sigma, bool) or not isinstance(n_sigma, int) or not 2 <= n_sigma <= 1000:
            raise ParameterError(f"StretchContact.n_sigma = {n_sigma!r} is invalid: must be an "
                                 "integer in [2, 1000]")
        self.params = params
        self.max_strain = float(max_strain)
        self.strains = np.linspace(0.0, self.max_strain, int(n_sigma))
        self.tables = [ContactTable(params_at_strain(params, e), **table_kw) for e in self.strains]
        self.sigmas = np.array([t.params.surface.sigma for t in self.tables])  # decreasing
        self._table_kw = table_kw

    def sigma_at_strain(self, strain: npt.ArrayLike) -> np.ndarray:
        """sigma_n(e) [m] at strain e [-]."""
        return self.params.surface.sigma * (1.0 - self.params.materials.nu1 * np.asarray(strain))

    def _weights(self, sigma: float) -> tuple[int, float]:
        s = float(sigma)
        if not (self.sigmas[-1] <= s <= self.sigmas[0]):
            raise ParameterError(f"sigma = {s:.6g} m is outside the tabulated range "
                                 f"[{self.sigmas[-1]:.6g}, {self.sigmas[0]:.6g}] m "
                                 f"(strain 0..{self.max_strain}); raise max_strain")
        x = (self.sigmas[0] - s) / (self.sigmas[0] - self.sigmas[-1]) * (len(self.sigmas) - 1)
        i = min(int(x), len(self.sigmas) - 2)
        return i, x - i

    def pull_off_force(self, sigma: npt.ArrayLike) -> np.ndarray:
        """Pull-off force [N] as a function of roughness sigma [m] (linear in sigma)."""
        f = np.array([t.pull_off_force for t in self.tables])
        return np.interp(np.asarray(sigma, float), self.sigmas[::-1], f[::-1])

    def friction(self, load: npt.ArrayLike, sigma: float) -> np.ndarray:
        """Maximum static friction Q [N] at load N [N] and roughness sigma [m]."""
        i, a = self._weights(sigma)
        return (1 - a) * self.tables[i].friction(load) + a * self.tables[i + 1].friction(load)

    def sigma_interpolation_error(self, loads: npt.ArrayLike) -> dict[str, float]:
        """Largest relative error of the sigma-interpolated Q and F_pull against tables built
        directly at the midpoints of the sigma grid, over the given loads [N]."""
        worst_q = worst_f = 0.0
        for k in range(len(self.strains) - 1):
            e_mid = 0.5 * (self.strains[k] + self.strains[k + 1])
            direct = ContactTable(params_at_strain(self.params, e_mid), **self._table_kw)
            sig = direct.params.surface.sigma
            loads_ok = np.asarray(loads, float)
            loads_ok = loads_ok[loads_ok > -min(direct.pull_off_force,
                                                self.tables[k].pull_off_force,
                                                self.tables[k + 1].pull_off_force)]
            q_ref = direct.friction(loads_ok)
            worst_q = max(worst_q, float(np.max(np.abs(self.friction(loads_ok, sig) - q_ref) / q_ref)))
            worst_f = max(worst_f, abs(float(self.pull_off_force(sig)) - direct.pull_off_force)
                          / direct.pull_off_force)
        return {"max_rel_error_Q": worst_q, "max_rel_error_pull_off": worst_f}


# ----------------------------------------------------------------------------- for the kernel
N_STRAIN_NODES = 129  # strain-of-amplitude table, uniform in amplitude^2


def strain_table(shape_code: int, wavelength: float, zone_length: float, max_amplitude: float,
                 n: int = N_STRAIN_NODES) -> tuple[float, np.ndarray]:
    """Zone strain e(A) of the active zone (length ``zone_length`` [m], centred on the actuator)
    deflected to amplitude A [m], on ``n`` [-] nodes uniform in A^2 from 0 to ``max_amplitude`` [m]
    squared; ``shape_code`` [-] the kinematics' shape code, ``wavelength`` [m].

    Returns ``(a2_step [m^2], e_nodes [-])``; e is close to linear in A^2 (e ~ c A^2 for small A),
    so linear interpolation in A^2 is accurate (measured by :func:`strain_table_error`)."""
    from .kinematics import zone_strain

    a_max = max(float(max_amplitude), 1e-12)
    a2 = np.linspace(0.0, a_max * a_max, int(n))
    e = np.array([zone_strain(math.sqrt(v), shape_code, wavelength, zone_length) for v in a2])
    return a2[1] - a2[0], e


def strain_table_error(shape_code: int, wavelength: float, zone_length: float,
                       max_amplitude: float, samples: int = 400) -> float:
    """Largest absolute error [-] of the interpolated zone strain over [0, max_amplitude] [m], at
    ``samples`` [-] amplitudes (``wavelength``, ``zone_length`` [m])."""
    from .kinematics import zone_strain

    step, e = strain_table(shape_code, wavelength, zone_length, max_amplitude)
    a = np.linspace(0.0, max_amplitude, samples)
    grid = np.arange(e.size) * step
    interp = np.interp(a * a, grid, e)
    exact = np.array([zone_strain(v, shape_code, wavelength, zone_length) for v in a])
    return float(np.max(np.abs(interp - exact)))


def pack_tables(stretch: StretchContact) -> dict[str, Any]:
    """The sigma-node tables as flat arrays for a compiled lookup: node arrays of table k are
    ``u[o_k:o_k+1]`` etc. with ``o = offsets``; ``n_min[k] = -F_pull`` of table k [N]; the strain
    nodes are uniform from 0 to ``max_strain``."""
    parts = [t.kernel_arrays() for t in stretch.tables]
    sizes = [p[0].size for p in parts]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(float)
    return {"u": np.concatenate([p[0] for p in parts]),
            "q": np.concatenate([p[1] for p in parts]),
            "q_u": np.concatenate([p[2] for p in parts]),
            "offsets": offsets, "n_min": np.array([p[3] for p in parts]),
            "max_load": min(t.max_load for t in stretch.tables),
            "max_strain": stretch.max_strain, "n_sigma": len(stretch.tables)}
