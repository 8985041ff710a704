"""Convergence in dt: event mode keeps RK4's order, the Karnopp threshold does not
(docs/physics.md §3.6-3.7).

Helpers and constants: ``tests/support/dynamics.py``. Measured numbers are printed (``pytest -s``).
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

from microconveyor_env.physics.schedule import Schedule

from support.dynamics import F_REF, H, WL, X0, dt_for, quiet, sim

# ============================================================================ 3. convergence
LADDER = [16, 32, 64, 128, 256, 512, 1024]  # steps per stroke
REF_STEPS = 2 ** 16


def _final(mode, n, kinematics="reduced"):
    s = sim(mode=mode, kinematics=kinematics, dt=dt_for(F_REF, n), min_steps=2)
    assert s.steps_per_stroke(F_REF) == n
    r = quiet(s.simulate, Schedule.single(F_REF, H), X0)
    assert r.steps >= n or r.outcome != "rest"  # event mode adds nodes and travel-limited splits
    return r


def _order(ns, errs):
    """Least-squares p in err ~ C dt^p (dt ~ 1/n)."""
    return np.polyfit(np.log(1.0 / np.asarray(ns, float)), np.log(errs), 1)[0]


@functools.cache
def convergence_study():
    ref = _final("event", REF_STEPS)
    ev = np.array([abs(_final("event", n).final_position_m - ref.final_position_m) for n in LADDER])
    ka = np.array([abs(_final("karnopp", n).final_position_m - ref.final_position_m)
                   for n in LADDER])
    ka_ref = _final("karnopp", REF_STEPS).final_position_m
    return ref, ev, ka, ka_ref


def test_convergence_event_mode_order():
    """Event mode keeps (nearly) RK4's order on the reference firing: fitted order >= 3."""
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


@pytest.mark.parametrize("kinematics,freq,min_order", [("reduced", 1300.0, 3.0), ("reduced", 1500.0, 3.0),
                                                       ("exact", F_REF, 1.2)])
def test_convergence_of_detachment_instant(kinematics, freq, min_order):
    """Event mode locates the detachment instant and place to ~1e-12 relative at 2048 steps.

    Seed kinematics: N depends on (x, t) only and the detachment time converges at ~RK4 order.
    Exact kinematics: N depends on xdot, and xdot converges slowly near pull-off because Q(N) has
    an infinite slope there (d(N) ~ sqrt(N + F_pull), docs/physics.md §2.5), so the integrand is
    not smooth on the last steps: measured order ~1.6 (erratic), hence the lower bound 1.2.
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
    reduced kinematics when the part comes to rest. The sinusoid and the clamped beam have a
    curvature jump at |u| = WL/2 (and the beam a third-derivative jump at u = 0) that the
    integrator does not locate, so their order is only printed in the other cases (measured
    ~2-3.5; the exact kinematics of the beam, whose N then jumps, ~2.7 with 1e-11 m errors)."""
    ns = [16, 32, 64, 128, 256, 512, 1024]
    rows = []
    for shape in ("gaussian", "sinusoidal", "clamped_beam"):
        for kin in ("reduced", "exact"):
            for f in (300.0, 500.0, 700.0, 950.0, 1250.0):
                def fin(n, shape=shape, kin=kin, f=f):
                    s = sim(shape=shape, kinematics=kin, dt=dt_for(f, n), min_steps=2)
                    r = quiet(s.simulate, Schedule.single(f, H), X0)
                    return r.final_position_m, r.outcome

                ref, outcome = fin(2 ** 16)
                e = np.array([abs(fin(n)[0] - ref) for n in ns]) + 1e-300
                order = _order(ns, e)
                rows.append((shape, kin, f, outcome, order, e[-1]))
                if shape != "clamped_beam" and kin == "reduced" and outcome == "rest":
                    assert order >= 3.0, (shape, kin, f, order)
    print()
    for shape, kin, f, outcome, order, e in rows:
        print(f"{shape:>12} {kin:>5} {f:6.0f} Hz {outcome:>8}: order {order:5.2f}, "
              f"error at 1024 steps {e:.1e} m")
