"""Closed forms on a still surface and an independent re-derivation of the normal load, the
equation of motion and the stick condition along recorded trajectories (docs/physics.md §3.2-3.4).

Helpers and constants: ``tests/support/dynamics.py``. Measured numbers are printed (``pytest -s``).
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from microconveyor_env.physics.schedule import ActuatorArray, Schedule

from support.dynamics import F_REF, G0, H, REL, X0, dt_for, normal_load_ref, sim, surface

# ============================================================================ 1. closed forms
@pytest.mark.parametrize("v0", [0.05, -0.05, 0.3])
def test_flat_coast_closed_form_in_a_stroke(v0):
    """Sliding on a still flat surface: stop after v0^2/(2a) at t = v0/a (zero stroke, event mode).

    The 10 us zero-height stroke is integrated by RK4 (exact for constant deceleration), the rest
    by the final closed-form coast, so ``rest_time_s`` is the stopping time itself.
    """
    s = sim()
    a = s.flat_deceleration()
    assert a == pytest.approx(s.table.friction(s.mass * G0) / s.mass, rel=1e-12)
    r = s.simulate(Schedule.single(1e5, 0.0), X0, v0=v0)
    assert r.outcome == "rest"
    assert r.final_velocity_m_s == 0.0
    assert r.displacement_m == pytest.approx(math.copysign(v0 ** 2 / (2 * a), v0), rel=REL)
    assert r.rest_time_s == pytest.approx(abs(v0) / a, rel=REL)


@pytest.mark.parametrize("mode", ["event", "karnopp"])
@pytest.mark.parametrize("v0", [0.05, -0.02])
def test_flat_coast_closed_form_in_a_delay_then_stays(mode, v0):
    """Coasting through a long delay (closed form) stops at v0^2/(2a), t = v0/a; afterwards the
    part stays *exactly* where it stopped through later zero-height firings and long delays."""
    s = sim(mode=mode)
    a = s.flat_deceleration()
    d_ref, t_ref = math.copysign(v0 ** 2 / (2 * a), v0), abs(v0) / a
    r1 = s.simulate(Schedule.single(1000.0, 0.0, delay=1.0), X0, v0=v0, record=True)
    assert r1.outcome == "rest" and r1.final_velocity_m_s == 0.0
    assert r1.displacement_m == pytest.approx(d_ref, rel=REL)
    tr = r1.trajectory
    stop = np.flatnonzero(tr["v_m_s"] == 0.0)[0]
    assert tr["t_s"][stop] == pytest.approx(t_ref, rel=REL)
    assert np.all(tr["x_m"][stop:] == tr["x_m"][stop]) and np.all(tr["v_m_s"][stop:] == 0.0)
    # more zero-height firings and long delays change nothing, bit for bit
    later = Schedule.sequence(ActuatorArray.uniform(4, 0.5e-3, 0.0), [1000.0, 300.0, 2000.0, 950.0],
                              0.0, [1.0, 0.0, 2.5, 0.3])
    r2 = s.simulate(later, X0, v0=v0, record=True)
    assert r2.outcome == "rest"
    assert r2.final_position_m == r1.final_position_m
    assert r2.final_velocity_m_s == 0.0
    tr2 = r2.trajectory
    stop2 = np.flatnonzero(tr2["v_m_s"] == 0.0)[0]
    assert np.all(tr2["x_m"][stop2:] == r1.final_position_m)
    assert np.all(tr2["v_m_s"][stop2:] == 0.0)


def test_flat_coast_stop_located_inside_a_stroke():
    """Event mode locates the stop inside an RK4 step (zero stroke of 10 ms, stop at 1.25 ms)."""
    s = sim(dt=1e-3 / 7, min_steps=2)  # steps do not line up with the stop
    a = s.flat_deceleration()
    v0 = 0.05
    r = s.simulate(Schedule.single(100.0, 0.0), X0, v0=v0, record=True)
    assert r.outcome == "rest"
    assert r.displacement_m == pytest.approx(v0 ** 2 / (2 * a), rel=REL)
    tr = r.trajectory
    stop = np.flatnonzero(tr["v_m_s"] == 0.0)[0]
    assert tr["t_s"][stop] == pytest.approx(v0 / a, rel=REL)
    assert np.all(tr["x_m"][stop:] == tr["x_m"][stop])


@pytest.mark.parametrize("mode", ["event", "karnopp"])
@pytest.mark.parametrize("kinematics", ["reduced", "exact"])
@pytest.mark.parametrize("shape", ["gaussian", "sinusoidal", "clamped_beam"])
def test_rest_on_still_surface_never_moves(mode, kinematics, shape):
    s = sim(mode=mode, kinematics=kinematics, shape=shape)
    sched = Schedule.sequence(ActuatorArray.uniform(3, 1e-3, 0.0), [950.0, 100.0, 3000.0], 0.0,
                              [0.0, 0.5, 2.0])
    r = s.simulate(sched, X0, record=True)
    assert r.outcome == "rest"
    assert r.final_position_m == X0 and r.final_velocity_m_s == 0.0
    assert np.all(r.trajectory["x_m"] == X0) and np.all(r.trajectory["v_m_s"] == 0.0)
    assert np.all(r.trajectory["stick"])


@pytest.mark.parametrize("shape", ["sinusoidal", "clamped_beam"])
def test_rest_outside_compact_bump_never_moves(shape):
    """A full stroke beyond the support |u| > WL/2 leaves the part's surface still: no motion."""
    r = sim(shape=shape).simulate(Schedule.single(F_REF, H, position=1e-3), 0.0)
    assert r.outcome == "rest" and r.final_position_m == 0.0 and r.final_velocity_m_s == 0.0


@pytest.mark.parametrize("slope", [1.0, -1.0, 100.0, -100.0])
def test_seed_part_sticks_at_any_tilt(slope):
    """Seed preset: adhesion makes Q(N) >= Q(0) ~ 8e-8 N ~ 4 m g0, so |N tan| = m g0 |sin| < Q at
    every tilt the simulator accepts (|tan| <= 100): the part never slides on a tilted carrier."""
    s = sim(slope=slope, max_time=0.05)
    N = s.mass * G0 / math.sqrt(1 + slope ** 2)
    assert abs(N * slope) < float(s.table.friction(N))
    for mode in ("event", "karnopp"):
        r = sim(slope=slope, max_time=0.05, mode=mode).simulate(
            Schedule.single(1000.0, 0.0, delay=0.01), X0)
        assert r.outcome == "rest" and r.final_position_m == X0


HEAVY_MASS = 2e-8  # kg: 10 x the seed part, so that a finite critical tilt exists


@functools.cache
def heavy_contact():
    from microconveyor_env.presets import load_preset

    return load_preset("feasibility").contact.replace(part__mass=HEAVY_MASS)


@functools.cache
def critical_slope():
    """tan(theta_c): |N tan| = Q(N) with N = m g0 cos(theta), from the simulator's own table."""
    s = sim(contact=heavy_contact())

    def margin(k):
        N = s.mass * G0 / math.sqrt(1 + k * k)
        return float(s.table.friction(N)) - N * k

    return brentq(margin, 0.0, 100.0, xtol=1e-15, rtol=1e-15)


@pytest.mark.parametrize("mode", ["event", "karnopp"])
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("factor", [0.999, 1.001, 1.05, 3.0])
@pytest.mark.parametrize("delay", [0.0, 0.02])
def test_tilt_threshold_and_constant_acceleration(mode, sign, factor, delay):
    """Constant tilt, no stroke: sticks for |N tan| <= Q(N); above, slides downhill with
    xddot = (F cos - N sin)/m, F = +-Q(N) against the motion, N = m g0 cos (closed form)."""
    kc = critical_slope()
    k = sign * factor * kc
    t_max = 0.05
    s = sim(contact=heavy_contact(), slope=k, max_time=t_max, mode=mode)
    x0 = 1e-3
    r = s.simulate(Schedule.single(1000.0, 0.0, delay=delay), x0)
    if factor < 1:
        assert r.outcome == "rest"
        assert r.final_position_m == x0 and r.final_velocity_m_s == 0.0
        return
    c = 1 / math.sqrt(1 + k * k)
    sn = k * c
    m = s.mass
    N = m * G0 * c
    Q = float(s.table.friction(N))
    a = (math.copysign(Q, k) * c - N * sn) / m  # downhill: v has the sign of -k, F the sign of k
    assert a * k < 0
    assert r.outcome == "max_time"
    assert r.end_time_s == pytest.approx(t_max, rel=1e-15)
    assert r.displacement_m == pytest.approx(0.5 * a * t_max ** 2, rel=REL)
    assert r.final_velocity_m_s == pytest.approx(a * t_max, rel=REL)


def test_max_time_is_honoured_inside_a_delay():
    """v0 = 1 m/s on the flat, a = 40 m/s^2 (stops at 25 ms), max_time = 10 ms, first delay 1 s:
    at max_time the part is still sliding at x = v0 t - a t^2/2 = 8 mm, v = 0.6 m/s."""
    s = sim(max_time=0.01)
    a = s.flat_deceleration()
    r = s.simulate(Schedule.single(1000.0, 0.0, delay=1.0), 0.0, v0=1.0)
    assert r.outcome == "max_time"
    assert r.end_time_s == pytest.approx(0.01, rel=1e-12)
    assert r.final_position_m == pytest.approx(0.01 - 0.5 * a * 0.01 ** 2, rel=REL)
    assert r.final_velocity_m_s == pytest.approx(1.0 - a * 0.01, rel=REL)


# ================================================ 2. independent re-derivation along trajectories
@pytest.mark.parametrize("kinematics", ["reduced", "exact"])
def test_recorded_normal_load_matches_physics(kinematics):
    """Recorded N equals m cos(theta)(g0 + Y_tt [+ 2 Y_xt v + Y_xx v^2]) from an independent
    implementation of the quintic stroke and the Gaussian bump; recorded Y too."""
    s = sim(kinematics=kinematics, dt=dt_for(F_REF, 400), min_steps=2)
    r = s.simulate(Schedule.single(F_REF, H), X0, record=True)
    tr = r.trajectory
    N_ref, _ = normal_load_ref(s.mass, tr["x_m"], tr["v_m_s"], tr["t_s"], F_REF, H,
                               kinematics == "exact")
    scale = s.mass * (G0 + 10 / math.sqrt(3) * H * (2 * F_REF) ** 2)
    np.testing.assert_allclose(tr["N_N"], N_ref, rtol=0, atol=1e-10 * scale)
    Y_ref = surface(tr["x_m"], tr["t_s"], F_REF, H)[0]
    np.testing.assert_allclose(tr["y_m"], Y_ref, rtol=0, atol=1e-12 * H)


def test_equation_of_motion_along_trajectory():
    """Between recorded slip points, dv = int (F cos - N sin)/m dt and dx = int v dt (trapezoid,
    with N, F from the record and theta from the independent surface); fine steps.

    The trapezoid rule itself errs by ~dt^3 a''/12 ~ 1e-6 of a_max dt here; a 1 % error in Q (or a
    missing cos(theta)) would show up 100-1000 times above the 1e-5 tolerance."""
    n = 4000
    s = sim(dt=dt_for(F_REF, n), min_steps=2)
    r = s.simulate(Schedule.single(F_REF, H), X0, record=True)
    tr = r.trajectory
    t, x, v, N, F = tr["t_s"], tr["x_m"], tr["v_m_s"], tr["N_N"], tr["F_N"]
    _, Yx, *_ = surface(x, t, F_REF, H)
    c = 1 / np.sqrt(1 + Yx ** 2)
    acc = (F * c - N * Yx * c) / s.mass
    T = 1 / F_REF
    pair = (~tr["stick"][:-1] & ~tr["stick"][1:] & (v[:-1] * v[1:] > 0)
            & (t[1:] <= T) & (np.diff(t) > 0))
    assert pair.sum() > 0.5 * n, "too few slip intervals to check"
    dt = np.diff(t)[pair]
    dv = np.diff(v)[pair]
    dv_trap = 0.5 * (acc[:-1] + acc[1:])[pair] * dt
    amax = np.abs(acc[:-1][pair]).max()
    assert np.max(np.abs(dv - dv_trap)) < 1e-5 * amax * T / n
    dx = np.diff(x)[pair]
    dx_trap = 0.5 * (v[:-1] + v[1:])[pair] * dt
    assert np.max(np.abs(dx - dx_trap)) < 1e-5 * np.abs(v).max() * T / n
    # friction opposes sliding: F v < 0 in every slip record
    slip = ~tr["stick"] & (v != 0)
    assert np.all(F[slip] * v[slip] < 0)


@pytest.mark.parametrize("freq", [300.0, F_REF, 1250.0])
def test_stick_condition_holds_while_stuck(freq):
    """Event mode: every recorded sticking state inside the stroke has |N tan(theta)| <= Q(N)."""
    s = sim(dt=dt_for(freq, 400), min_steps=2)
    r = s.simulate(Schedule.single(freq, H), X0, record=True)
    tr = r.trajectory
    st = tr["stick"]
    assert st.any()
    _, Yx, *_ = surface(tr["x_m"][st], tr["t_s"][st], freq, H)
    drive = np.abs(tr["N_N"][st] * Yx)
    Q = tr["Q_N"][st]
    assert np.all(drive <= Q * (1 + 1e-9) + 1e-12 * Q.max())
    assert np.all(tr["v_m_s"][st] == 0.0)


@pytest.mark.parametrize("mode", ["event", "karnopp"])
def test_friction_never_does_positive_work_on_still_flat_surface(mode):
    """Coast phases (delays and the final coast) of a multi-actuator run: |v| never increases,
    and while sliding it falls at exactly the flat deceleration."""
    s = sim(mode=mode)
    a = s.flat_deceleration()
    freqs, delays = [700.0, 900.0, 950.0], [0.0, 1e-3, 4e-3]
    sched = Schedule.sequence(ActuatorArray.uniform(3, 0.5e-3, -1.0e-3), freqs, 150e-6, delays)
    r = s.simulate(sched, -0.875e-3, record=True)
    assert r.outcome == "rest"
    tr = r.trajectory
    t, v = tr["t_s"], tr["v_m_s"]
    # still intervals: the delays and everything after the last stroke
    still, t_end = [], 0.0
    for f, d in zip(freqs, delays, strict=True):
        still.append((t_end, t_end + d))
        t_end += d + 1 / f
    still.append((t_end, math.inf))
    eps = 1e-12
    inside = np.zeros(len(t) - 1, bool)
    for lo, hi in still:
        inside |= (t[:-1] >= lo - eps) & (t[1:] <= hi + eps) & (np.diff(t) > 0)
    assert inside.sum() >= 3, "no coast phase exercised"
    speed = np.abs(v)
    assert np.all(speed[1:][inside] <= speed[:-1][inside])
    sliding = inside & (v[1:] != 0)
    assert sliding.any(), "the part never coasts while moving"
    np.testing.assert_allclose((speed[:-1] - speed[1:])[sliding], a * np.diff(t)[sliding], rtol=1e-9)
    # also inside zero-height strokes (RK4 / Karnopp): |v| never increases on a still surface
    r0 = s.simulate(Schedule.sequence(ActuatorArray.uniform(3, 1e-3), 950.0, 0.0, 0.0), 0.0,
                    v0=0.1, record=True)
    assert np.all(np.diff(np.abs(r0.trajectory["v_m_s"])) <= 0)


def test_recorded_coast_lies_on_the_parabola():
    """A recorded firing carries the closed-form coast after the stroke as many points on the
    parabola x = x_T + v_T tau - a tau^2 / 2 (a = Q(m g0) / m), up to the rest point; the chart
    of a firing shows the coast as it is, not as a straight line between two points."""
    s = sim()
    r = s.simulate(Schedule.single(F_REF, H), X0, record=True)
    tr = r.trajectory
    T = 1.0 / F_REF
    end = np.flatnonzero(np.isclose(tr["t_s"], T, rtol=0, atol=1e-15))[-1]
    x_T, v_T = tr["x_m"][end], tr["v_m_s"][end]
    after = tr["t_s"] > T
    assert after.sum() >= 30 and v_T != 0.0
    a = s.flat_deceleration() * np.sign(v_T)
    tau = tr["t_s"][after] - T
    np.testing.assert_allclose(tr["x_m"][after], x_T + v_T * tau - 0.5 * a * tau ** 2,
                               rtol=0, atol=1e-12)
    assert tr["t_s"][-1] == pytest.approx(r.rest_time_s, rel=1e-12)
    assert tr["x_m"][-1] == r.final_position_m and tr["v_m_s"][-1] == 0.0
    np.testing.assert_allclose(tr["F_N"][after][:-1], -np.sign(v_T) * s.flat_deceleration()
                               * s.mass, rtol=1e-9)
