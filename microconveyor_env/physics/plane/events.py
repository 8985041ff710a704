"""Event location for the plane (docs/physics.md §10.5): where inside an RK4 step a sliding part
stops or turns (:func:`_illinois_slip` on ``min(v . e / v_scale, (N + F_pull) / F_pull)``), where
a stuck part breaks away (:func:`_illinois_stick` on the disc test), and a pull-off hidden between
two nodes (:func:`_hidden_pull_off`, a golden-section search on the Hermite path). The 2-D
counterparts of :mod:`.events`, whose root finders (Illinois, secant) and constants they reuse;
:mod:`.kernel` calls them.

The loops of the Illinois and golden-section searches are written out here as in :mod:`.events`
rather than shared: a compiled search taking the searched function as an argument gives the
same numbers bit for bit, but numba then refuses to cache every kernel that calls it ("uses
dynamic globals"), so each process would compile the kernels afresh.
"""
from __future__ import annotations

import math

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ..events import GOLDEN_ITERATIONS, _illinois, _secant, screened_clear
from ..forces import I_NMIN
from .forces import plane_accel, plane_normal_load, plane_rk4, plane_stick_state


@njit(cache=True)
def _slip_event(x, y, vx, vy, tl, tau, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq, tqu):
    """min(v . e / vscale, (N - N_min) / F_pull) after an RK4 sub-step tau: > 0 while sliding on."""
    x, y, vx, vy = plane_rk4(x, y, vx, vy, tl, tau, ex, ey, h_dir, xa, ya, f, h, P, tu, tq, tqu)
    N = plane_normal_load(x, y, vx, vy, tl + tau, xa, ya, f, h, P)[0]
    return min((vx * ex + vy * ey) / vscale, (N - P[I_NMIN]) / -P[I_NMIN])


@njit(cache=True)
def _vscale(x, y, vx, vy, tl, hmax, ex, ey, xa, ya, f, h, P, tu, tq, tqu):
    """Velocity scale [m/s] of the slip event: max(|v|, |a| hmax)."""
    ax, ay = plane_accel(x, y, vx, vy, tl, ex, ey, False, 0.0, xa, ya, f, h, P, tu, tq, tqu)
    return max(math.sqrt(vx * vx + vy * vy), math.sqrt(ax * ax + ay * ay) * hmax, 1e-300)


@njit(cache=True)
def _illinois_slip(x, y, vx, vy, tl, hmax, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq, tqu):
    """First tau in (0, hmax] where v . e or the load above pull-off reaches 0 (as
    :func:`..events.illinois_slip`)."""
    a, b = 0.0, hmax
    fb = _slip_event(x, y, vx, vy, tl, b, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq, tqu)
    fa = _slip_event(x, y, vx, vy, tl, 0.0, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq, tqu)
    if not fa > 0.0:  # starting from rest: find a positive lower point
        lo = hmax
        for _ in range(60):
            lo *= 0.5
            fl = _slip_event(x, y, vx, vy, tl, lo, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq,
                             tqu)
            if fl > 0.0:
                a, fa = lo, fl
                break
        else:
            return 0.0
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        fc = _slip_event(x, y, vx, vy, tl, c, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq, tqu)
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * hmax:
            break
    return b


@njit(cache=True)
def _load_on_hermite(th, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P):
    """Normal load at fraction ``th`` of a step, on the cubic Hermite interpolant of (x, y)(t)."""
    t2 = th * th
    t3 = t2 * th
    h00, h10, h01, h11 = 2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + th, -2 * t3 + 3 * t2, t3 - t2
    d00, d10, d01, d11 = 6 * t2 - 6 * th, 3 * t2 - 4 * th + 1, -6 * t2 + 6 * th, 3 * t2 - 2 * th
    x = h00 * x0 + h10 * hs * vx0 + h01 * x1 + h11 * hs * vx1
    y = h00 * y0 + h10 * hs * vy0 + h01 * y1 + h11 * hs * vy1
    vx = d00 * x0 / hs + d10 * vx0 + d01 * x1 / hs + d11 * vx1
    vy = d00 * y0 / hs + d10 * vy0 + d01 * y1 / hs + d11 * vy1
    return plane_normal_load(x, y, vx, vy, tl + th * hs, xa, ya, f, h, P)[0]


@njit(cache=True)
def _hidden_pull_off(x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, N1, xa, ya, f, h, P):
    """A dip of the load below pull-off inside an accepted sliding step (as
    :func:`..events.hidden_pull_off`): the sub-step length at the minimum, or -1."""
    n_min = P[I_NMIN]
    N0 = plane_normal_load(x0, y0, vx0, vy0, tl, xa, ya, f, h, P)[0]
    if min(N0, N1) >= 0.0:
        return -1.0
    Nm = _load_on_hermite(0.5, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P)
    if screened_clear(N0, Nm, N1, n_min):
        return -1.0
    a, b = 0.0, 1.0
    g = 0.6180339887498949
    c, d = b - g * (b - a), a + g * (b - a)
    fc = _load_on_hermite(c, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P)
    fd = _load_on_hermite(d, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P)
    for _ in range(GOLDEN_ITERATIONS):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = _load_on_hermite(c, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = _load_on_hermite(d, x0, y0, vx0, vy0, x1, y1, vx1, vy1, tl, hs, xa, ya, f, h, P)
        if min(fc, fd) < n_min:
            break
    if fc < fd:
        return c * hs if fc < n_min else -1.0
    return d * hs if fd < n_min else -1.0


@njit(cache=True)
def _stick_event(x, y, t, xa, ya, f, h, P, tu, tq, tqu):
    m, d, _, _ = plane_stick_state(x, y, t, xa, ya, f, h, P, tu, tq, tqu)
    return min(m, d)


@njit(cache=True)
def _illinois_stick(x, y, t0, t1, xa, ya, f, h, P, tu, tq, tqu):
    """First t in (t0, t1] where min(margin, N - N_min) of a resting part reaches 0."""
    a, b = t0, t1
    fa = _stick_event(x, y, a, xa, ya, f, h, P, tu, tq, tqu)
    fb = _stick_event(x, y, b, xa, ya, f, h, P, tu, tq, tqu)
    if fa <= 0.0:
        return a
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        fc = _stick_event(x, y, c, xa, ya, f, h, P, tu, tq, tqu)
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * (t1 - t0):
            break
    return b


# ---- one stroke ----


refresh_jit_cache(globals())
