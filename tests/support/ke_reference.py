"""An independent reference for the KE surface integrals: adaptive quadrature in z*
(``scipy.integrate.quad``), no table, no Gauss rules, no portable arithmetic. Shared by the
contact tests and the material presets' tests."""
import math

from scipy import integrate

from microconveyor_env.physics import asperity
from microconveyor_env.physics.rough_surface import Normalised


def PHI(z):  # noqa: N802 - the standard normal density, as the docs write it
    return math.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)


def _quad(f, a, b, points=()):
    edges = [a] + sorted(p for p in points if a < p < b) + [b]
    return sum(integrate.quad(f, lo, hi, epsabs=0, epsrel=1e-12, limit=400)[0]
               for lo, hi in zip(edges[:-1], edges[1:], strict=True))


def reference_integrals(norm, d, keys="PCQG"):
    """The per-asperity integrals I_P, I_C, I_Q, I_G [-] at d* = ``d`` [-] (those named in
    ``keys``)."""
    oc, e, k = norm.omega_c_star, norm.eps_star, norm.eps_over_omega_c
    top = max(d, 0) + 14
    kinks = [d + oc * c for c in asperity.adhesion_floor_crossings(k)]
    brk = [d + oc, d + 6 * oc, d + 110 * oc]
    integrals = {
        "P": lambda: _quad(lambda z: float(asperity.load((z - d) / oc, norm.K)) * PHI(z), d, top,
                           brk),
        "C": lambda: _quad(lambda z: float(asperity.adhesion_contact((z - d) / oc, k)) * PHI(z),
                           d, top, brk + kinks),
        "Q": lambda: _quad(lambda z: float(asperity.friction((z - d) / oc)) * PHI(z), d,
                           d + 6 * oc, [d + oc, d + oc * asperity.friction_mid_root()]),
        "G": lambda: _quad(lambda z: float(asperity.adhesion_gap((d - z + e) / e)) * PHI(z),
                           min(d, 0) - 14, d, [d - e * m for m in (1, 3, 10, 30, 100, 300)])}
    return {key: integrals[key]() for key in keys}


def reference_normal(params, d_star):
    """N [N] at d* = ``d_star`` [-] from :func:`reference_integrals` (without I_Q, which N does
    not need: what a root finder or minimiser of N evaluates)."""
    ref = reference_integrals(Normalised.from_params(params), d_star, "PCG")
    n = params.asperity_count
    return n * (params.critical_load * ref["P"] - params.adhesion_force_scale * (ref["C"] + ref["G"]))


def reference_forces(params, d_star):
    """N and Q [N] at d* = ``d_star`` [-] from :func:`reference_integrals`."""
    ref = reference_integrals(Normalised.from_params(params), d_star)
    n = params.asperity_count
    normal = n * (params.critical_load * ref["P"] - params.adhesion_force_scale * (ref["C"] + ref["G"]))
    return normal, n * params.critical_load * params.friction_scale * ref["Q"]
