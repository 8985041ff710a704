"""Shared helpers of the dynamics tests (test_dynamics_*.py): scene constants, runners,
sweeps and an independent numpy re-derivation of the surface and normal load."""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from microconveyor_env.physics.materials import G0
from microconveyor_env.physics.schedule import Schedule
from microconveyor_env.presets import simulator
from microconveyor_env.physics.simulator import Simulator, StepSizeWarning

WL = 0.6e-3           # m, seed wavelength
X0 = 0.125e-3         # m, seed start (from the actuator at 0)
H = 200e-6            # m, seed stroke
F_REF = 950.0        # Hz, reference firing
OUTCOMES = {"rest", "detached", "max_time", "moving", "too_many_events"}
REL = 1e-9            # closed-form tolerance (relative)


# ----------------------------------------------------------------------------- helpers
@functools.cache
def sim(**kw) -> Simulator:
    """Cached Simulator (the contact table and the kernel arrays are built once per setting)."""
    return simulator(**kw)


def run(freq=F_REF, h=H, x0=X0, **kw):
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


@functools.cache
def sweep(shape="gaussian", h=H, kinematics="reduced", x0=X0):
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


# Independent surface kinematics (docs/physics.md §1), plain numpy, NOT the package's kinematics
# module.
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
    """N = m cos(theta) (g0 + Y_tt [+ 2 Y_xt v + Y_xx v^2]) (docs/physics.md §3.2)."""
    _, Yx, Ytt, Yxt, Yxx = surface(x, t, freq, h)
    acc = G0 + Ytt + ((2 * Yxt * v + Yxx * v * v) if exact else 0.0)
    return m * acc / np.sqrt(1 + Yx ** 2), Yx
