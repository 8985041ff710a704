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

from numba import njit

from .forces import EVENT, I_MASS, I_MODE, I_NMAX, I_NMIN, accel, friction_of_load, normal_load, rk4, \
    stick_state
from .jit_cache import refresh as refresh_jit_cache

# ---- outcome codes ----
REST, DETACHED, MAX_TIME, MOVING, TOO_MANY_EVENTS, BEYOND_TABLE = 0, 1, 2, 3, 4, 5
OUTCOMES = ("rest", "detached", "max_time", "moving", "too_many_events", "load_beyond_table")
# ---- out array slots ----
O_X, O_V, O_T, O_OUTCOME, O_EVENT_T, O_EVENT_X, O_STEPS, O_EVENTS, O_NREC, O_STICK = range(10)
N_OUT = 10
# ---- record columns ----
R_T, R_X, R_V, R_Y, R_N, R_Q, R_F, R_STICK = range(8)
N_REC = 8
MAX_EVENTS_PER_STEP = 32


@njit(cache=True)
def _record(rec, out, t, x, v, s, xa, f, h, tl, P, tu, tq, tqu):
    """Append a trajectory row; ``s`` is the slip direction (+-1) or 0 while sticking."""
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
    rec[k, R_F] = N * Yx if s == 0.0 else -s * Q
    rec[k, R_STICK] = 1.0 if s == 0.0 else 0.0
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
            if t_stop <= remaining:
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


@njit(cache=True)
def _slip_event(x0, v0, tl, tau, s, vscale, xa, f, h, P, tu, tq, tqu):
    """min(s v / vscale, (N - N_min) / F_pull) after an RK4 sub-step tau: > 0 while sliding on."""
    x, v = rk4(x0, v0, tl, tau, s, xa, f, h, P, tu, tq, tqu)
    N = normal_load(x, v, tl + tau, xa, f, h, P)[0]
    return min(s * v / vscale, (N - P[I_NMIN]) / -P[I_NMIN])


@njit(cache=True)
def _illinois_slip(x0, v0, tl, hmax, s, xa, f, h, P, tu, tq, tqu):
    """First tau in (0, hmax] where the slip ends (v = 0) or the load reaches pull-off."""
    vscale = max(abs(v0), abs(accel(x0, v0, tl, s, xa, f, h, P, tu, tq, tqu)) * hmax, 1e-300)
    a, b = 0.0, hmax
    fb = _slip_event(x0, v0, tl, b, s, vscale, xa, f, h, P, tu, tq, tqu)
    fa = _slip_event(x0, v0, tl, 0.0, s, vscale, xa, f, h, P, tu, tq, tqu)
    if not fa > 0.0:  # starting from rest (s v = 0): find a positive lower point
        lo = hmax
        for _ in range(60):
            lo *= 0.5
            fl = _slip_event(x0, v0, tl, lo, s, vscale, xa, f, h, P, tu, tq, tqu)
            if fl > 0.0:
                a, fa = lo, fl
                break
        else:
            return 0.0
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        fc = _slip_event(x0, v0, tl, c, s, vscale, xa, f, h, P, tu, tq, tqu)
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * hmax:
            break
    return b


@njit(cache=True)
def _stick_event(x, t, xa, f, h, P, tu, tq, tqu):
    m, d, _ = stick_state(x, t, xa, f, h, P, tu, tq, tqu)
    return min(m, d)


@njit(cache=True)
def _illinois_stick(x, t0, t1, xa, f, h, P, tu, tq, tqu):
    """First t in (t0, t1] where min(margin, N - N_min) of a resting part reaches 0."""
    a, b = t0, t1
    fa = _stick_event(x, a, xa, f, h, P, tu, tq, tqu)
    fb = _stick_event(x, b, xa, f, h, P, tu, tq, tqu)
    if fa <= 0.0:
        return a
    side = 0
    for _ in range(100):
        c = _secant(a, b, fa, fb)
        fc = _stick_event(x, c, xa, f, h, P, tu, tq, tqu)
        a, b, fa, fb, side = _illinois(a, b, fa, fb, c, fc, side)
        if b - a <= 1e-15 * (t1 - t0):
            break
    return b


@njit(cache=True)
def stroke(x, v, t0, xa, f, h, n_steps, P, tu, tq, tqu, rec, out):
    """Integrate one stroke (duration 1/f, ``n_steps`` RK4 steps) from state (x, v) at time t0.

    Returns (x, v, outcome) with outcome MOVING (stroke finished), DETACHED, TOO_MANY_EVENTS or
    BEYOND_TABLE (the load left the contact table); the event time/place go to ``out``.
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
        _record(rec, out, t0, x, v, 0.0 if stuck else s, xa, f, h, tl, P, tu, tq, tqu)
    for k in range(n_steps + 1):
        if normal_load(x, v, tl, xa, f, h, P)[0] > P[I_NMAX]:  # Q(N) would extrapolate
            out[O_EVENT_T] = t0 + tl
            out[O_EVENT_X] = x
            return x, v, BEYOND_TABLE
        if k == n_steps:
            break
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
                decreasing = v != 0.0 and v * accel(x, v, tl, sv, xa, f, h, P, tu, tq, tqu) < 0.0
                if decreasing or Q >= abs(N * Yx):
                    v = 0.0
                    stuck = True
                    tl = t_end
                    if recording:
                        _record(rec, out, t0 + tl, x, v, 0.0, xa, f, h, tl, P, tu, tq, tqu)
                    continue
                s = 1.0 if -N * Yx > 0.0 else -1.0
            else:
                s = 1.0 if v > 0.0 else -1.0
            stuck = False
            x, v = rk4(x, v, tl, t_end - tl, s, xa, f, h, P, tu, tq, tqu)
            tl = t_end
            if recording:
                _record(rec, out, t0 + tl, x, v, s, xa, f, h, tl, P, tu, tq, tqu)
            continue
        n_ev = 0  # ------------------------------------------------------ event location
        while tl < t_end:
            if n_ev > MAX_EVENTS_PER_STEP:
                out[O_EVENT_T] = t0 + tl
                out[O_EVENT_X] = x
                return x, v, TOO_MANY_EVENTS
            if stuck:
                m1, d1, _ = stick_state(x, t_end, xa, f, h, P, tu, tq, tqu)
                if m1 > 0.0 and d1 > 0.0:
                    tl = t_end
                    break
                tc = _illinois_stick(x, tl, t_end, xa, f, h, P, tu, tq, tqu)
                mc, dc, sc = stick_state(x, tc, xa, f, h, P, tu, tq, tqu)
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
                    _record(rec, out, t0 + tl, x, v, 0.0, xa, f, h, tl, P, tu, tq, tqu)
            else:
                hs = t_end - tl
                xn, vn = rk4(x, v, tl, hs, s, xa, f, h, P, tu, tq, tqu)
                Nn = normal_load(xn, vn, t_end, xa, f, h, P)[0]
                if s * vn > 0.0 and Nn >= n_min:
                    x, v, tl = xn, vn, t_end
                    break
                tau = _illinois_slip(x, v, tl, hs, s, xa, f, h, P, tu, tq, tqu)
                n_ev += 1
                out[O_EVENTS] += 1
                if tau > 0.0:
                    x, v = rk4(x, v, tl, tau, s, xa, f, h, P, tu, tq, tqu)
                    tl = tl + tau
                Nc = normal_load(x, v, tl, xa, f, h, P)[0]
                if Nc <= n_min:  # the load reached pull-off (before the velocity reached 0)
                    out[O_EVENT_T] = t0 + tl
                    out[O_EVENT_X] = x
                    return x, v, DETACHED
                v = 0.0
                mc, dc, sc = stick_state(x, tl, xa, f, h, P, tu, tq, tqu)
                if mc >= 0.0:
                    stuck = True
                else:
                    s = sc
                if recording:
                    _record(rec, out, t0 + tl, x, v, 0.0 if stuck else s, xa, f, h, tl, P, tu, tq,
                            tqu)
        if recording:
            _record(rec, out, t0 + t_end, x, v, 0.0 if stuck else s, xa, f, h, t_end, P, tu, tq,
                    tqu)
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
                _record(rec, out, t, x, v, math.copysign(1.0, v) if v != 0.0 else 0.0, 0.0, 1.0,
                        0.0, -1.0, P, tu, tq, tqu)
            span = min(delay[k], max(t_max - t, 0.0))  # never coast past the time limit
            x, v, used, rest, t_stop = coast(x, v, span, P, tu, tq, tqu)
            if recording and t_stop > 0.0:
                _record(rec, out, t + t_stop, x, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)
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
            _record(rec, out, t, x, v, 0.0 if rest else math.copysign(1.0, v), 0.0, 1.0, 0.0,
                    -1.0, P, tu, tq, tqu)
    out[O_X] = x
    out[O_V] = v
    out[O_T] = t
    out[O_OUTCOME] = outcome
    out[O_STICK] = 1.0 if v == 0.0 else 0.0




refresh_jit_cache(globals())
