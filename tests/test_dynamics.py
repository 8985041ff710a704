"""Physics checks of the stick-slip simulator (physics.md §3 and §5), through the public API.

Layout
------
1. closed forms on a still surface (flat coasting, rest, constant tilt: stick/slip threshold);
2. an independent re-derivation of the normal load, the equation of motion and the stick
   condition along recorded trajectories;
3. convergence in dt (event mode ~ RK4 order, Karnopp threshold much worse);
4. stability and input validation;
5. the dissertation's reported figures (§5) on the seed preset, and the exact-vs-seed kinematics.

Measured numbers are printed (``pytest -s`` shows them). Frequencies on a grid are exact
multiples of 25 Hz; "travel" is ``|final - x0|``.
"""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np
import pytest
from scipy.optimize import brentq

from microconveyor_env.physics.contact_table import TableRangeError
from microconveyor_env.physics.materials import G0, ParameterError
from microconveyor_env.physics.schedule import ActuatorArray, Schedule
from microconveyor_env.physics.simulator import Simulator, StepSizeWarning

WL = 0.6e-3           # m, seed wavelength
X0 = 0.125e-3         # m, seed start (from the actuator at 0)
H = 200e-6            # m, seed stroke
F_SEED = 950.0        # Hz, seed firing
OUTCOMES = {"rest", "detached", "max_time", "moving", "too_many_events"}
REL = 1e-9            # closed-form tolerance (relative)


# ----------------------------------------------------------------------------- helpers
@functools.lru_cache(maxsize=None)
def sim(**kw) -> Simulator:
    """Cached Simulator (the contact table and the kernel arrays are built once per setting)."""
    return Simulator(**kw)


def run(freq=F_SEED, h=H, x0=X0, **kw):
    return sim(**kw).simulate(Schedule.single(freq, h), x0)


def quiet(fn, *a, **kw):
    """Call ``fn`` with StepSizeWarning silenced (coarse rungs of a convergence ladder)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepSizeWarning)
        return fn(*a, **kw)


def dt_for(freq, n):
    """dt giving exactly ``n`` (even) RK4 steps per stroke with ``min_steps=2``."""
    return 1.0 / (freq * n)


GRID = np.arange(100.0, 2000.0 + 1, 25.0)  # Hz, 25 Hz grid


@functools.lru_cache(maxsize=None)
def sweep(shape="gaussian", h=H, kinematics="seed", x0=X0):
    """Travel [m] and detachment flag over GRID (single actuator at 0)."""
    s = sim(shape=shape, kinematics=kinematics)
    travel, detached = [], []
    for f in GRID:
        r = s.simulate(Schedule.single(float(f), h), x0)
        travel.append(abs(r.displacement_m))
        detached.append(r.outcome == "detached")
    return np.array(travel), np.array(detached)


def onset(detached):
    """Lowest detaching frequency on GRID."""
    assert detached.any(), "no detachment on the grid"
    return float(GRID[detached][0])


def usable_window(travel, detached, threshold=10e-6):
    """(lowest, highest) grid frequency that moves the part >= threshold without detaching."""
    ok = (travel >= threshold) & ~detached
    return float(GRID[ok][0]), float(GRID[ok][-1])


def assert_finite_result(r, label=""):
    d = r.to_dict()
    assert r.outcome in OUTCOMES, label
    for k, v in d.items():
        if k == "outcome":
            continue
        if k in ("rest_time_s", "detach_time_s", "detach_position_m") and v is None:
            continue
        assert v is not None and math.isfinite(v), f"{label}: {k} = {v!r}"
    assert (r.rest_time_s is not None) == (r.outcome == "rest"), label
    assert (r.detach_time_s is not None) == (r.outcome == "detached"), label
    assert (r.detach_position_m is not None) == (r.outcome == "detached"), label


# Independent surface kinematics (physics.md §1), plain numpy, NOT the package's kinematics module.
def quintic(t, freq, h):
    """(p, p_t, p_tt) of the rest-to-rest quintic stroke; 0 outside [0, T]."""
    t = np.asarray(t, float)
    T = 1.0 / freq
    half = T / 2
    up = t <= half
    tau = np.where(up, t / half, (T - t) / half)
    p = h * (10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5)
    pt = h * (30 * tau ** 2 - 60 * tau ** 3 + 30 * tau ** 4) / half * np.where(up, 1.0, -1.0)
    ptt = h * (60 * tau - 180 * tau ** 2 + 120 * tau ** 3) / half ** 2
    inside = (t >= 0) & (t <= T)
    return np.where(inside, p, 0.0), np.where(inside, pt, 0.0), np.where(inside, ptt, 0.0)


def gaussian(u, wl=WL):
    s = wl / 6
    g = np.exp(-u ** 2 / (2 * s ** 2))
    return g, -u / s ** 2 * g, (u ** 2 / s ** 2 - 1) / s ** 2 * g


def surface(x, t, freq, h, x_act=0.0):
    """(Y, Y_x, Y_tt, Y_xt, Y_xx) of a Gaussian bump fired once at t = 0."""
    p, pt, ptt = quintic(t, freq, h)
    g, gu, guu = gaussian(np.asarray(x, float) - x_act)
    return p * g, p * gu, ptt * g, pt * gu, p * guu


def normal_load_ref(m, x, v, t, freq, h, exact):
    """N = m cos(theta) (g0 + Y_tt [+ 2 Y_xt v + Y_xx v^2]) (physics.md §3)."""
    _, Yx, Ytt, Yxt, Yxx = surface(x, t, freq, h)
    acc = G0 + Ytt + ((2 * Yxt * v + Yxx * v * v) if exact else 0.0)
    return m * acc / np.sqrt(1 + Yx ** 2), Yx


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
@pytest.mark.parametrize("kinematics", ["seed", "exact"])
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
    r = sim(shape=shape).simulate(Schedule.single(F_SEED, H, position=1e-3), 0.0)
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


@functools.lru_cache(maxsize=None)
def heavy_contact():
    from microconveyor_env.presets import load_preset

    return load_preset("seed").contact.replace(part__mass=HEAVY_MASS)


@functools.lru_cache(maxsize=None)
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
@pytest.mark.parametrize("kinematics", ["seed", "exact"])
def test_recorded_normal_load_matches_physics(kinematics):
    """Recorded N equals m cos(theta)(g0 + Y_tt [+ 2 Y_xt v + Y_xx v^2]) from an independent
    implementation of the quintic stroke and the Gaussian bump; recorded Y too."""
    s = sim(kinematics=kinematics, dt=dt_for(F_SEED, 400), min_steps=2)
    r = s.simulate(Schedule.single(F_SEED, H), X0, record=True)
    tr = r.trajectory
    N_ref, _ = normal_load_ref(s.mass, tr["x_m"], tr["v_m_s"], tr["t_s"], F_SEED, H,
                               kinematics == "exact")
    scale = s.mass * (G0 + 10 / math.sqrt(3) * H * (2 * F_SEED) ** 2)
    np.testing.assert_allclose(tr["N_N"], N_ref, rtol=0, atol=1e-10 * scale)
    Y_ref = surface(tr["x_m"], tr["t_s"], F_SEED, H)[0]
    np.testing.assert_allclose(tr["y_m"], Y_ref, rtol=0, atol=1e-12 * H)


def test_equation_of_motion_along_trajectory():
    """Between recorded slip points, dv = int (F cos - N sin)/m dt and dx = int v dt (trapezoid,
    with N, F from the record and theta from the independent surface); fine steps.

    The trapezoid rule itself errs by ~dt^3 a''/12 ~ 1e-6 of a_max dt here; a 1 % error in Q (or a
    missing cos(theta)) would show up 100-1000 times above the 1e-5 tolerance."""
    n = 4000
    s = sim(dt=dt_for(F_SEED, n), min_steps=2)
    r = s.simulate(Schedule.single(F_SEED, H), X0, record=True)
    tr = r.trajectory
    t, x, v, N, F = tr["t_s"], tr["x_m"], tr["v_m_s"], tr["N_N"], tr["F_N"]
    _, Yx, *_ = surface(x, t, F_SEED, H)
    c = 1 / np.sqrt(1 + Yx ** 2)
    acc = (F * c - N * Yx * c) / s.mass
    T = 1 / F_SEED
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


@pytest.mark.parametrize("freq", [300.0, F_SEED, 1250.0])
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
    for f, d in zip(freqs, delays):
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


# ============================================================================ 3. convergence
LADDER = [16, 32, 64, 128, 256, 512, 1024]  # steps per stroke
REF_STEPS = 2 ** 16


def _final(mode, n, kinematics="seed"):
    s = sim(mode=mode, kinematics=kinematics, dt=dt_for(F_SEED, n), min_steps=2)
    r = quiet(s.simulate, Schedule.single(F_SEED, H), X0)
    assert r.steps == n or r.outcome != "rest"
    return r


def _order(ns, errs):
    """Least-squares p in err ~ C dt^p (dt ~ 1/n)."""
    return np.polyfit(np.log(1.0 / np.asarray(ns, float)), np.log(errs), 1)[0]


@functools.lru_cache(maxsize=None)
def convergence_study():
    ref = _final("event", REF_STEPS)
    ev = np.array([abs(_final("event", n).final_position_m - ref.final_position_m) for n in LADDER])
    ka = np.array([abs(_final("karnopp", n).final_position_m - ref.final_position_m)
                   for n in LADDER])
    ka_ref = _final("karnopp", REF_STEPS).final_position_m
    return ref, ev, ka, ka_ref


def test_convergence_event_mode_order():
    """Event mode keeps (nearly) RK4's order on the seed firing: fitted order >= 3."""
    ref, ev, _, _ = convergence_study()
    assert ref.outcome == "rest"
    order = _order(LADDER, ev)
    local = np.log2(ev[:-1] / ev[1:])
    print(f"\nevent mode: errors {ev}, local orders {np.round(local, 2)}, fitted order {order:.2f}")
    assert order >= 3.0
    assert ev[-1] < 1e-12  # 1024 steps/stroke: final position good to ~1e-9 relative


def test_convergence_karnopp_worse_than_event():
    """Karnopp threshold: fitted order printed (expected ~0.5-1, erratic); error larger than the
    event mode's at every dt; both converge to the same answer."""
    ref, ev, ka, ka_ref = convergence_study()
    order = _order(LADDER, ka)
    local = np.log2(ka[:-1] / ka[1:])
    print(f"\nkarnopp: errors {ka}, local orders {np.round(local, 2)}, fitted order {order:.2f}; "
          f"karnopp at {REF_STEPS} steps differs from the event reference by "
          f"{abs(ka_ref - ref.final_position_m):.2e} m")
    assert np.all(ka > ev)
    assert np.all(ka > 10 * ev)
    assert abs(ka_ref - ref.final_position_m) < 1e-7


@pytest.mark.parametrize("kinematics,freq,min_order", [("seed", 1300.0, 3.0), ("seed", 1500.0, 3.0),
                                                       ("exact", F_SEED, 1.2)])
def test_convergence_of_detachment_instant(kinematics, freq, min_order):
    """Event mode locates the detachment instant and place to ~1e-12 relative at 2048 steps.

    Seed kinematics: N depends on (x, t) only and the detachment time converges at ~RK4 order.
    Exact kinematics: N depends on xdot, and xdot converges slowly near pull-off because Q(N) has
    an infinite slope there (d(N) ~ sqrt(N + F_pull), physics.md §2), so the integrand is not
    smooth on the last steps: measured order ~1.6 (erratic), hence the lower bound 1.2.
    """
    def det(n):
        s = sim(kinematics=kinematics, dt=dt_for(freq, n), min_steps=2)
        r = quiet(s.simulate, Schedule.single(freq, H), X0)
        assert r.outcome == "detached"
        return r.detach_time_s, r.detach_position_m

    ref = det(2 ** 17)
    ns = [64, 128, 256, 512, 1024, 2048]
    et = np.array([abs(det(n)[0] - ref[0]) for n in ns])
    ex = np.array([abs(det(n)[1] - ref[1]) for n in ns])
    order = _order(ns, et + 1e-300)
    print(f"\n{kinematics} {freq:g} Hz detachment at {ref[0] * 1e3:.4f} ms: time errors {et}, "
          f"position errors {ex}, fitted order (time) {order:.2f}")
    assert et[-1] < 1e-9 / freq and ex[-1] < 1e-9 * WL
    assert order >= min_order


def test_convergence_study_across_frequencies_and_shapes():
    """Event-mode order of the final position / detachment place, 300-1250 Hz, three shapes, both
    kinematics (printed table). Asserted: order >= 3 for the smooth Gaussian and the sinusoid in
    seed kinematics when the part comes to rest. The sinusoid and the clamped beam have a
    curvature jump at |u| = WL/2 (and the beam a third-derivative jump at u = 0) that the
    integrator does not locate, so their order is only printed in the other cases (measured
    ~2-3.5; the exact kinematics of the beam, whose N then jumps, ~2.7 with 1e-11 m errors)."""
    ns = [16, 32, 64, 128, 256, 512, 1024]
    rows = []
    for shape in ("gaussian", "sinusoidal", "clamped_beam"):
        for kin in ("seed", "exact"):
            for f in (300.0, 500.0, 700.0, 950.0, 1250.0):
                def fin(n):
                    s = sim(shape=shape, kinematics=kin, dt=dt_for(f, n), min_steps=2)
                    r = quiet(s.simulate, Schedule.single(f, H), X0)
                    return r.final_position_m, r.outcome

                ref, outcome = fin(2 ** 16)
                e = np.array([abs(fin(n)[0] - ref) for n in ns]) + 1e-300
                order = _order(ns, e)
                rows.append((shape, kin, f, outcome, order, e[-1]))
                if shape != "clamped_beam" and kin == "seed" and outcome == "rest":
                    assert order >= 3.0, (shape, kin, f, order)
    print()
    for shape, kin, f, outcome, order, e in rows:
        print(f"{shape:>12} {kin:>5} {f:6.0f} Hz {outcome:>8}: order {order:5.2f}, "
              f"error at 1024 steps {e:.1e} m")


# ============================================================================ 4. stability
def test_coarse_step_warns_and_stays_finite():
    s = sim(dt=1e-4, min_steps=2)  # 950 Hz: T/dt = 10.5 -> 12 steps < 20
    assert s.steps_per_stroke(F_SEED) < 20
    with pytest.warns(StepSizeWarning, match="dt"):
        r = s.simulate(Schedule.single(F_SEED, H), X0)
    assert_finite_result(r, "coarse")
    with pytest.warns(StepSizeWarning):
        r = sim(dt=5e-4, min_steps=2).simulate(Schedule.single(1500.0, H), X0)  # 2 steps
    assert_finite_result(r, "2 steps")


def test_default_min_steps_never_warns():
    with warnings.catch_warnings():
        warnings.simplefilter("error", StepSizeWarning)
        r = sim(dt=1e-3).simulate(Schedule.single(3000.0, H), X0)
    assert sim(dt=1e-3).steps_per_stroke(3000.0) == 20
    assert_finite_result(r, "3000 Hz, dt = 1 ms")


@pytest.mark.parametrize("mode", ["event", "karnopp"])
@pytest.mark.parametrize("freq", [1400.0, 1600.0, 2000.0, 3000.0])
@pytest.mark.parametrize("delay", [0.0, 2e-3])
def test_detachment_beyond_onset(mode, freq, delay):
    s = sim(mode=mode)
    r = s.simulate(Schedule.single(freq, H, delay=delay), X0)
    assert r.outcome == "detached"
    assert_finite_result(r, "detached")
    T = 1 / freq
    assert delay < r.detach_time_s <= delay + T
    assert r.end_time_s == r.detach_time_s
    assert r.detach_position_m == r.final_position_m
    assert abs(r.detach_position_m - X0) < WL / 2
    # the load at the detachment point (independent formula) is at / beyond pull-off
    N, _ = normal_load_ref(s.mass, r.detach_position_m, r.final_velocity_m_s,
                           r.detach_time_s - delay, freq, H, False)
    F_pull = s.table.pull_off_force
    if mode == "event":
        assert N == pytest.approx(-F_pull, rel=1e-7)
    else:  # Karnopp checks at step starts only: the load is already below -F_pull
        assert N < -F_pull


def test_detachment_in_exact_kinematics_is_genuine():
    """Exact kinematics at 950 Hz detaches (see test_exact_vs_seed_kinematics): at the reported
    point the full normal load, velocity terms included, is exactly -F_pull."""
    s = sim(kinematics="exact")
    r = s.simulate(Schedule.single(F_SEED, H), X0)
    assert r.outcome == "detached"
    N, _ = normal_load_ref(s.mass, r.detach_position_m, r.final_velocity_m_s, r.detach_time_s,
                           F_SEED, H, True)
    assert N == pytest.approx(-s.table.pull_off_force, rel=1e-7)


NAN = float("nan")


@pytest.mark.parametrize("build,match", [
    (lambda: Schedule.single(0.0, H), r"frequency = 0\.0 is invalid"),
    (lambda: Schedule.single(-950.0, H), r"frequency = -950\.0 is invalid"),
    (lambda: Schedule.single(NAN, H), r"frequency = nan is invalid.*finite"),
    (lambda: Schedule.single(math.inf, H), r"frequency = inf is invalid"),
    (lambda: Schedule.single(F_SEED, -1e-6), r"stroke = -1e-06 is invalid"),
    (lambda: Schedule.single(F_SEED, NAN), r"stroke = nan is invalid"),
    (lambda: Schedule.single(F_SEED, H, delay=-1e-3), r"delay = -0\.001 is invalid"),
    (lambda: Schedule.single(F_SEED, H, delay=NAN), r"delay = nan is invalid"),
    (lambda: Schedule.sequence(ActuatorArray.uniform(2, 1e-3), F_SEED, H, [0.0, -1.0]),
     r"delay = -1\.0 is invalid"),
    (lambda: ActuatorArray.uniform(2, -1e-3), r"spacing = -0\.001 is invalid"),
    (lambda: sim().simulate(Schedule.single(F_SEED, H), NAN), r"x0 = nan is invalid"),
    (lambda: sim().simulate(Schedule.single(F_SEED, H), math.inf), r"x0 = inf is invalid"),
    (lambda: sim().simulate(Schedule.single(F_SEED, H), X0, v0=NAN), r"v0 = nan is invalid"),
    (lambda: sim().simulate("950 Hz", X0), r"schedule must be a Schedule"),
    (lambda: Simulator(dt=0.0), r"dt = 0\.0 is invalid"),
    (lambda: Simulator(dt=-2e-5), r"dt = -2e-05 is invalid"),
    (lambda: Simulator(dt=NAN), r"dt = nan is invalid"),
    (lambda: Simulator(wavelength=0.0), r"wavelength = 0\.0 is invalid"),
    (lambda: Simulator(min_steps=1), r"min_steps = 1 is invalid"),
    (lambda: Simulator(max_time=0.0), r"max_time = 0\.0 is invalid"),
    (lambda: Simulator(slope=NAN), r"slope = nan is invalid"),
    (lambda: Simulator(shape="square"), r"shape = 'square' is invalid.*gaussian"),
    (lambda: Simulator(mode="rk45"), r"mode = 'rk45' is invalid.*event.*karnopp"),
    (lambda: Simulator(kinematics="approx"), r"kinematics = 'approx' is invalid.*seed.*exact"),
])
def test_bad_inputs_raise_parameter_error(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


def test_stroke_beyond_contact_table_raises():
    with pytest.raises(TableRangeError, match="beyond the contact table"):
        sim().simulate(Schedule.single(1e5, 1e-2), X0)


@pytest.mark.parametrize("mode", ["event", "karnopp"])
@pytest.mark.parametrize("kinematics", ["seed", "exact"])
def test_no_nan_over_frequency_sweep(mode, kinematics):
    s = sim(mode=mode, kinematics=kinematics)
    outcomes = {}
    for f in np.arange(100.0, 3000.0 + 1, 50.0):
        r = s.simulate(Schedule.single(float(f), H), X0)
        assert_finite_result(r, f"{mode}/{kinematics} {f} Hz")
        assert r.outcome in ("rest", "detached"), (f, r.outcome)
        outcomes[r.outcome] = outcomes.get(r.outcome, 0) + 1
    assert outcomes.get("rest", 0) > 0 and outcomes.get("detached", 0) > 0


# ============================================================================ 5. seed figures
def test_seed_travel_at_950_hz():
    """§5: ~1250 um at 950 Hz, towards and past the actuator (uphill first)."""
    r = run()
    print(f"\nseed 950 Hz / 200 um: travel {abs(r.displacement_m) * 1e6:.1f} um, "
          f"final x {r.final_position_m * 1e6:.1f} um, rest at {r.rest_time_s * 1e3:.3f} ms")
    assert r.outcome == "rest"
    assert 0.9e-3 <= abs(r.displacement_m) <= 1.6e-3
    assert r.final_position_m < 0.0  # past the actuator at x = 0 (started at +0.125 mm)
    # same in Karnopp mode at the default step, within its (first-order) error
    rk = run(mode="karnopp")
    assert rk.final_position_m == pytest.approx(r.final_position_m, rel=1e-1)


def test_seed_detachment_onset():
    """§5: detachment above ~1300 Hz; on the 25 Hz grid the onset lies in [1150, 1450] Hz and
    every higher grid frequency (to 2000 Hz) detaches as well."""
    travel, det = sweep()
    f_on = onset(det)
    print(f"\nseed Gaussian 200 um: detachment onset {f_on:g} Hz")
    assert 1150 <= f_on <= 1450
    assert np.all(det[GRID >= f_on]) and not np.any(det[GRID < f_on])


def test_seed_low_frequency_motion():
    """§5: 'below ~300 Hz essentially no motion (< 10 um)'. Measured: ~83 um at 300 Hz (brief's
    bound < 150 um) and < 10 um only at 200 Hz and below; travel grows monotonically with f."""
    travel, det = sweep()
    t300 = travel[GRID == 300][0]
    print(f"\nseed travel: 200 Hz {travel[GRID == 200][0] * 1e6:.1f} um, 300 Hz {t300 * 1e6:.1f} um")
    assert t300 < 150e-6
    assert np.all(travel[GRID <= 200] < 10e-6)
    ok = ~det
    assert np.all(np.diff(travel[ok]) >= 0)


@pytest.mark.parametrize("freq", [500.0, 700.0, 950.0])
def test_larger_stroke_travels_further(freq):
    small, big = run(freq=freq, h=150e-6), run(freq=freq, h=200e-6)
    print(f"\n{freq:g} Hz: 150 um -> {abs(small.displacement_m) * 1e6:.0f} um, "
          f"200 um -> {abs(big.displacement_m) * 1e6:.0f} um")
    assert small.outcome == big.outcome == "rest"
    assert abs(big.displacement_m) > abs(small.displacement_m)


def test_sinusoidal_vs_gaussian():
    """§5: sinusoidal shapes travel further, at lower frequencies, over a narrower window.

    Measured on the seed preset (200 um, WL 0.6 mm, x0 0.125 mm; usable = travel >= 10 um and no
    detachment): Gaussian 225-1275 Hz (onset 1300), sinusoidal 200-1025 Hz (onset 1050); the
    sinusoid travels further at every usable frequency, and its best travel is larger.
    All three reported trends hold in this model (seed kinematics).
    """
    tg, dg = sweep("gaussian")
    ts, ds = sweep("sinusoidal")
    lo_g, hi_g = usable_window(tg, dg)
    lo_s, hi_s = usable_window(ts, ds)
    on_g, on_s = onset(dg), onset(ds)
    both = ~dg & ~ds & (GRID >= min(lo_g, lo_s))
    print(f"\nGaussian window {lo_g:g}-{hi_g:g} Hz (onset {on_g:g}, best "
          f"{tg[~dg].max() * 1e6:.0f} um); sinusoidal {lo_s:g}-{hi_s:g} Hz (onset {on_s:g}, best "
          f"{ts[~ds].max() * 1e6:.0f} um); at 300 Hz G {tg[GRID == 300][0] * 1e6:.0f} um, "
          f"S {ts[GRID == 300][0] * 1e6:.0f} um")
    assert np.all(ts[both] > tg[both])          # further at every frequency both can use
    assert ts[~ds].max() > tg[~dg].max()       # further at best
    assert on_s < on_g and hi_s < hi_g          # detaches at lower frequencies
    assert lo_s <= lo_g                         # starts moving no later
    assert hi_s - lo_s < hi_g - lo_g            # narrower usable window


def test_best_start_position():
    """§5: 'largest travel for a start a little under WL/4'. Measured at 950 Hz / 200 um on a
    5 um grid: the best non-detaching start is ~0.085 mm (~WL/7), right above the starts that
    detach (<= 0.08 mm); documented, not the dissertation's value exactly."""
    xs = np.arange(0.05, 0.30001, 0.005) * 1e-3
    res = [run(x0=float(x)) for x in xs]
    ok = np.array([r.outcome != "detached" for r in res])
    travel = np.array([abs(r.displacement_m) for r in res])
    best = xs[ok][np.argmax(travel[ok])]
    print(f"\nbest start {best * 1e3:.3f} mm (WL/4 = {WL / 4 * 1e3:.3f} mm), "
          f"travel {travel[ok].max() * 1e6:.0f} um")
    assert WL / 12 < best < WL / 4


# ======================================================================== exact vs seed kinematics
def test_exact_vs_seed_kinematics():
    """Both kinematics levels run at the seed firing. Measured: the seed level (velocity terms
    dropped) travels ~1164 um and comes to rest; the exact level detaches after ~36 um, ~0.68 ms
    into the stroke -- on the downstroke, 2 Y_xt xdot and Y_xx xdot^2 (each ~1e3 m/s^2 at xdot
    ~ 0.3 m/s) pull the load below -F_pull. Exact kinematics moves the detachment onset from
    1300 Hz down to ~725 Hz (h = 200 um, Gaussian)."""
    seed, exact = run(kinematics="seed"), run(kinematics="exact")
    assert_finite_result(seed, "seed")
    assert_finite_result(exact, "exact")
    diff = abs(seed.displacement_m) - abs(exact.displacement_m)
    _, det_exact = sweep(kinematics="exact")
    print(f"\n950 Hz: seed {seed.displacement_m * 1e6:.1f} um ({seed.outcome}), exact "
          f"{exact.displacement_m * 1e6:.1f} um ({exact.outcome}"
          f"{'' if exact.detach_time_s is None else f' at {exact.detach_time_s * 1e3:.3f} ms'}); "
          f"difference in travel {diff * 1e6:.1f} um; exact onset {onset(det_exact):g} Hz")
    assert seed.outcome == "rest"
    # documented measurement (not a dissertation figure): the velocity terms matter at 950 Hz
    assert exact.outcome == "detached" and abs(exact.displacement_m) < 100e-6
    # at low frequency, where the part barely moves, both levels agree
    lo_s, lo_e = run(freq=150.0, kinematics="seed"), run(freq=150.0, kinematics="exact")
    assert abs(lo_s.displacement_m - lo_e.displacement_m) < 1e-6
