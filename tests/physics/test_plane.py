"""The plane (docs/physics.md §10), validated the way a physicist would: a scene on one line is
the 1-D scene, a rotated scene gives the rotated result, a resting part on the still surface stays,
a sliding one stops after v^2/(2a) on a straight line, the same inputs give the same bits.

Helpers: ``tests/support/plane.py``. Measured numbers are printed (``pytest -s``).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numba import njit

from microconveyor_env.physics import dynamics_kernel as k1
from microconveyor_env.physics.plane import kernel as k2
from microconveyor_env.physics.kinematics import SHAPES, surface_eval
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.physics.plane.simulator import ActuatorGrid, PlaneSchedule
from microconveyor_env.physics.plane.kinematics import plane_surface_eval, plane_surface_height
from microconveyor_env.physics.schedule import ActuatorArray, Firing, Schedule

from support import DATA as DATA_DIR
from support.dynamics import F_REF, H, X0, sim
from support.plane import distance, plane_sim, rotate, scene

REL = 1e-9  # the bar for the 1-D reduction (relative final position)


# ============================================================================ surface
@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_surface_on_the_line_is_the_1d_surface(shape):
    """On y = y_a the radial bump and its derivatives are the 1-D ones, bit for bit, and every
    y-derivative that enters the dynamics there is zero."""
    kind = SHAPES[shape]
    for x in np.linspace(-0.5e-3, 0.5e-3, 41):
        for t in (0.0, 2.1e-4, 5.3e-4, 1e-3):
            Y, Yx, Yt, Ytt, Yxt, Yxx = surface_eval(x, t, 1e-4, 950.0, 2e-4, kind, 0.6e-3)
            Z, Zx, Zy, Ztt, Zxt, Zyt, Zxx, Zxy, Zyy = plane_surface_eval(
                x, 0.3e-3, t, 1e-4, 0.3e-3, 950.0, 2e-4, kind, 0.6e-3)
            assert (Z, Zx, Ztt, Zxt, Zxx) == (Y, Yx, Ytt, Yxt, Yxx)
            assert Zy == Zyt == Zxy == 0.0


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_surface_derivatives_match_finite_differences(shape):
    """Gradient, Hessian and time derivatives against central differences at off-axis points, and
    the centre: finite, isotropic Hessian (g'(r)/r -> g''(0))."""
    kind, f, h, wl, xa, ya = SHAPES[shape], 800.0, 1.5e-4, 0.6e-3, 0.1e-3, -0.05e-3

    def ev(x, y, t):
        return np.array(plane_surface_eval(x, y, t, xa, ya, f, h, kind, wl))

    e, et = 1e-8, 1e-8
    for x, y, t in ((0.2e-3, 0.03e-3, 3e-4), (0.0, -0.2e-3, 6.1e-4), (0.12e-3, 0.1e-3, 2e-4)):
        Z, Zx, Zy, Ztt, Zxt, Zyt, Zxx, Zxy, Zyy = ev(x, y, t)
        dx = (ev(x + e, y, t) - ev(x - e, y, t)) / (2 * e)
        dy = (ev(x, y + e, t) - ev(x, y - e, t)) / (2 * e)
        dt = (ev(x, y, t + et) - ev(x, y, t - et)) / (2 * et)
        scale = max(abs(Zxx), abs(Zyy), abs(Zxy))
        assert dx[0] == pytest.approx(Zx, rel=1e-6, abs=1e-9)
        assert dy[0] == pytest.approx(Zy, rel=1e-6, abs=1e-9)
        assert dx[1] == pytest.approx(Zxx, rel=1e-5, abs=1e-6 * scale)
        assert dy[1] == pytest.approx(Zxy, rel=1e-5, abs=1e-6 * scale)
        assert dy[2] == pytest.approx(Zyy, rel=1e-5, abs=1e-6 * scale)
        assert dt[1] == pytest.approx(Zxt, rel=1e-5, abs=1e-6 * abs(Zxt) + 1e-12)
        assert dt[2] == pytest.approx(Zyt, rel=1e-5, abs=1e-6 * abs(Zyt) + 1e-12)
    c = ev(xa, ya, 4e-4)
    assert np.all(np.isfinite(c)) and c[1] == c[2] == c[7] == 0.0 and c[6] == c[8] != 0.0
    near = ev(xa + 1e-11, ya, 4e-4)
    assert near[6] == pytest.approx(c[6], rel=1e-6) and near[8] == pytest.approx(c[8], rel=1e-6)
    r = np.hypot(0.2e-3 - xa, 0.03e-3 - ya)
    assert plane_surface_height(0.2e-3, 0.03e-3, h, shape, wl, xa, ya) == pytest.approx(
        ev(0.2e-3, 0.03e-3, 0.5 / f)[0], rel=1e-12)
    assert plane_surface_height(0.0, r, h, kind, wl) == pytest.approx(
        ev(0.2e-3, 0.03e-3, 0.5 / f)[0], rel=1e-12)


# ============================================================================ 1-D reduction
def _line_vs_plane(kw, schedule1, grid, firings, x0, y_line=0.0):
    r1 = sim(**kw).simulate(schedule1, x0)
    r2 = plane_sim(**{k: v for k, v in kw.items() if k != "mode"}).simulate(
        PlaneSchedule(grid, firings), x0, y_line)
    return r1, r2


@pytest.mark.parametrize("kw,freq", [({}, F_REF), ({"kinematics": "exact"}, 700.0),
                                     ({"shape": "sinusoidal"}, 600.0),
                                     ({"shape": "clamped_beam"}, 800.0), ({}, 1300.0)])
def test_one_line_reproduces_the_1d_reference_firing(kw, freq):
    """The reference firing (and other shapes, exact kinematics, a detachment) with the part and
    the bump on one line: the 1-D simulator's final position to 1e-9 relative, same outcome."""
    r1, r2 = _line_vs_plane(kw, Schedule.single(freq, H), ActuatorGrid(((0.0, 0.0),)),
                            (Firing(0, freq, H),), X0)
    assert r2.outcome == r1.outcome
    err = abs(r2.final_position_m[0] - r1.final_position_m) / abs(r1.final_position_m)
    print(f"\n{kw or 'reference'} {freq:g} Hz: 1-D {r1.final_position_m:.9e} m, plane "
          f"{r2.final_position_m[0]:.9e} m, relative difference {err:.1e} ({r1.outcome})")
    assert err <= REL and r2.final_position_m[1] == 0.0
    assert r2.events == r1.events and r2.steps == r1.steps
    if r1.outcome == "detached":
        assert r2.detach_time_s == pytest.approx(r1.detach_time_s, rel=REL)


def _v0_episodes():
    data = json.loads((DATA_DIR / "episodes.json").read_text())["episodes"]
    return [(e["category"], e["frequency_hz"], e["stroke_m"], e["delay_s"]) for e in data]


@pytest.mark.parametrize("angle", [0.0, 0.5236])
def test_one_line_reproduces_the_stored_episodes(angle):
    """The stored MicroConveyor-v0 episodes (tests/data/episodes.json: far throws, near
    detachments, high-speed engagements), fired through the 1-D simulator on v0's scene (five
    actuators 0.5 mm apart, the part 0.15 mm before the first, dt 1e-4 s, 48 steps per stroke) and
    through the plane with those actuators as the middle row of a 5 x 3 grid; ``angle`` [rad]
    turns the whole plane scene. Same outcomes, final positions to 1e-9 relative."""
    kw = {"dt": 1e-4, "min_steps": 48, "max_time": 1.0}
    line = sim(**kw)
    plane = plane_sim(**kw)
    xs = [0.5e-3 * i for i in range(5)]
    pts = [(x, y) for y in (-0.5e-3, 0.0, 0.5e-3) for x in xs]
    grid = ActuatorGrid(tuple(tuple(rotate(p, angle)) for p in pts))
    start = rotate((-0.15e-3, 0.0), angle)
    worst = 0.0
    for cat, f, h, d in _v0_episodes():
        r1 = line.simulate(Schedule(ActuatorArray(tuple(xs)),
                                    tuple(Firing(i, f[i], h[i], d[i]) for i in range(5))), -0.15e-3)
        r2 = plane.simulate(PlaneSchedule(grid, tuple(Firing(5 + i, f[i], h[i], d[i])
                                                      for i in range(5))), *start)
        assert r2.outcome == r1.outcome, cat
        along = rotate(r2.final_position_m, -angle)
        x1 = r1.final_position_m
        err = abs(along[0] - x1) / max(abs(x1), 1e-3)
        worst = max(worst, err)
        assert err <= REL, (cat, along[0], x1)
        assert abs(along[1]) <= 1e-15, cat
    print(f"\nstored episodes, line at {angle:g} rad: largest relative difference {worst:.1e}")


# ============================================================================ invariances
@pytest.mark.parametrize("name", ["pass_by", "relay", "oblique_stop"])
def test_rotating_the_scene_rotates_the_result(name):
    """Turning the whole scene (actuators, part position and velocity) by an angle turns the
    result: final positions agree to round-off (1e-15 m on millimetre paths), same outcome and
    events, for several angles including a shift of the origin."""
    sched, start = scene(name)
    base = plane_sim().simulate(sched, *start)
    worst = 0.0
    for angle, shift in ((0.3, (0.0, 0.0)), (math.pi / 2, (0.0, 0.0)), (2.0, (0.0, 0.0)),
                         (-1.1, (0.7e-3, -0.4e-3))):
        s2, st2 = scene(name, angle, shift)
        r = plane_sim().simulate(s2, *st2)
        assert r.outcome == base.outcome and r.events == base.events
        back = rotate(np.subtract(r.final_position_m, shift), -angle)
        worst = max(worst, distance(back, base.final_position_m))
    print(f"\n{name}: {base.outcome}, {base.events} events, travel "
          f"{base.displacement_m * 1e6:.1f} um; largest rotation difference {worst:.1e} m")
    assert worst <= 1e-15


def test_a_resting_part_on_the_still_surface_stays_put():
    """No stroke (h = 0) after delays, at several places: the part stays, bit for bit, at rest."""
    grid = ActuatorGrid(((0.0, 0.0), (0.5e-3, 0.2e-3)))
    for x, y in ((0.1e-3, 0.2e-3), (0.0, 0.0), (-0.3e-3, 0.45e-3)):
        r = plane_sim().simulate(PlaneSchedule(grid, (Firing(0, 900.0, 0.0, 0.01),
                                                      Firing(1, 300.0, 0.0, 0.002))), x, y)
        assert r.outcome == "rest" and r.final_position_m == (x, y)
        assert r.final_velocity_m_s == (0.0, 0.0) and r.events == 0
    out = k2.coast(0.1e-3, 0.2e-3, 0.0, 0.0, math.inf, plane_sim().params, *plane_sim().tables)
    assert out == (0.1e-3, 0.2e-3, 0.0, 0.0, 0.0, True, 0.0)


@pytest.mark.parametrize("speed,heading", [(0.05, 0.4), (0.2, 2.5), (0.01, -1.9)])
def test_a_sliding_part_on_the_flat_stops_after_v2_over_2a_on_a_line(speed, heading):
    """On the still, level surface a part launched at ``speed`` [m/s] stops after v^2/(2a),
    a = Q(m g0)/m, on the straight line of its velocity: in closed form (coast) and integrated
    (a stroke of zero height, the stop located by the event search), to 1e-12 relative."""
    s = plane_sim()
    a = s.flat_deceleration()
    vx, vy = speed * math.cos(heading), speed * math.sin(heading)
    x0, y0 = 0.2e-3, -0.1e-3
    want = speed ** 2 / (2 * a)
    grid = ActuatorGrid(((0.0, 0.0),))
    coast_r = s.simulate(PlaneSchedule(grid, (Firing(0, 1e3, 0.0, 1.0),)), x0, y0, vx, vy)
    stroke_r = s.simulate(PlaneSchedule(grid, (Firing(0, 1.0, 0.0),)), x0, y0, vx, vy,
                          record=True)
    assert stroke_r.events == 1 and stroke_r.outcome == coast_r.outcome == "rest"
    for r in (coast_r, stroke_r):
        dx, dy = np.subtract(r.final_position_m, (x0, y0))
        along = dx * math.cos(heading) + dy * math.sin(heading)
        across = -dx * math.sin(heading) + dy * math.cos(heading)
        print(f"\n{speed} m/s: distance {along * 1e6:.4f} um (v^2/2a {want * 1e6:.4f} um), "
              f"off the line {across:.1e} m")
        assert along == pytest.approx(want, rel=1e-12) and abs(across) <= 1e-12 * want
    tr = stroke_r.trajectory
    across = (-(tr["x_m"] - x0) * math.sin(heading) + (tr["y_m"] - y0) * math.cos(heading))
    assert np.abs(across).max() <= 1e-12 * want
    assert stroke_r.rest_time_s == pytest.approx(1.0, rel=1e-12)  # the stroke lasts 1/f


# ============================================================================ determinism
def _scene_arrays(name):
    sched, start = scene(name)
    return sched.arrays(), start


@njit(cache=True)
def _fire_batch(xa, ya, f, h, d, starts, dt, min_steps, t_max, P, tu, tq, tqu, rec, out, res):
    """A per-part loop over a batch, as a batched env would call the kernel."""
    for i in range(starts.shape[0]):
        x, y, vx, vy, t = starts[i, 0], starts[i, 1], starts[i, 2], starts[i, 3], 0.0
        k2.reset_out(out[i])
        outcome = k2.MOVING
        for k in range(xa.shape[0]):
            x, y, vx, vy, t, outcome = k2.fire(x, y, vx, vy, t, xa[k], ya[k], f[k], h[k], d[k], dt,
                                               min_steps, k == xa.shape[0] - 1, t_max, P, tu, tq,
                                               tqu, rec, out[i])
            if outcome != k2.MOVING:
                break
        res[i, 0], res[i, 1], res[i, 2], res[i, 3], res[i, 4], res[i, 5] = x, y, vx, vy, t, outcome


def test_same_inputs_same_bits_single_and_batched():
    """Repeated runs are bit-identical, and a compiled per-part loop over a batch of starts calling
    ``plane_kernel.fire`` gives exactly the simulator's results (single = batched)."""
    s = plane_sim()
    (xa, ya, f, h, d), start = _scene_arrays("relay")
    runs = [s.simulate(scene("relay")[0], *start, record=True) for _ in range(3)]
    for r in runs[1:]:
        assert r.final_position_m == runs[0].final_position_m and r.events == runs[0].events
        for key, col in r.trajectory.items():
            assert np.array_equal(col, runs[0].trajectory[key]), key
    rng = np.random.default_rng(0)
    starts = np.column_stack([rng.uniform(-0.2e-3, 0.6e-3, 16), rng.uniform(-0.2e-3, 0.5e-3, 16),
                              rng.normal(0, 0.05, 16), rng.normal(0, 0.05, 16)])
    res = np.zeros((16, 6))
    out = np.zeros((16, k2.N_OUT))
    _fire_batch(xa, ya, f, h, d, starts, s.dt, s.min_steps, s.max_time, s.params, *s.tables,
                np.zeros((0, k2.N_REC)), out, res)
    sched = scene("relay")[0]
    for i in range(16):
        r = s.simulate(sched, *starts[i])
        assert (res[i, 0], res[i, 1]) == r.final_position_m
        assert (res[i, 2], res[i, 3]) == r.final_velocity_m_s
        assert k1.OUTCOMES[int(res[i, 5])] == r.outcome and res[i, 4] == r.end_time_s


# ============================================================================ inputs
@pytest.mark.parametrize("build,match", [
    (lambda: ActuatorGrid(()), "empty"),
    (lambda: ActuatorGrid(((0.0, 0.0), (0.0, 0.0))), "same place"),
    (lambda: ActuatorGrid(((0.0,),)), r"an \(x, y\) pair"),
    (lambda: ActuatorGrid(((0.0, "1"),)), r"positions\[0\]\[1\]"),
    (lambda: ActuatorGrid.regular(0, 3, 1e-3), "nx"),
    (lambda: ActuatorGrid.regular(2, 2, -1e-3), "spacing"),
    (lambda: PlaneSchedule(ActuatorGrid(((0.0, 0.0),)), (Firing(1, 900.0, 1e-4),)),
     "the grid has 1 actuators"),
    (lambda: PlaneSchedule((0.0, 0.0), ()), "must be an ActuatorGrid"),
    (lambda: plane_sim().simulate(Schedule.single(900.0, 1e-4), 0.0, 0.0), "PlaneSchedule"),
    (lambda: plane_sim().simulate(PlaneSchedule(ActuatorGrid(((0.0, 0.0),)), ()), 0.0, 2.0),
     r"y0 = 2\.0 is invalid"),
    (lambda: plane_sim().simulate(PlaneSchedule(ActuatorGrid(((0.0, 0.0),)), ()), 0.0, 0.0,
                                  vx0=math.nan), "vx0"),
    (lambda: plane_sim(dt=-1.0), r"dt = -1\.0 is invalid"),
    (lambda: plane_sim(shape="square"), "shape"),
])
def test_bad_inputs_raise_parameter_error(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


def test_firing_checks_are_the_lines():
    """The plane refuses what the line refuses (loads beyond the table, step budgets) and counts
    the same steps per stroke."""
    from microconveyor_env.physics.contact_table import TableRangeError

    with pytest.raises(TableRangeError, match="beyond the contact table"):
        plane_sim().check_firings(np.array([2e5]), np.array([1e-2]))
    with pytest.raises(ParameterError, match="max_steps"):
        plane_sim(max_steps=10).simulate(
            PlaneSchedule(ActuatorGrid(((0.0, 0.0),)), (Firing(0, 10.0, 1e-4),)), 0.0, 0.0)
    assert plane_sim().steps_per_stroke(950.0) == sim().steps_per_stroke(950.0) == 22


def test_regular_grid_indexing():
    g = ActuatorGrid.regular(5, 3, 0.5e-3, origin=(1e-3, -1e-3))
    assert len(g) == 15 and g.positions[0] == (1e-3, -1e-3)
    assert g.positions[2 + 5 * 1] == pytest.approx((2e-3, -0.5e-3))
