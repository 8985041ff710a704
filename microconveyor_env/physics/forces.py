"""Instantaneous mechanics of the part on the surface, compiled (docs/physics.md §3.2-3.3).

Normal load, the tabulated maximum static friction Q(N), the slip acceleration, one RK4 step and
the stick test: what :mod:`.dynamics_kernel` integrates. Model constants travel in one float
array ``P`` (indices ``I_*``).
"""
from __future__ import annotations

import math

from numba import njit

from .jit_cache import refresh as refresh_jit_cache
from .kinematics import surface_eval

# ---- model constants array P ----
I_MASS, I_G0, I_NMIN, I_EXACT, I_SLOPE, I_WL, I_SHAPE, I_MODE, I_NMAX = range(9)
N_PARAMS = 9  # I_NMIN: -F_pull [N]; I_NMAX: largest tabulated load [N]
KARNOPP, EVENT = 0, 1  # integration modes (used by the kernel)


@njit(cache=True)
def friction_of_load(N, tu, tq, tqu, n_min):
    """Q(N) from the table. N below the pull-off point is clamped to it; above the last node the
    last cubic extrapolates, so callers must keep N <= P[I_NMAX] (the kernel checks every step)."""
    du = N - n_min
    u = math.sqrt(du) if du > 0.0 else 0.0
    n = tu.shape[0]
    lo = 0
    if u >= tu[n - 2]:
        lo = n - 2
    else:
        hi = n - 1
        while hi - lo > 1:
            mid = (lo + hi) >> 1
            if tu[mid] <= u:
                lo = mid
            else:
                hi = mid
    h = tu[lo + 1] - tu[lo]
    t = (u - tu[lo]) / h
    t2 = t * t
    t3 = t2 * t
    return ((2 * t3 - 3 * t2 + 1) * tq[lo] + (t3 - 2 * t2 + t) * h * tqu[lo]
            + (-2 * t3 + 3 * t2) * tq[lo + 1] + (t3 - t2) * h * tqu[lo + 1])


@njit(cache=True)
def normal_load(x, v, tl, xa, f, h, P):
    """(N, Y_x, cos(theta), Y) at position x, velocity v, time tl into the stroke."""
    Y, Yx, Yt, Ytt, Yxt, Yxx = surface_eval(x, tl, xa, f, h, int(P[I_SHAPE]), P[I_WL])
    Yx += P[I_SLOPE]
    Y += P[I_SLOPE] * x
    c = 1.0 / math.sqrt(1.0 + Yx * Yx)
    acc = P[I_G0] + Ytt
    if P[I_EXACT] != 0.0:
        acc += 2.0 * Yxt * v + Yxx * v * v
    return P[I_MASS] * c * acc, Yx, c, Y


@njit(cache=True)
def accel(x, v, tl, s, xa, f, h, P, tu, tq, tqu):
    N, Yx, c, _ = normal_load(x, v, tl, xa, f, h, P)
    Q = friction_of_load(N, tu, tq, tqu, P[I_NMIN])
    return (-s * Q * c - N * Yx * c) / P[I_MASS]


@njit(cache=True)
def rk4(x, v, tl, dt, s, xa, f, h, P, tu, tq, tqu):
    a1 = accel(x, v, tl, s, xa, f, h, P, tu, tq, tqu)
    x2, v2 = x + 0.5 * dt * v, v + 0.5 * dt * a1
    a2 = accel(x2, v2, tl + 0.5 * dt, s, xa, f, h, P, tu, tq, tqu)
    x3, v3 = x + 0.5 * dt * v2, v + 0.5 * dt * a2
    a3 = accel(x3, v3, tl + 0.5 * dt, s, xa, f, h, P, tu, tq, tqu)
    x4, v4 = x + dt * v3, v + dt * a3
    a4 = accel(x4, v4, tl + dt, s, xa, f, h, P, tu, tq, tqu)
    return (x + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))


@njit(cache=True)
def stick_state(x, tl, xa, f, h, P, tu, tq, tqu):
    """(margin Q - |N tan|, N - N_min, break-away direction) of a part at rest at x."""
    N, Yx, c, _ = normal_load(x, 0.0, tl, xa, f, h, P)
    Q = friction_of_load(N, tu, tq, tqu, P[I_NMIN])
    drive = -N * Yx
    return Q - abs(drive), N - P[I_NMIN], 1.0 if drive > 0.0 else -1.0


refresh_jit_cache(globals())
