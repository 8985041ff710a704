"""Instantaneous mechanics of the part on the surface, compiled (docs/physics.md §3.2-3.3).

Normal load, the tabulated maximum static friction Q(N), the slip acceleration, one RK4 step and
the stick test: what :mod:`.dynamics_kernel` integrates. Model constants travel in one float
array ``P`` (indices ``I_*``); the part's mass ``P[I_MASS]`` (inertia and weight) and a factor
on the friction ``P[I_FSCALE]`` are what the env's per-episode randomisation varies per part.
"""
from __future__ import annotations

import math

from numba import njit
from numba.extending import overload

from ..jit_cache import refresh as refresh_jit_cache
from .kinematics import shape_constant, shape_eval, shape_with, stroke_eval, stroke_with

# ---- model constants array P ----
I_MASS, I_G0, I_NMIN, I_EXACT, I_SLOPE, I_WL, I_SHAPE, I_MODE, I_NMAX = range(9)
# stretch-dependent roughness (docs/physics.md §4): I_STRETCH = 1 selects the sigma-dependent lookup;
# then P also holds the zone half-length [m], the strain table step in amplitude^2 [m^2], the
# number of strain-table nodes and of sigma nodes, the largest tabulated strain, and from
# I_SDATA on: table offsets (n_sig + 1), -F_pull per sigma node (n_sig) [N], strain nodes.
I_STRETCH, I_ZONE, I_A2STEP, I_NSTRAIN, I_NSIG, I_EMAX = range(9, 15)
# I_FSCALE: factor [-] on the tabulated Q(N) (static and sliding friction), 1 unless the env
# randomises friction per episode (docs/randomisation.md); x * 1.0 == x, so 1 changes nothing
I_FSCALE = 15
N_PARAMS = 16  # I_NMIN: -F_pull [N] (unstretched); I_NMAX: largest tabulated load [N]
I_SDATA = N_PARAMS
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
def stretch_node(x, tl, xa, f, h, P):
    """(k, a): the sigma node and weight of the stretched zone under the part (k = 0, a = 0: no
    strain, outside the active zone or on the still surface)."""
    if abs(x - xa) > P[I_ZONE]:
        return 0, 0.0
    amp = stroke_eval(tl, f, h)[0]
    if amp <= 0.0:
        return 0, 0.0
    n_e = int(P[I_NSTRAIN])
    n_sig = int(P[I_NSIG])
    base = I_SDATA + 2 * n_sig + 1
    s = amp * amp / P[I_A2STEP]
    j = min(int(s), n_e - 2)
    b = s - j
    e = (1.0 - b) * P[base + j] + b * P[base + j + 1]
    g = e / P[I_EMAX] * (n_sig - 1)
    k = min(int(g), n_sig - 2)
    return k, g - k


@njit(cache=True)
def stretch_n_min(x, tl, xa, f, h, P):
    """-F_pull [N] at the stretched roughness under the part (linear in sigma)."""
    k, a = stretch_node(x, tl, xa, f, h, P)
    nb = I_SDATA + int(P[I_NSIG]) + 1
    return (1.0 - a) * P[nb + k] + a * P[nb + k + 1]


@njit(cache=True)
def stretch_friction(N, x, tl, xa, f, h, P, tu, tq, tqu):
    """Q(N) [N] at the stretched roughness under the part: linear in sigma between the two
    neighbouring sigma-node tables (rows of the (1, L) arrays, cut at the offsets in P)."""
    k, a = stretch_node(x, tl, xa, f, h, P)
    nb = I_SDATA + int(P[I_NSIG]) + 1
    o0, o1 = int(P[I_SDATA + k]), int(P[I_SDATA + k + 1])
    u, q_, qu = tu[0], tq[0], tqu[0]
    q = friction_of_load(N, u[o0:o1], q_[o0:o1], qu[o0:o1], P[nb + k])
    if a == 0.0:
        return q
    o2 = int(P[I_SDATA + k + 2])
    q1 = friction_of_load(N, u[o1:o2], q_[o1:o2], qu[o1:o2], P[nb + k + 1])
    return (1.0 - a) * q + a * q1


# The three lookups below are resolved at *compile time* from the table arrays' dimension:
# 1-D tables (constant roughness) compile to exactly the constant-roughness code (no flag test,
# no stretch code); 2-D tables of shape (1, L) (stretch, see Simulator) to the sigma-dependent
# lookup. The plain-Python bodies are the same dispatch, for calls outside compiled code.
def friction_at(N, x, tl, xa, f, h, P, tu, tq, tqu):
    """Q(N) [N] at the roughness under the part, times the friction factor P[I_FSCALE]."""
    if tu.ndim == 1:
        return friction_of_load(N, tu, tq, tqu, P[I_NMIN]) * P[I_FSCALE]
    return stretch_friction(N, x, tl, xa, f, h, P, tu, tq, tqu) * P[I_FSCALE]


def n_min_at(x, tl, xa, f, h, P, tu):
    """-F_pull [N] at the roughness under the part (P[I_NMIN] for constant roughness)."""
    if tu.ndim == 1:
        return P[I_NMIN]
    return stretch_n_min(x, tl, xa, f, h, P)


def shifted_load(N, x, tl, xa, f, h, P, tu):
    """N [N] shifted so that it meets the constant pull-off P[I_NMIN] where the true load meets
    the local (stretch-dependent) one: the kernel's detachment tests compare it with P[I_NMIN].
    For constant roughness it is N itself."""
    if tu.ndim == 1:
        return N
    return N + (P[I_NMIN] - stretch_n_min(x, tl, xa, f, h, P))


@overload(friction_at, inline="always", jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_friction_at(N, x, tl, xa, f, h, P, tu, tq, tqu):
    if tu.ndim == 1:
        return lambda N, x, tl, xa, f, h, P, tu, tq, tqu: friction_of_load(
            N, tu, tq, tqu, P[I_NMIN]) * P[I_FSCALE]
    return lambda N, x, tl, xa, f, h, P, tu, tq, tqu: stretch_friction(
        N, x, tl, xa, f, h, P, tu, tq, tqu) * P[I_FSCALE]


@overload(n_min_at, inline="always", jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_n_min_at(x, tl, xa, f, h, P, tu):
    if tu.ndim == 1:
        return lambda x, tl, xa, f, h, P, tu: P[I_NMIN]
    return lambda x, tl, xa, f, h, P, tu: stretch_n_min(x, tl, xa, f, h, P)


@overload(shifted_load, inline="always", jit_options={"cache": True})  # type: ignore[typeddict-unknown-key]
def _ov_shifted_load(N, x, tl, xa, f, h, P, tu):
    if tu.ndim == 1:
        return lambda N, x, tl, xa, f, h, P, tu: N
    return lambda N, x, tl, xa, f, h, P, tu: N + (P[I_NMIN] - stretch_n_min(x, tl, xa, f, h, P))


# ---- the mechanics at one point, from its parts ----
# A stroke's evaluations share what depends on the stroke alone (:func:`stroke_constants`, the
# tuple ``K``); the load at a point combines the stroke's motion at its time (:func:`motion`) with
# the shape at its place (:func:`shape_of`) in :func:`load_from`. The kernel reuses a motion or a
# shape computed at the same time or place, and a load computed at the same point: every float
# operation keeps its inputs and order, so the results are bit for bit those of
# :func:`normal_load`, :func:`accel`, :func:`rk4` and :func:`stick_state`, which are built from
# the same pieces.
@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def stroke_constants(f, h, P):
    """``K``: what every evaluation on one stroke of frequency ``f`` [Hz] and height ``h`` [m]
    shares: (f, h, period [s], half period [s], its square [s^2], shape code, wavelength [m],
    the shape's constant, :func:`.kinematics.shape_constant`)."""
    period = 1.0 / f
    half = 0.5 * period
    kind = int(P[I_SHAPE])
    wl = P[I_WL]
    return (f, h, period, half, half * half, kind, wl, shape_constant(kind, wl))


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def motion(t, K):
    """The actuator's (p [m], p_t [m/s], p_tt [m/s^2]) at ``t`` [s] into the stroke ``K``."""
    return stroke_with(t, K[2], K[3], K[4], K[1])


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def shape_of(x, xa, K):
    """The shape's (g, g_u [1/m], g_uu [1/m^2]) at the part's place ``x`` [m] (actuator ``xa``)."""
    return shape_with(K[5], x - xa, K[6], K[7])


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def load_from(x, v, m, g, P):
    """(N, Y_x, cos(theta), Y) at position x, velocity v from the stroke's motion ``m`` at the
    time and the shape ``g`` at x (:func:`motion`, :func:`shape_of`)."""
    p, p_t, p_tt = m
    g0, g_u, g_uu = g
    Y, Yx, Ytt, Yxt, Yxx = p * g0, p * g_u, p_tt * g0, p_t * g_u, p * g_uu
    Yx += P[I_SLOPE]
    Y += P[I_SLOPE] * x
    c = 1.0 / math.sqrt(1.0 + Yx * Yx)
    acc = P[I_G0] + Ytt
    if P[I_EXACT] != 0.0:
        acc += 2.0 * Yxt * v + Yxx * v * v
    return P[I_MASS] * c * acc, Yx, c, Y


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def load_at(x, v, t, xa, K, P):
    """:func:`normal_load` on the stroke ``K``."""
    return load_from(x, v, motion(t, K), shape_of(x, xa, K), P)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def accel_from(N, Yx, c, s, x, tl, xa, K, P, tu, tq, tqu):
    """The slip acceleration [m/s^2] in direction ``s`` from the load (N, Y_x, cos(theta)) at the
    point (x, tl) of the stroke ``K``."""
    Q = friction_at(N, x, tl, xa, K[0], K[1], P, tu, tq, tqu)
    return (-s * Q * c - N * Yx * c) / P[I_MASS]


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def rk4_from(x, v, tl, dt, s, a1, xa, K, P, tu, tq, tqu):
    """:func:`rk4` on the stroke ``K`` given its first stage ``a1`` (the acceleration at
    (x, v, tl)). Returns (x, v) after ``dt``, the time ``tl + dt`` and the motion there."""
    x2, v2 = x + 0.5 * dt * v, v + 0.5 * dt * a1
    th = tl + 0.5 * dt
    mh = motion(th, K)
    N, Yx, c, _ = load_from(x2, v2, mh, shape_of(x2, xa, K), P)
    a2 = accel_from(N, Yx, c, s, x2, th, xa, K, P, tu, tq, tqu)
    x3, v3 = x + 0.5 * dt * v2, v + 0.5 * dt * a2
    N, Yx, c, _ = load_from(x3, v3, mh, shape_of(x3, xa, K), P)
    a3 = accel_from(N, Yx, c, s, x3, th, xa, K, P, tu, tq, tqu)
    x4, v4 = x + dt * v3, v + dt * a3
    t4 = tl + dt
    m4 = motion(t4, K)
    N, Yx, c, _ = load_from(x4, v4, m4, shape_of(x4, xa, K), P)
    a4 = accel_from(N, Yx, c, s, x4, t4, xa, K, P, tu, tq, tqu)
    return (x + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4), t4, m4)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def stick_from(N, Yx, x, tl, xa, K, P, tu, tq, tqu):
    """:func:`stick_state` from the load (N, Y_x) of the resting part at (x, tl)."""
    Q = friction_at(N, x, tl, xa, K[0], K[1], P, tu, tq, tqu)
    drive = -N * Yx
    return Q - abs(drive), N - n_min_at(x, tl, xa, K[0], K[1], P, tu), 1.0 if drive > 0.0 else -1.0


@njit(cache=True)
def normal_load(x, v, tl, xa, f, h, P):
    """(N, Y_x, cos(theta), Y) at position x, velocity v, time tl into the stroke."""
    return load_from(x, v, stroke_eval(tl, f, h), shape_eval(int(P[I_SHAPE]), x - xa, P[I_WL]), P)


@njit(cache=True)
def accel(x, v, tl, s, xa, f, h, P, tu, tq, tqu):
    K = stroke_constants(f, h, P)
    N, Yx, c, _ = load_at(x, v, tl, xa, K, P)
    return accel_from(N, Yx, c, s, x, tl, xa, K, P, tu, tq, tqu)


@njit(cache=True)
def rk4(x, v, tl, dt, s, xa, f, h, P, tu, tq, tqu):
    K = stroke_constants(f, h, P)
    N, Yx, c, _ = load_at(x, v, tl, xa, K, P)
    a1 = accel_from(N, Yx, c, s, x, tl, xa, K, P, tu, tq, tqu)
    xn, vn, _, _ = rk4_from(x, v, tl, dt, s, a1, xa, K, P, tu, tq, tqu)
    return xn, vn


@njit(cache=True)
def stick_state(x, tl, xa, f, h, P, tu, tq, tqu):
    """(margin Q - |N tan|, N - N_min, break-away direction) of a part at rest at x."""
    K = stroke_constants(f, h, P)
    N, Yx, c, _ = load_at(x, 0.0, tl, xa, K, P)
    return stick_from(N, Yx, x, tl, xa, K, P, tu, tq, tqu)


refresh_jit_cache(globals())
