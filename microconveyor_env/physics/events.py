"""Event location inside an RK4 step of the compiled kernel (docs/physics.md §3.7): where a slip
ends (v = 0), a resting part breaks away, or the load reaches pull-off.

Bracketed root finding (Illinois, a modified regula falsi) on the partial RK4 step keeps the
integrator's order; :func:`hidden_pull_off` finds a dip of the load below pull-off *inside* a
sliding step whose ends are both above it.
"""
from __future__ import annotations

from numba import njit

from .forces import I_NMIN, load_at, load_from, motion, rk4_from, shape_of, shifted_load, \
    stick_from
from ..jit_cache import refresh as refresh_jit_cache

GOLDEN_ITERATIONS = 20  # golden-section steps for a load minimum inside a step
SCREEN_MARGIN = 0.25    # search only if the parabolic estimate is within this * F_pull of pull-off


@njit(cache=True)
def _illinois(a, b, fa, fb, c, fc, side):
    """One Illinois (modified regula falsi) bracket update with the new point (c, fc)."""
    if fc > 0.0:
        if side == 1:
            fb *= 0.5
        return c, b, fc, fb, 1
    if side == -1:
        fa *= 0.5
    return a, c, fa, fc, -1


@njit(cache=True)
def _secant(a, b, fa, fb):
    c = (a * fb - b * fa) / (fb - fa)
    return c if a < c < b else 0.5 * (a + b)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def slip_event(x0, v0, tl, tau, s, a1, vscale, xa, K, P, tu, tq, tqu):
    """min(s v / vscale, (N - N_min) / F_pull) after an RK4 sub-step tau from (x0, v0, tl) on
    the stroke ``K`` (``a1``: the acceleration there): > 0 while sliding on."""
    x, v, t, m = rk4_from(x0, v0, tl, tau, s, a1, xa, K, P, tu, tq, tqu)
    N = load_from(x, v, m, shape_of(x, xa, K), P)[0]
    N = shifted_load(N, x, t, xa, K[0], K[1], P, tu)
    return min(s * v / vscale, (N - P[I_NMIN]) / -P[I_NMIN])


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def illinois_slip(x0, v0, tl, hmax, s, a1, xa, K, P, tu, tq, tqu):
    """First tau in (0, hmax] where the slip ends (v = 0) or the load reaches pull-off
    (``a1``: the acceleration at (x0, v0, tl) in direction s)."""
    vscale = max(abs(v0), abs(a1) * hmax, 1e-300)
    a, b = 0.0, hmax
    fb = slip_event(x0, v0, tl, b, s, a1, vscale, xa, K, P, tu, tq, tqu)
    fa = slip_event(x0, v0, tl, 0.0, s, a1, vscale, xa, K, P, tu, tq, tqu)
    if not fa > 0.0:  # starting from rest (s v = 0): find a positive lower point
        lo = hmax
        for _ in range(60):
            lo *= 0.5
            fl = slip_event(x0, v0, tl, lo, s, a1, vscale, xa, K, P, tu, tq, tqu)
            if fl > 0.0:
                a, fa = lo, fl
                break
        else:
            return 0.0
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        fc = slip_event(x0, v0, tl, c, s, a1, vscale, xa, K, P, tu, tq, tqu)
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * hmax:
            break
    return b


@njit(cache=True)
def screened_clear(N0: float, Nm: float, N1: float, n_min: float) -> bool:
    """The cheap screen of :func:`hidden_pull_off` (and of the plane's): True when the parabola
    through the normal loads at a step's ends (``N0``, ``N1``) and midpoint (``Nm``) [N] stays
    above the pull-off load ``n_min`` [N] by ``SCREEN_MARGIN`` of it, so no pull-off can hide."""
    curv = N0 - 2.0 * Nm + N1
    low = min(N0, Nm, N1)
    if curv > 0.0:
        th = 0.5 + 0.25 * (N0 - N1) / curv
        if 0.0 < th < 1.0:
            low = min(low, Nm - 0.125 * (N1 - N0) ** 2 / curv)
    return low - n_min > SCREEN_MARGIN * -n_min


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def hidden_pull_off(x0, v0, x1, v1, tl, hs, N0, N1, xa, K, P, tu):
    """A dip of the load below pull-off *inside* an accepted sliding step (both ends above it).

    ``N0``, ``N1``: the (shifted, :func:`.forces.shifted_load`) loads at the step's ends [N].
    Checked only while the load is tensile at an end of the step, and searched only where a
    parabola through the load at both ends and at the midpoint comes within ``SCREEN_MARGIN``
    F_pull of pull-off: then the load along the step's cubic Hermite interpolant of x(t) is
    minimised by golden-section search. Returns the sub-step length at the minimum if it lies
    below pull-off, else -1.
    """
    n_min = P[I_NMIN]
    if min(N0, N1) >= 0.0:
        return -1.0
    Nm = _load_on_hermite(0.5, x0, v0, x1, v1, tl, hs, xa, K, P, tu)
    if screened_clear(N0, Nm, N1, n_min):
        return -1.0
    a, b = 0.0, 1.0
    g = 0.6180339887498949
    c, d = b - g * (b - a), a + g * (b - a)
    fc = _load_on_hermite(c, x0, v0, x1, v1, tl, hs, xa, K, P, tu)
    fd = _load_on_hermite(d, x0, v0, x1, v1, tl, hs, xa, K, P, tu)
    for _ in range(GOLDEN_ITERATIONS):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = _load_on_hermite(c, x0, v0, x1, v1, tl, hs, xa, K, P, tu)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = _load_on_hermite(d, x0, v0, x1, v1, tl, hs, xa, K, P, tu)
        if min(fc, fd) < n_min:
            break
    if fc < fd:
        return c * hs if fc < n_min else -1.0
    return d * hs if fd < n_min else -1.0


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def _load_on_hermite(th, x0, v0, x1, v1, tl, hs, xa, K, P, tu):
    """Normal load at fraction ``th`` of a step, on the cubic Hermite interpolant of x(t)."""
    t2 = th * th
    t3 = t2 * th
    x = ((2 * t3 - 3 * t2 + 1) * x0 + (t3 - 2 * t2 + th) * hs * v0 + (-2 * t3 + 3 * t2) * x1
         + (t3 - t2) * hs * v1)
    v = ((6 * t2 - 6 * th) * x0 / hs + (3 * t2 - 4 * th + 1) * v0 + (-6 * t2 + 6 * th) * x1 / hs
         + (3 * t2 - 2 * th) * v1)
    t = tl + th * hs
    return shifted_load(load_at(x, v, t, xa, K, P)[0], x, t, xa, K[0], K[1], P, tu)


@njit(cache=True, inline="always")
def _stick_event(x, t, g, xa, K, P, tu, tq, tqu):
    """min(margin, N - N_min) of a part resting at x, whose shape values are ``g``, at t."""
    N, Yx, _, _ = load_from(x, 0.0, motion(t, K), g, P)
    m, d, _ = stick_from(N, Yx, x, t, xa, K, P, tu, tq, tqu)
    return min(m, d)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def illinois_stick(x, t0, t1, fb, g, xa, K, P, tu, tq, tqu):
    """First t in (t0, t1] where min(margin, N - N_min) of a resting part reaches 0 (``fb``: its
    value at t1; ``g``: the shape values at x, :func:`.forces.shape_of`)."""
    a, b = t0, t1
    fa = _stick_event(x, a, g, xa, K, P, tu, tq, tqu)
    if fa <= 0.0:
        return a
    # the function's own values at a and b (Illinois halves fa or fb): once the bracket is as
    # narrow as the times' resolution allows, the secant's fallback midpoint rounds to a or b
    # and the value there is already known
    va, vb = fa, fb
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        if c == a:
            fc = va
        elif c == b:
            fc = vb
        else:
            fc = _stick_event(x, c, g, xa, K, P, tu, tq, tqu)
        if fc > 0.0:  # c becomes a (as _illinois decides)
            va = fc
        else:
            vb = fc
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * (t1 - t0):
            break
    return b


refresh_jit_cache(globals())
