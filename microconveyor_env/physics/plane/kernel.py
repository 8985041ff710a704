"""Compiled dynamics of a part on the plane (docs/physics.md §10.4-10.6): the 2-D counterpart of
:mod:`..dynamics_kernel`, event mode only. Plain arrays in, plain arrays out.

State ``(x, y, vx, vy)`` [m, m, m/s, m/s] at time ``t`` [s]. One firing (:func:`fire`) coasts
through the delay in closed form (:func:`coast`), integrates the stroke with fixed-step RK4 on the
1-D kernel's grid (``steps_for``, unload nodes, cut at the time limit) with stick -> slip,
slip -> stick and detachment located inside the step, and optionally coasts to rest. Outcome codes
are the 1-D kernel's (``REST``, ``DETACHED``, ``MAX_TIME``, ``MOVING``, ``TOO_MANY_EVENTS``,
``BEYOND_TABLE``). ``P``, ``tu, tq, tqu`` are the 1-D model constants and contact table arrays
(:mod:`.forces`); :class:`.simulator.PlaneSimulator` builds them.

Sliding: a step starts with the reference direction ``e = v/|v|`` (from rest: the break-away
direction), the friction directed over it by :func:`.forces.step_direction`, and is accepted
while ``v . e`` stays positive and the load above pull-off (a dip of the load inside the step is
searched for as in 1-D). Otherwise the instant where ``min(v . e / v_scale, (N + F_pull) /
F_pull)`` reaches 0 is located on the partial RK4 step (Illinois). There the part detaches if the
load reached pull-off; it stops if its speed is below ``STOP_TOLERANCE * v_scale``, or if the disc
can hold it and the speed left (transverse to ``e``) would coast less than ``STOP_TOLERANCE *
v_scale * step`` (then the disc test decides: stick, or break away along the unbalanced force);
otherwise its velocity has turned within the step and it slides on with a new reference direction.
"""
from __future__ import annotations

import math

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ..dynamics_kernel import (
    BEYOND_TABLE,
    COAST_POINTS,
    DETACHED,
    MAX_EVENTS_PER_STEP,
    MAX_TIME,
    MOVING,
    REST,
    TAU_UNLOAD,
    TOO_MANY_EVENTS,
    _next_node,
    steps_for,
)
from ..forces import I_MASS, I_NMAX, I_NMIN
from .events import _hidden_pull_off, _illinois_slip, _illinois_stick, _slip_event, _vscale
from .forces import plane_friction, plane_normal_load, plane_rk4, plane_stick_state

# ---- out array slots ----
O_X, O_Y, O_VX, O_VY, O_T, O_OUTCOME, O_EVENT_T, O_EVENT_X, O_EVENT_Y, O_STEPS, O_EVENTS, \
    O_NREC, O_STICK = range(13)
N_OUT = 13
# ---- record columns ----
R_T, R_X, R_Y, R_VX, R_VY, R_Z, R_N, R_Q, R_STICK = range(9)
N_REC = 9
STOP_TOLERANCE = 1e-9  # [-] a located end of slip is a stop below this * v_scale (speed) or,
                       # where friction can hold the part, this * v_scale * step (coasting distance)


@njit(cache=True)
def _record(rec, out, t, x, y, vx, vy, stuck, xa, ya, f, h, tl, P, tu, tq, tqu):
    """Append a trajectory row (``stuck`` 1.0 while the part sticks, else 0.0)."""
    k = int(out[O_NREC])
    if k >= rec.shape[0]:
        return
    N, _, _, _, Z = plane_normal_load(x, y, vx, vy, tl, xa, ya, f, h, P)
    rec[k, R_T] = t
    rec[k, R_X] = x
    rec[k, R_Y] = y
    rec[k, R_VX] = vx
    rec[k, R_VY] = vy
    rec[k, R_Z] = Z
    rec[k, R_N] = N
    rec[k, R_Q] = plane_friction(N, P, tu, tq, tqu) if N >= P[I_NMIN] else 0.0
    rec[k, R_STICK] = stuck
    out[O_NREC] = k + 1


@njit(cache=True)
def coast(x, y, vx, vy, duration, P, tu, tq, tqu):
    """Closed-form motion on the still, level surface for ``duration`` [s] (may be inf): a straight
    line at constant deceleration ``Q(m g0)/m`` against the velocity, then rest (a resting part
    stays: the disc test always holds on the level).

    Returns ``(x, y, vx, vy, elapsed, at_rest, t_stop)`` (``t_stop`` relative, or -1).
    """
    sp = math.sqrt(vx * vx + vy * vy)
    if sp == 0.0:
        return x, y, 0.0, 0.0, 0.0, True, 0.0
    N0, Zx, Zy, c, _ = plane_normal_load(x, y, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, P)
    Q0 = plane_friction(N0, P, tu, tq, tqu)
    ux, uy = vx / sp, vy / sp
    m = P[I_MASS]
    ax = (-ux * Q0 * c - N0 * Zx * c) / m
    ay = (-uy * Q0 * c - N0 * Zy * c) / m
    a_along = ux * ax + uy * ay
    if a_along < 0.0:
        t_stop = -sp / a_along
        if t_stop <= duration:
            return (x + vx * t_stop + 0.5 * ax * t_stop * t_stop,
                    y + vy * t_stop + 0.5 * ay * t_stop * t_stop, 0.0, 0.0, t_stop, True, t_stop)
    if math.isinf(duration):
        return x, y, vx, vy, math.inf, False, -1.0
    return (x + vx * duration + 0.5 * ax * duration * duration,
            y + vy * duration + 0.5 * ay * duration * duration,
            vx + ax * duration, vy + ay * duration, duration, False, -1.0)


# ---- events (the plane's :mod:`.events`) ----
@njit(cache=True, inline="always")
def _stuck_substep(x, y, tl, t_end, ex, ey, xa, ya, f, h, P, tu, tq, tqu):
    """A resting part: stays put to t_end, or breaks away / detaches at the located instant.
    Returns (tl, ex, ey, stuck, outcome, events)."""
    m1, d1, _, _ = plane_stick_state(x, y, t_end, xa, ya, f, h, P, tu, tq, tqu)
    if m1 > 0.0 and d1 > 0.0:
        return t_end, ex, ey, True, MOVING, 0
    tc = _illinois_stick(x, y, tl, t_end, xa, ya, f, h, P, tu, tq, tqu)
    mc, dc, bx, by = plane_stick_state(x, y, tc, xa, ya, f, h, P, tu, tq, tqu)
    if dc <= 0.0 and dc <= mc:
        return tc, ex, ey, True, DETACHED, 1
    return tc, bx, by, False, MOVING, 1


@njit(cache=True, inline="always")
def _slide_substep(x, y, vx, vy, tl, t_end, ex, ey, xa, ya, f, h, P, tu, tq, tqu):
    """A sliding part: one RK4 step to t_end if the slip and the contact last through it, else the
    first event is located and handled. Returns (x, y, vx, vy, tl, ex, ey, stuck, outcome, events).
    """
    n_min = P[I_NMIN]
    sp = math.sqrt(vx * vx + vy * vy)
    if sp > 0.0:  # from rest: e is the break-away direction
        ex, ey = vx / sp, vy / sp
    hs = t_end - tl
    h_dir = hs  # the friction direction's stiffness is judged on the whole step (plane_rk4)
    xn, yn, vxn, vyn = plane_rk4(x, y, vx, vy, tl, hs, ex, ey, h_dir, xa, ya, f, h, P, tu, tq, tqu)
    Nn = plane_normal_load(xn, yn, vxn, vyn, t_end, xa, ya, f, h, P)[0]
    h_ev = hs
    if vxn * ex + vyn * ey > 0.0 and Nn >= n_min:
        tm = _hidden_pull_off(x, y, vx, vy, xn, yn, vxn, vyn, tl, hs, Nn, xa, ya, f, h, P)
        if tm <= 0.0 or _slip_event(x, y, vx, vy, tl, tm, ex, ey, h_dir, 1.0, xa, ya, f, h, P, tu,
                                    tq, tqu) > 0.0:
            return xn, yn, vxn, vyn, t_end, ex, ey, False, MOVING, 0
        h_ev = tm
    vscale = _vscale(x, y, vx, vy, tl, h_ev, ex, ey, xa, ya, f, h, P, tu, tq, tqu)
    tau = _illinois_slip(x, y, vx, vy, tl, h_ev, ex, ey, h_dir, vscale, xa, ya, f, h, P, tu, tq,
                         tqu)
    if tau > 0.0:
        x, y, vx, vy = plane_rk4(x, y, vx, vy, tl, tau, ex, ey, h_dir, xa, ya, f, h, P, tu, tq, tqu)
        tl = tl + tau
    if plane_normal_load(x, y, vx, vy, tl, xa, ya, f, h, P)[0] <= n_min:
        return x, y, vx, vy, tl, ex, ey, False, DETACHED, 1
    mc, _, bx, by = plane_stick_state(x, y, tl, xa, ya, f, h, P, tu, tq, tqu)
    v2 = vx * vx + vy * vy
    if v2 <= (STOP_TOLERANCE * vscale) ** 2:  # stopped (as in 1-D): stick, or break away
        if mc >= 0.0:
            return x, y, 0.0, 0.0, tl, ex, ey, True, MOVING, 1
        return x, y, 0.0, 0.0, tl, bx, by, False, MOVING, 1
    if mc >= 0.0 and P[I_MASS] * v2 <= 2.0 * mc * STOP_TOLERANCE * vscale * h_ev:
        # a transverse remainder the friction would stop within STOP_TOLERANCE * vscale * h_ev
        return x, y, 0.0, 0.0, tl, ex, ey, True, MOVING, 1
    return x, y, vx, vy, tl, ex, ey, False, MOVING, 1  # turned, not stopped: slide on


@njit(cache=True, inline="always")
def _event_step(x, y, vx, vy, tl, t_end, ex, ey, stuck, t0, xa, ya, f, h, P, tu, tq, tqu, rec,
                out):
    """One step from tl to t_end through its events (at most MAX_EVENTS_PER_STEP + 1).
    Returns (x, y, vx, vy, tl, ex, ey, stuck, outcome)."""
    recording = rec.shape[0] > 0
    n_ev = 0
    while tl < t_end:
        if n_ev > MAX_EVENTS_PER_STEP:
            return x, y, vx, vy, tl, ex, ey, stuck, TOO_MANY_EVENTS
        out[O_STEPS] += 1
        if stuck:
            tl, ex, ey, stuck, outcome, ev = _stuck_substep(x, y, tl, t_end, ex, ey, xa, ya, f,
                                                            h, P, tu, tq, tqu)
        else:
            x, y, vx, vy, tl, ex, ey, stuck, outcome, ev = _slide_substep(
                x, y, vx, vy, tl, t_end, ex, ey, xa, ya, f, h, P, tu, tq, tqu)
        n_ev += ev
        out[O_EVENTS] += ev
        if outcome != MOVING:
            return x, y, vx, vy, tl, ex, ey, stuck, outcome
        if ev > 0 and recording:
            _record(rec, out, t0 + tl, x, y, vx, vy, 1.0 if stuck else 0.0, xa, ya, f, h, tl, P,
                    tu, tq, tqu)
    if recording:
        _record(rec, out, t0 + t_end, x, y, vx, vy, 1.0 if stuck else 0.0, xa, ya, f, h, t_end,
                P, tu, tq, tqu)
    return x, y, vx, vy, tl, ex, ey, stuck, MOVING


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # numba's typing omits _nrt
def stroke(x, y, vx, vy, t0, xa, ya, f, h, n_steps, t_lim, P, tu, tq, tqu, rec, out):
    """Integrate one stroke of the actuator at ``(xa, ya)`` [m] (frequency ``f`` [Hz], height
    ``h`` [m], ``n_steps`` RK4 steps plus the unload nodes) from the state at time ``t0`` [s], cut
    at ``t_lim`` [s, relative to t0]. Returns ``(x, y, vx, vy, outcome)``, outcome MOVING (stroke
    finished), DETACHED, MAX_TIME, TOO_MANY_EVENTS or BEYOND_TABLE; the event's time and place go
    to ``out``."""
    T = 1.0 / f
    dt = T / n_steps
    t_unload1 = TAU_UNLOAD * 0.5 * T
    t_unload2 = T - t_unload1
    stuck = vx == 0.0 and vy == 0.0
    sp = math.sqrt(vx * vx + vy * vy)
    ex, ey = (vx / sp, vy / sp) if sp > 0.0 else (1.0, 0.0)
    tl = 0.0
    k = 0
    if rec.shape[0] > 0:
        _record(rec, out, t0, x, y, vx, vy, 1.0 if stuck else 0.0, xa, ya, f, h, tl, P, tu, tq,
                tqu)
    outcome = MOVING
    while True:
        if plane_normal_load(x, y, vx, vy, tl, xa, ya, f, h, P)[0] > P[I_NMAX]:
            outcome = BEYOND_TABLE
            break
        if tl >= T:
            break
        if tl >= t_lim:
            outcome = MAX_TIME
            break
        t_end, k = _next_node(tl, k, n_steps, dt, T, t_unload1, t_unload2, t_lim)
        x, y, vx, vy, tl, ex, ey, stuck, outcome = _event_step(
            x, y, vx, vy, tl, t_end, ex, ey, stuck, t0, xa, ya, f, h, P, tu, tq, tqu, rec, out)
        if outcome != MOVING:
            break
    if outcome != MOVING:
        out[O_EVENT_T] = t0 + tl
        out[O_EVENT_X] = x
        out[O_EVENT_Y] = y
        return x, y, vx, vy, outcome
    if stuck:
        vx, vy = 0.0, 0.0
    return x, y, vx, vy, MOVING


@njit(cache=True)
def _record_coast(x, y, vx, vy, t, span, P, tu, tq, tqu, rec, out):
    """COAST_POINTS trajectory rows over the moving part of a closed-form coast of ``span`` [s]."""
    _, _, _, _, _, rest, t_stop = coast(x, y, vx, vy, span, P, tu, tq, tqu)
    moving = t_stop if rest else span
    if not 0.0 < moving < math.inf:
        return
    for j in range(1, COAST_POINTS + 1):
        tau = moving * j / COAST_POINTS
        xj, yj, vxj, vyj, _, _, _ = coast(x, y, vx, vy, tau, P, tu, tq, tqu)
        _record(rec, out, t + tau, xj, yj, vxj, vyj, 1.0 if vxj == 0.0 and vyj == 0.0 else 0.0,
                0.0, 0.0, 1.0, 0.0, -1.0, P, tu, tq, tqu)


@njit(cache=True)
def fire(x, y, vx, vy, t, xa, ya, f, h, delay, dt, min_steps, to_rest, t_max, P, tu, tq, tqu,
         rec, out):
    """One firing of the actuator at ``(xa, ya)`` [m] on the part at ``(x, y)`` [m] with velocity
    ``(vx, vy)`` [m/s] at time ``t`` [s]: coast for ``delay`` [s], one stroke (frequency ``f``
    [Hz], height ``h`` [m], RK4 steps of at most ``dt`` [s] and at least ``min_steps`` per
    stroke), and with ``to_rest`` coast to rest; nothing goes past ``t_max`` [s].

    Returns ``(x, y, vx, vy, t, outcome)``: REST (at rest from ``t``), MOVING (stroke done,
    ``to_rest`` off), DETACHED (state and time of the detachment), MAX_TIME, TOO_MANY_EVENTS or
    BEYOND_TABLE. No allocation: the per-part call of a batched env. ``rec`` (shape ``(k,
    N_REC)``, ``k = 0`` for none) receives trajectory rows; ``out`` (``N_OUT``) accumulates
    O_STEPS/O_EVENTS/O_NREC and gets O_EVENT_T/X/Y on an event.
    """
    recording = rec.shape[0] > 0
    if delay > 0.0:
        span = min(delay, max(t_max - t, 0.0))
        if recording:
            _record(rec, out, t, x, y, vx, vy, 1.0 if vx == 0.0 and vy == 0.0 else 0.0, 0.0, 0.0,
                    1.0, 0.0, -1.0, P, tu, tq, tqu)
            _record_coast(x, y, vx, vy, t, span, P, tu, tq, tqu, rec, out)
        x, y, vx, vy, _, _, _ = coast(x, y, vx, vy, span, P, tu, tq, tqu)
        t += span
        if span < delay:
            return x, y, vx, vy, t, MAX_TIME
    if t >= t_max:
        return x, y, vx, vy, t, MAX_TIME
    x, y, vx, vy, outcome = stroke(x, y, vx, vy, t, xa, ya, f, h, steps_for(f, dt, min_steps),
                                   t_max - t, P, tu, tq, tqu, rec, out)
    if outcome != MOVING:
        return x, y, vx, vy, out[O_EVENT_T], outcome
    t += 1.0 / f
    if to_rest:
        span = max(t_max - t, 0.0)
        if recording:
            _record_coast(x, y, vx, vy, t, span, P, tu, tq, tqu, rec, out)
        x, y, vx, vy, used, rest, _ = coast(x, y, vx, vy, span, P, tu, tq, tqu)
        if rest:
            t += used
            outcome = REST
        else:
            t = max(t, t_max)
            outcome = MAX_TIME
    return x, y, vx, vy, t, outcome


@njit(cache=True)
def reset_out(out):
    """Zero the counters of ``out`` and clear its event slots."""
    out[O_STEPS] = 0.0
    out[O_EVENTS] = 0.0
    out[O_NREC] = 0.0
    out[O_EVENT_T] = -1.0
    out[O_EVENT_X] = math.nan
    out[O_EVENT_Y] = math.nan


@njit(cache=True)
def finish_out(out, x, y, vx, vy, t, outcome):
    """Write the final state, time and outcome into ``out``."""
    out[O_X] = x
    out[O_Y] = y
    out[O_VX] = vx
    out[O_VY] = vy
    out[O_T] = t
    out[O_OUTCOME] = outcome
    out[O_STICK] = 1.0 if vx == 0.0 and vy == 0.0 else 0.0


@njit(cache=True)
def run(xa, ya, freq, stroke_h, delay, x0, y0, vx0, vy0, t0, dt, min_steps, to_rest, t_max, P,
        tu, tq, tqu, rec, out):
    """Fire a schedule (arrays over firings: actuator positions ``xa``, ``ya`` [m], ``freq``
    [Hz], ``stroke_h`` [m], ``delay`` [s]) from ``(x0, y0, vx0, vy0)`` at ``t0``; fill ``out``."""
    x, y, vx, vy, t = x0, y0, vx0, vy0, t0
    reset_out(out)
    outcome = MOVING
    n = xa.shape[0]
    for k in range(n):
        x, y, vx, vy, t, outcome = fire(x, y, vx, vy, t, xa[k], ya[k], freq[k], stroke_h[k],
                                        delay[k], dt, min_steps, to_rest and k == n - 1, t_max,
                                        P, tu, tq, tqu, rec, out)
        if outcome != MOVING:
            break
    finish_out(out, x, y, vx, vy, t, outcome)


refresh_jit_cache(globals())
