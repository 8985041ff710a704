"""Compiled inner loop of the part dynamics (physics.md §3). Plain arrays in, plain arrays out.

State ``(x, v)``: horizontal position [m] and velocity [m/s] of the part on the surface
``Y = p(t) g(x - x_act) + slope x``. Per firing the kernel

1. advances the **delay** in closed form (surface flat/still: constant acceleration phases),
2. integrates the **stroke** with fixed-step RK4 (``n`` steps, even, aligned with T/2 and T),
3. and after the last firing, optionally coasts **to rest** in closed form.

Modes (``P[I_MODE]``): ``KARNOPP`` -- the dissertation's velocity threshold ``v_th = Q dt / m``
(stick/slip decided once per step, order ~0.5-1); ``EVENT`` -- stick -> slip, slip -> stick and
detachment located inside the step by bracketed root finding (Illinois) on the partial RK4 step,
which keeps the integrator's order.

Friction in slip is ``F = -s Q(N)`` with the slip direction ``s`` fixed over a step (the event
mode stops the step where ``s v`` reaches 0). Sticking needs ``|N tan(theta)| <= Q(N)``.
Detachment: ``N < -F_pull``. ``Q(N)`` is the contact table's cubic Hermite in
``u = sqrt(N + F_pull)``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kinematics import surface_eval

# ---- model constants array P ----
I_MASS, I_G0, I_NMIN, I_EXACT, I_SLOPE, I_WL, I_SHAPE, I_MODE = range(8)
N_PARAMS = 8
KARNOPP, EVENT = 0, 1
# ---- outcome codes ----
REST, DETACHED, MAX_TIME, MOVING, TOO_MANY_EVENTS = 0, 1, 2, 3, 4
OUTCOMES = ("rest", "detached", "max_time", "moving", "too_many_events")
# ---- out array slots ----
O_X, O_V, O_T, O_OUTCOME, O_EVENT_T, O_EVENT_X, O_STEPS, O_EVENTS, O_NREC, O_STICK, O_TABLE = range(11)
N_OUT = 11
# ---- record columns ----
R_T, R_X, R_V, R_Y, R_N, R_Q, R_F, R_STICK = range(8)
N_REC = 8
MAX_EVENTS_PER_STEP = 32


@njit(cache=True)
def friction_of_load(N, tu, tq, tqu, n_min):
    """Q(N) from the table (N below the pull-off point is clamped to it)."""
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
def _accel(x, v, tl, s, xa, f, h, P, tu, tq, tqu):
    N, Yx, c, _ = normal_load(x, v, tl, xa, f, h, P)
    Q = friction_of_load(N, tu, tq, tqu, P[I_NMIN])
    return (-s * Q * c - N * Yx * c) / P[I_MASS]


@njit(cache=True)
def _rk4(x, v, tl, dt, s, xa, f, h, P, tu, tq, tqu):
    a1 = _accel(x, v, tl, s, xa, f, h, P, tu, tq, tqu)
    x2, v2 = x + 0.5 * dt * v, v + 0.5 * dt * a1
    a2 = _accel(x2, v2, tl + 0.5 * dt, s, xa, f, h, P, tu, tq, tqu)
    x3, v3 = x + 0.5 * dt * v2, v + 0.5 * dt * a2
    a3 = _accel(x3, v3, tl + 0.5 * dt, s, xa, f, h, P, tu, tq, tqu)
    x4, v4 = x + dt * v3, v + dt * a3
    a4 = _accel(x4, v4, tl + dt, s, xa, f, h, P, tu, tq, tqu)
    return (x + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))


@njit(cache=True)
def _stick_state(x, tl, xa, f, h, P, tu, tq, tqu):
    """(margin Q - |N tan|, N - N_min, break-away direction) of a part at rest at x."""
    N, Yx, c, _ = normal_load(x, 0.0, tl, xa, f, h, P)
    Q = friction_of_load(N, tu, tq, tqu, P[I_NMIN])
    drive = -N * Yx
    return Q - abs(drive), N - P[I_NMIN], 1.0 if drive > 0.0 else -1.0


@njit(cache=True)
def _record(rec, out, t, x, v, stick, xa, f, h, tl, P, tu, tq, tqu):
    k = int(out[O_NREC])
    if k >= rec.shape[0]:
        return
    N, Yx, c, Y = normal_load(x, v, tl, xa, f, h, P)
    Q = friction_of_load(N, tu, tq, tqu, P[I_NMIN]) if N >= P[I_NMIN] else 0.0
    rec[k, R_T] = t
    rec[k, R_X] = x
    rec[k, R_V] = v
    rec[k, R_Y] = Y
    rec[k, R_N] = N
    rec[k, R_Q] = Q
    rec[k, R_F] = N * Yx if stick else (-Q if v > 0 else Q)
    rec[k, R_STICK] = 1.0 if stick else 0.0
    out[O_NREC] = k + 1


@njit(cache=True)
def coast(x, v, duration, P, tu, tq, tqu):
    """Closed-form motion on the still surface for ``duration`` [s] (may be inf).

    Returns (x, v, elapsed, at_rest, t_stop): the state after ``duration`` (or at rest), the time
    used, whether the part is at rest, and when it came to rest (relative, or -1).
    """
    N0, Yx, c, _ = normal_load(x, 0.0, -1.0, 0.0, 1.0, 0.0, P)
    Q0 = friction_of_load(N0, tu, tq, tqu, P[I_NMIN])
    m = P[I_MASS]
    t_used = 0.0
    for _ in range(3):  # at most: decelerate, stop, slide the other way
        if v == 0.0:
            drive = -N0 * Yx * c
            if Q0 * c >= abs(drive):
                return x, 0.0, t_used, True, t_used
            s = 1.0 if drive > 0 else -1.0
        else:
            s = 1.0 if v > 0 else -1.0
        a = (-s * Q0 * c - N0 * Yx * c) / m
        remaining = duration - t_used
        if s * a < 0.0:
            t_stop = -v / a
            if t_stop < remaining:
                x += v * t_stop + 0.5 * a * t_stop * t_stop
                v = 0.0
                t_used += t_stop
                continue
        if math.isinf(remaining):
            return x, v, math.inf, False, -1.0
        x += v * remaining + 0.5 * a * remaining * remaining
        v += a * remaining
        return x, v, duration, False, -1.0
    return x, v, t_used, v == 0.0, t_used if v == 0.0 else -1.0


@njit(cache=True)
def _illinois_slip(x0, v0, tl, hmax, s, xa, f, h, P, tu, tq, tqu):
    """First tau in (0, hmax] where min(s v, N - N_min) reaches 0 along the RK4 sub-step."""
    a, b = 0.0, hmax
    fa = 1.0  # positive by construction (s v > 0 or just starting from rest)
    xb, vb = _rk4(x0, v0, tl, b, s, xa, f, h, P, tu, tq, tqu)
    Nb = normal_load(xb, vb, tl + b, xa, f, h, P)[0]
    fb = min(s * vb, (Nb - P[I_NMIN]))
    if v0 == 0.0:  # starting from rest: find a positive lower point
        lo = hmax
        for _ in range(60):
            lo *= 0.5
            xl, vl = _rk4(x0, v0, tl, lo, s, xa, f, h, P, tu, tq, tqu)
            Nl = normal_load(xl, vl, tl + lo, xa, f, h, P)[0]
            fl = min(s * vl, (Nl - P[I_NMIN]))
            if fl > 0.0:
                a, fa = lo, fl
                break
        else:
            return 0.0
    side = 0
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        if not (a < c < b):
            c = 0.5 * (a + b)
        xc, vc = _rk4(x0, v0, tl, c, s, xa, f, h, P, tu, tq, tqu)
        Nc = normal_load(xc, vc, tl + c, xa, f, h, P)[0]
        fc = min(s * vc, (Nc - P[I_NMIN]))
        if fc > 0.0:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        if b - a <= 1e-15 * hmax + 1e-300:
            break
    return b


@njit(cache=True)
def _illinois_stick(x, t0, t1, xa, f, h, P, tu, tq, tqu):
    """First t in (t0, t1] where min(margin, N - N_min) of a resting part reaches 0."""
    a, b = t0, t1
    m0, d0, _ = _stick_state(x, a, xa, f, h, P, tu, tq, tqu)
    fa = min(m0, d0)
    m1, d1, _ = _stick_state(x, b, xa, f, h, P, tu, tq, tqu)
    fb = min(m1, d1)
    if fa <= 0.0:
        return a
    side = 0
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        if not (a < c < b):
            c = 0.5 * (a + b)
        mc, dc, _ = _stick_state(x, c, xa, f, h, P, tu, tq, tqu)
        fc = min(mc, dc)
        if fc > 0.0:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        if b - a <= 1e-15 * (t1 - t0) + 1e-300:
            break
    return b


@njit(cache=True)
def stroke(x, v, t0, xa, f, h, n_steps, P, tu, tq, tqu, rec, out):
    """Integrate one stroke (duration 1/f, ``n_steps`` RK4 steps) from state (x, v) at time t0.

    Returns (x, v, outcome) with outcome MOVING (stroke finished), DETACHED or TOO_MANY_EVENTS;
    the detachment time/place go to ``out``.
    """
    T = 1.0 / f
    dt = T / n_steps
    event = P[I_MODE] == EVENT
    n_min = P[I_NMIN]
    m = P[I_MASS]
    recording = rec.shape[0] > 0
    stuck = v == 0.0
    s = 1.0 if v >= 0.0 else -1.0
    tl = 0.0
    if recording:
        _record(rec, out, t0, x, v, stuck, xa, f, h, tl, P, tu, tq, tqu)
    for k in range(n_steps):
        t_end = T if k == n_steps - 1 else (k + 1) * dt
        out[O_STEPS] += 1
        if not event:  # ---------------------------------------------- Karnopp threshold
            N, Yx, c, _ = normal_load(x, v, tl, xa, f, h, P)
            if N < n_min:
                out[O_EVENT_T] = t0 + tl
                out[O_EVENT_X] = x
                return x, v, DETACHED
            Q = friction_of_load(N, tu, tq, tqu, n_min)
            if abs(v) < Q * dt / m:
                sv = 1.0 if v > 0.0 else -1.0
                decreasing = v != 0.0 and v * _accel(x, v, tl, sv, xa, f, h, P, tu, tq, tqu) < 0.0
                if decreasing or Q >= abs(N * Yx):
                    v = 0.0
                    stuck = True
                    tl = t_end
                    if recording:
                        _record(rec, out, t0 + tl, x, v, True, xa, f, h, tl, P, tu, tq, tqu)
                    continue
                s = 1.0 if -N * Yx > 0.0 else -1.0
            else:
                s = 1.0 if v > 0.0 else -1.0
            stuck = False
            x, v = _rk4(x, v, tl, t_end - tl, s, xa, f, h, P, tu, tq, tqu)
            tl = t_end
            if recording:
                _record(rec, out, t0 + tl, x, v, False, xa, f, h, tl, P, tu, tq, tqu)
            continue
        n_ev = 0  # ------------------------------------------------------ event location
        while tl < t_end:
            if n_ev > MAX_EVENTS_PER_STEP:
                out[O_EVENT_T] = t0 + tl
                out[O_EVENT_X] = x
                return x, v, TOO_MANY_EVENTS
            if stuck:
                m1, d1, _ = _stick_state(x, t_end, xa, f, h, P, tu, tq, tqu)
                if m1 > 0.0 and d1 > 0.0:
                    tl = t_end
                    break
                tc = _illinois_stick(x, tl, t_end, xa, f, h, P, tu, tq, tqu)
                mc, dc, sc = _stick_state(x, tc, xa, f, h, P, tu, tq, tqu)
                n_ev += 1
                out[O_EVENTS] += 1
                tl = tc
                if dc <= 0.0 and dc <= mc:
                    out[O_EVENT_T] = t0 + tl
                    out[O_EVENT_X] = x
                    return x, v, DETACHED
                stuck = False
                s = sc
                if recording:
                    _record(rec, out, t0 + tl, x, v, True, xa, f, h, tl, P, tu, tq, tqu)
            else:
                hs = t_end - tl
                xn, vn = _rk4(x, v, tl, hs, s, xa, f, h, P, tu, tq, tqu)
                Nn = normal_load(xn, vn, t_end, xa, f, h, P)[0]
                if s * vn > 0.0 and Nn >= n_min:
                    x, v, tl = xn, vn, t_end
                    break
                tau = _illinois_slip(x, v, tl, hs, s, xa, f, h, P, tu, tq, tqu)
                n_ev += 1
                out[O_EVENTS] += 1
                if tau > 0.0:
                    x, v = _rk4(x, v, tl, tau, s, xa, f, h, P, tu, tq, tqu)
                    tl = tl + tau
                Nc = normal_load(x, v, tl, xa, f, h, P)[0]
                if Nc <= n_min:  # the load reached pull-off (before the velocity reached 0)
                    out[O_EVENT_T] = t0 + tl
                    out[O_EVENT_X] = x
                    return x, v, DETACHED
                v = 0.0
                mc, dc, sc = _stick_state(x, tl, xa, f, h, P, tu, tq, tqu)
                if mc >= 0.0:
                    stuck = True
                else:
                    s = sc
                if recording:
                    _record(rec, out, t0 + tl, x, v, stuck, xa, f, h, tl, P, tu, tq, tqu)
        if recording:
            _record(rec, out, t0 + t_end, x, v, stuck, xa, f, h, t_end, P, tu, tq, tqu)
    if stuck:
        v = 0.0
    return x, v, MOVING


@njit(cache=True)
def steps_for(f, dt, min_steps):
    """Even number of RK4 steps for a stroke of 1/f: step <= dt and at least min_steps steps."""
    n = max(int(math.ceil(1.0 / (f * dt) - 1e-9)), min_steps, 2)
    return n + (n & 1)


@njit(cache=True)
def run(xa, freq, stroke_h, delay, x0, v0, t0, dt, min_steps, to_rest, t_max, P, tu, tq, tqu,
        rec, out):
    """Fire the schedule (arrays over firings) from (x0, v0) at t0; fill ``out`` (see O_*)."""
    x, v, t = x0, v0, t0
    out[O_STEPS] = 0.0
    out[O_EVENTS] = 0.0
    out[O_NREC] = 0.0
    out[O_EVENT_T] = -1.0
    out[O_EVENT_X] = math.nan
    outcome = MOVING
    recording = rec.shape[0] > 0
    for k in range(xa.shape[0]):
        if delay[k] > 0.0:
            if recording:
                _record(rec, out, t, x, v, v == 0.0, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)
            span = min(delay[k], max(t_max - t, 0.0))  # never coast past the time limit
            x, v, used, rest, t_stop = coast(x, v, span, P, tu, tq, tqu)
            if recording and t_stop > 0.0:
                _record(rec, out, t + t_stop, x, 0.0, True, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)
            t += span
            if span < delay[k]:
                outcome = MAX_TIME
                break
        if t >= t_max:
            outcome = MAX_TIME
            break
        x, v, outcome = stroke(x, v, t, xa[k], freq[k], stroke_h[k], steps_for(freq[k], dt, min_steps),
                               P, tu, tq, tqu, rec, out)
        if outcome != MOVING:
            t = out[O_EVENT_T]
            break
        t += 1.0 / freq[k]
    if outcome == MOVING and to_rest:
        x, v, used, rest, t_stop = coast(x, v, max(t_max - t, 0.0), P, tu, tq, tqu)
        if rest:
            t += used
            outcome = REST
        else:
            t = max(t, t_max)
            outcome = MAX_TIME
        if recording:
            _record(rec, out, t, x, v, rest, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)
    out[O_X] = x
    out[O_V] = v
    out[O_T] = t
    out[O_OUTCOME] = outcome
    out[O_STICK] = 1.0 if v == 0.0 else 0.0


