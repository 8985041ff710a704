"""Compiled inner loop of the part dynamics (docs/physics.md §3.4-3.9).
Plain arrays in, plain arrays out.

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
With stretch-dependent roughness (docs/physics.md §4) Q and the pull-off force follow the strain of the
active zone under the part: :func:`.forces.friction_at`, :func:`.forces.n_min_at` and
:func:`.forces.shifted_load` select that lookup at compile time from the tables' dimension, so the
constant-roughness code is unchanged.
"""
from __future__ import annotations

import math

from numba import njit

from .events import hidden_pull_off, illinois_slip, illinois_stick, slip_event
from .forces import EVENT, I_MASS, I_MODE, I_NMAX, I_NMIN, accel_from, friction_at, load_at, \
    load_from, motion, n_min_at, normal_load, rk4_from, shape_of, shifted_load, stick_from, \
    stroke_constants
from ..jit_cache import refresh as refresh_jit_cache

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
COAST_POINTS = 32  # trajectory rows recorded per closed-form coast
# p''(t) of the quintic stroke is most negative at tau = (3 + sqrt 3)/6 of each half (mirrored)
TAU_UNLOAD = (3.0 + math.sqrt(3.0)) / 6.0


@njit(cache=True)
def _record(rec, out, t, x, v, s, xa, f, h, tl, P, tu, tq, tqu):
    """Append a trajectory row; ``s`` is the slip direction (+-1) or 0 while sticking."""
    k = int(out[O_NREC])
    if k >= rec.shape[0]:
        return
    N, Yx, c, Y = normal_load(x, v, tl, xa, f, h, P)
    Q = (friction_at(N, x, tl, xa, f, h, P, tu, tq, tqu) if N >= n_min_at(x, tl, xa, f, h, P, tu)
         else 0.0)
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
    Q0 = friction_at(N0, x, -1.0, 0.0, 1.0, 0.0, P, tu, tq, tqu)  # still surface: no strain
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


# ---- one stroke: the step helpers below, put together by stroke() ----
# They are inlined into stroke() by numba (inline="always") and stroke() is compiled without
# numba's reference-counting runtime (_nrt=False; it allocates nothing, and numba refuses to
# compile it if it ever does): as separate calls, or inlined with reference counting, every step
# would pay an atomic incref/decref per array argument, 10-30 % of a step's time.
@njit(cache=True, inline="always")
def _stop(out, t, x, v, outcome):
    """Note where and when the stroke ended early (O_EVENT_T/O_EVENT_X); (x, v, outcome)."""
    out[O_EVENT_T] = t
    out[O_EVENT_X] = x
    return x, v, outcome


@njit(cache=True, inline="always")
def _next_node(tl, k, n_steps, dt, T, t_unload1, t_unload2, t_lim):
    """End of the step from ``tl``: the next grid node ``(k + 1) dt`` (T for the last), cut at an
    extra node ``t_unload1/2`` or at ``t_lim`` if one lies before it. Returns (t_end, k) with k
    advanced once a grid node is reached."""
    t_end = T if k >= n_steps - 1 else (k + 1) * dt
    if tl < t_unload1 < t_end:
        t_end = t_unload1
    elif tl < t_unload2 < t_end:
        t_end = t_unload2
    if tl < t_lim < t_end:
        t_end = t_lim
    if t_end >= (k + 1) * dt or t_end >= T:
        k += 1
    return t_end, k


@njit(cache=True, inline="always")
def _karnopp_step(x, v, tl, t_end, dt, s, stuck, t0, xa, K, N, Yx, c, P, tu, tq, tqu, rec, out):
    """One Karnopp step from tl to t_end: stick/slip decided once, at its start, by the velocity
    threshold ``v_th = Q dt / m``; detachment if the load is below pull-off there. ``N, Yx, c``:
    the load at (x, v, tl) (:func:`.forces.normal_load`).

    Returns (x, v, tl, s, stuck, outcome): MOVING at t_end, or DETACHED with the state at tl.
    """
    out[O_STEPS] += 1
    f, h = K[0], K[1]
    if shifted_load(N, x, tl, xa, f, h, P, tu) < P[I_NMIN]:
        return x, v, tl, s, stuck, DETACHED
    Q = friction_at(N, x, tl, xa, f, h, P, tu, tq, tqu)
    if abs(v) < Q * dt / P[I_MASS]:
        sv = 1.0 if v > 0.0 else -1.0
        # the slip acceleration at (x, v, tl) in direction sv: Q is the friction at this load
        decreasing = v != 0.0 and v * ((-sv * Q * c - N * Yx * c) / P[I_MASS]) < 0.0
        if decreasing or Q >= abs(N * Yx):  # sticks through the step
            if rec.shape[0] > 0:
                _record(rec, out, t0 + t_end, x, 0.0, 0.0, xa, f, h, t_end, P, tu, tq, tqu)
            return x, 0.0, t_end, s, True, MOVING
        s = 1.0 if -N * Yx > 0.0 else -1.0  # breaks away from (near) rest
    else:
        s = 1.0 if v > 0.0 else -1.0
    a1 = (-s * Q * c - N * Yx * c) / P[I_MASS]
    x, v, _, _ = rk4_from(x, v, tl, t_end - tl, s, a1, xa, K, P, tu, tq, tqu)
    if rec.shape[0] > 0:
        _record(rec, out, t0 + t_end, x, v, s, xa, f, h, t_end, P, tu, tq, tqu)
    return x, v, t_end, s, False, MOVING


@njit(cache=True, inline="always")
def _stuck_substep(x, tl, t_end, s, g, xa, K, P, tu, tq, tqu):
    """A part resting at x from tl: it stays put to t_end, or the first time the stick margin or
    the load above pull-off reaches 0 is located (:func:`illinois_stick`). ``g``: the shape at x
    (:func:`.forces.shape_of`).

    Returns (tl, s, stuck, outcome, events, N, Yx, c): (t_end, s, True, MOVING, 0) if it stays
    put; else the located time with a break-away (slip direction, False, MOVING, 1) or (..,
    DETACHED, 1); (N, Yx, c) the load of the part at rest at t_end.
    """
    N1, Yx1, c1, _ = load_from(x, 0.0, motion(t_end, K), g, P)
    m1, d1, _ = stick_from(N1, Yx1, x, t_end, xa, K, P, tu, tq, tqu)
    if m1 > 0.0 and d1 > 0.0:
        return t_end, s, True, MOVING, 0, N1, Yx1, c1
    tc = illinois_stick(x, tl, t_end, min(m1, d1), g, xa, K, P, tu, tq, tqu)
    Nc, Yxc, _, _ = load_from(x, 0.0, motion(tc, K), g, P)
    mc, dc, sc = stick_from(Nc, Yxc, x, tc, xa, K, P, tu, tq, tqu)
    if dc <= 0.0 and dc <= mc:
        return tc, s, True, DETACHED, 1, N1, Yx1, c1
    return tc, sc, False, MOVING, 1, N1, Yx1, c1


@njit(cache=True, inline="always")
def _slide_substep(x, v, tl, t_end, s, N0, Yx0, c0, xa, K, P, tu, tq, tqu):
    """A part sliding in direction s from tl: one RK4 step to t_end if the slip and the contact
    last through it (no end of slip, no load below pull-off at its end or hidden inside it,
    :func:`hidden_pull_off`); else the first such event is located (:func:`illinois_slip`) and the
    part stops there, sticks or turns (direction of break-away), or detaches. ``N0, Yx0, c0``:
    the load at (x, v, tl) (:func:`.forces.normal_load`).

    Returns (x, v, tl, s, stuck, outcome, events, N, Yx, c): outcome MOVING or DETACHED, events 0
    or 1; (N, Yx, c) the load at the returned state when it is the end of the step with no
    event (events 0, MOVING), else not meaningful.
    """
    f, h = K[0], K[1]
    n_min = P[I_NMIN]
    hs = t_end - tl
    a1 = accel_from(N0, Yx0, c0, s, x, tl, xa, K, P, tu, tq, tqu)
    xn, vn, t4, m4 = rk4_from(x, v, tl, hs, s, a1, xa, K, P, tu, tq, tqu)
    Nr, Yxn, cn, _ = load_from(xn, vn, m4 if t4 == t_end else motion(t_end, K),
                               shape_of(xn, xa, K), P)
    Nn = shifted_load(Nr, xn, t_end, xa, f, h, P, tu)
    h_ev = hs
    if s * vn > 0.0 and Nn >= n_min:
        N0s = shifted_load(N0, x, tl, xa, f, h, P, tu)
        tm = -1.0 if min(N0s, Nn) >= 0.0 else hidden_pull_off(x, v, xn, vn, tl, hs, N0s, Nn, xa,
                                                              K, P, tu)
        if tm <= 0.0 or slip_event(x, v, tl, tm, s, a1, 1.0, xa, K, P, tu, tq, tqu) > 0.0:
            return xn, vn, t_end, s, False, MOVING, 0, Nr, Yxn, cn
        h_ev = tm  # the load dips below pull-off inside the step: locate it
    tau = illinois_slip(x, v, tl, h_ev, s, a1, xa, K, P, tu, tq, tqu)
    if tau > 0.0:
        x, v, tl, _ = rk4_from(x, v, tl, tau, s, a1, xa, K, P, tu, tq, tqu)
    Nc = load_at(x, v, tl, xa, K, P)[0]
    if shifted_load(Nc, x, tl, xa, f, h, P, tu) <= n_min:  # pull-off before v = 0
        return x, v, tl, s, False, DETACHED, 1, Nr, Yxn, cn
    Nc, Yxc, _, _ = load_at(x, 0.0, tl, xa, K, P)
    mc, dc, sc = stick_from(Nc, Yxc, x, tl, xa, K, P, tu, tq, tqu)
    if mc >= 0.0:
        return x, 0.0, tl, s, True, MOVING, 1, Nr, Yxn, cn
    return x, 0.0, tl, sc, False, MOVING, 1, Nr, Yxn, cn


@njit(cache=True, inline="always")
def _event_step(x, v, tl, t_end, s, stuck, t0, xa, K, N, Yx, c, g, g_ok, P, tu, tq, tqu, rec,
                out):
    """One event-mode step from tl to t_end: sub-steps that each run to t_end or to the next
    located stick/slip/detachment event, at most MAX_EVENTS_PER_STEP + 1 events. ``N, Yx, c``:
    the load at (x, v, tl) (:func:`.forces.normal_load`); ``g``: the shape at x if ``g_ok`` (a
    resting part keeps its place, so its shape serves every step it rests).

    Returns (x, v, tl, s, stuck, outcome, valid, N, Yx, c, g, g_ok): MOVING at t_end, or DETACHED
    / TOO_MANY_EVENTS with the state at that moment; with ``valid``, (N, Yx, c) is the load at
    the returned state (a slide to t_end with no event, or a part still at rest), for the next
    step.
    """
    recording = rec.shape[0] > 0
    n_ev = 0
    valid = True  # (N, Yx, c) is the load at (x, v, tl)
    while tl < t_end:
        if n_ev > MAX_EVENTS_PER_STEP:
            return x, v, tl, s, stuck, TOO_MANY_EVENTS, False, N, Yx, c, g, g_ok
        out[O_STEPS] += 1
        if stuck:
            if not g_ok:
                g, g_ok = shape_of(x, xa, K), True
            tl, s, stuck, outcome, ev, N, Yx, c = _stuck_substep(x, tl, t_end, s, g, xa, K, P, tu,
                                                                 tq, tqu)
            s_row = 0.0  # the break-away instant is recorded as sticking
            # the load at rest at t_end: the part stays stuck, so only the next step's check of
            # the table's range reads it, and v (+-0) changes no comparison of N there
            valid = ev == 0
        else:
            if not valid:
                N, Yx, c, _ = load_at(x, v, tl, xa, K, P)
            g_ok = False  # the part slides: its place changes
            x, v, tl, s, stuck, outcome, ev, N, Yx, c = _slide_substep(x, v, tl, t_end, s, N, Yx,
                                                                       c, xa, K, P, tu, tq, tqu)
            s_row = 0.0 if stuck else s
            valid = ev == 0
        n_ev += ev
        out[O_EVENTS] += ev
        if outcome != MOVING:
            return x, v, tl, s, stuck, outcome, False, N, Yx, c, g, g_ok
        if ev > 0 and recording:
            _record(rec, out, t0 + tl, x, v, s_row, xa, K[0], K[1], tl, P, tu, tq, tqu)
    if recording:
        _record(rec, out, t0 + t_end, x, v, 0.0 if stuck else s, xa, K[0], K[1], t_end, P, tu,
                tq, tqu)
    return x, v, tl, s, stuck, MOVING, valid, N, Yx, c, g, g_ok


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def stroke(x, v, t0, xa, f, h, n_steps, t_lim, P, tu, tq, tqu, rec, out):
    """Integrate one stroke (duration 1/f, ``n_steps`` RK4 steps) from state (x, v) at time t0.

    The stroke is cut at ``t_lim`` [s, relative to t0] (the simulated-time limit). In event mode the
    step grid also has nodes where the actuator's downward acceleration peaks (there the load on a
    resting part is smallest), and a sliding step whose load is tensile at an end is searched for
    a dip below pull-off inside it (:func:`hidden_pull_off`), so a detachment cannot hide inside
    a step. Each step is a :func:`_karnopp_step` or an :func:`_event_step`; the load at a step's
    start is computed once, or taken from the step before when it ended there.

    Returns (x, v, outcome) with outcome MOVING (stroke finished), DETACHED, MAX_TIME,
    TOO_MANY_EVENTS or BEYOND_TABLE (the load left the contact table); the event time/place go to
    ``out``.
    """
    K = stroke_constants(f, h, P)
    T = 1.0 / f
    dt = T / n_steps
    event = P[I_MODE] == EVENT
    t_unload1 = TAU_UNLOAD * 0.5 * T if event else T  # extra grid nodes (event mode only)
    t_unload2 = T - t_unload1 if event else T
    stuck = v == 0.0
    s = 1.0 if v >= 0.0 else -1.0
    tl = 0.0
    k = 0
    if rec.shape[0] > 0:
        _record(rec, out, t0, x, v, 0.0 if stuck else s, xa, f, h, tl, P, tu, tq, tqu)
    valid = False  # whether (N, Yx, c) is the load at (x, v, tl)
    N = Yx = c = 0.0
    g, g_ok = (0.0, 0.0, 0.0), False  # the shape at x, while the part rests (event mode)
    while True:
        if not valid:
            N, Yx, c, _ = load_at(x, v, tl, xa, K, P)
        if N > P[I_NMAX]:  # Q(N) would extrapolate
            return _stop(out, t0 + tl, x, v, BEYOND_TABLE)
        if tl >= T:
            break
        if tl >= t_lim:
            return _stop(out, t0 + tl, x, v, MAX_TIME)
        t_end, k = _next_node(tl, k, n_steps, dt, T, t_unload1, t_unload2, t_lim)
        if event:
            x, v, tl, s, stuck, outcome, valid, N, Yx, c, g, g_ok = _event_step(
                x, v, tl, t_end, s, stuck, t0, xa, K, N, Yx, c, g, g_ok, P, tu, tq, tqu, rec, out)
        else:
            x, v, tl, s, stuck, outcome = _karnopp_step(x, v, tl, t_end, dt, s, stuck, t0, xa, K,
                                                        N, Yx, c, P, tu, tq, tqu, rec, out)
            valid = False
        if outcome != MOVING:
            return _stop(out, t0 + tl, x, v, outcome)
    if stuck:
        v = 0.0
    return x, v, MOVING


@njit(cache=True)
def steps_for(f, dt, min_steps):
    """Even number of RK4 steps for a stroke of 1/f: step <= dt and at least min_steps steps."""
    n = max(int(math.ceil(1.0 / (f * dt) - 1e-9)), min_steps, 2)
    return n + (n & 1)


@njit(cache=True)
def fire(x, v, t, xa, f, h, delay, dt, min_steps, to_rest, t_max, P, tu, tq, tqu, rec, out):
    """One firing from (x, v) at time t: coast for ``delay``, stroke, and (``to_rest``) coast to
    rest. Returns (x, v, t, outcome); no allocation (the single-firing entry point of the env).

    ``out`` slots O_STEPS/O_EVENTS/O_NREC accumulate; O_EVENT_T/O_EVENT_X are set on an event.
    """
    recording = rec.shape[0] > 0
    if delay > 0.0:
        if recording:
            _record(rec, out, t, x, v, math.copysign(1.0, v) if v != 0.0 else 0.0, 0.0, 1.0,
                    0.0, -1.0, P, tu, tq, tqu)
        span = min(delay, max(t_max - t, 0.0))  # never coast past the time limit
        if recording:
            _record_coast(x, v, t, span, P, tu, tq, tqu, rec, out)
        x, v, used, rest, t_stop = coast(x, v, span, P, tu, tq, tqu)
        t += span
        if span < delay:
            return x, v, t, MAX_TIME
    if t >= t_max:
        return x, v, t, MAX_TIME
    x, v, outcome = stroke(x, v, t, xa, f, h, steps_for(f, dt, min_steps), t_max - t, P, tu, tq,
                           tqu, rec, out)
    if outcome != MOVING:
        return x, v, out[O_EVENT_T], outcome
    t += 1.0 / f
    if to_rest:
        if recording:
            _record_coast(x, v, t, max(t_max - t, 0.0), P, tu, tq, tqu, rec, out)
        x, v, used, rest, t_stop = coast(x, v, max(t_max - t, 0.0), P, tu, tq, tqu)
        if rest:
            t += used
            outcome = REST
        else:
            t = max(t, t_max)
            outcome = MAX_TIME
    return x, v, t, outcome


@njit(cache=True)
def _record_coast(x, v, t, span, P, tu, tq, tqu, rec, out):
    """Trajectory rows of the closed-form coast of ``span`` [s] from (x, v) at time t:
    COAST_POINTS rows evenly over its moving part, each evaluated exactly (a parabola per phase)."""
    _, _, _, rest, t_stop = coast(x, v, span, P, tu, tq, tqu)
    moving = t_stop if rest else span
    if not 0.0 < moving < math.inf:
        return
    for j in range(1, COAST_POINTS + 1):
        tau = moving * j / COAST_POINTS
        xj, vj, _, _, _ = coast(x, v, tau, P, tu, tq, tqu)
        sj = 0.0 if vj == 0.0 else math.copysign(1.0, vj)
        _record(rec, out, t + tau, xj, vj, sj, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)


@njit(cache=True)
def reset_out(out):
    out[O_STEPS] = 0.0
    out[O_EVENTS] = 0.0
    out[O_NREC] = 0.0
    out[O_EVENT_T] = -1.0
    out[O_EVENT_X] = math.nan


@njit(cache=True)
def finish_out(out, x, v, t, outcome):
    out[O_X] = x
    out[O_V] = v
    out[O_T] = t
    out[O_OUTCOME] = outcome
    out[O_STICK] = 1.0 if v == 0.0 else 0.0


@njit(cache=True)
def run(xa, freq, stroke_h, delay, x0, v0, t0, dt, min_steps, to_rest, t_max, P, tu, tq, tqu,
        rec, out):
    """Fire the schedule (arrays over firings) from (x0, v0) at t0; fill ``out`` (see O_*)."""
    x, v, t = x0, v0, t0
    reset_out(out)
    outcome = MOVING
    n = xa.shape[0]
    for k in range(n):
        x, v, t, outcome = fire(x, v, t, xa[k], freq[k], stroke_h[k], delay[k], dt, min_steps,
                                to_rest and k == n - 1, t_max, P, tu, tq, tqu, rec, out)
        if outcome != MOVING:
            break
    finish_out(out, x, v, t, outcome)


refresh_jit_cache(globals())
