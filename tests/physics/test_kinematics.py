"""Tests for microconveyor_env.physics.kinematics (shapes, stroke, surface, zone strain)."""
import math
import warnings

import numpy as np
import pytest
from scipy.integrate import IntegrationWarning, quad

from microconveyor_env.physics import kinematics as km
from microconveyor_env.physics.dynamics_kernel import TAU_UNLOAD
from microconveyor_env.physics.simulator import PEAK_QUINTIC_ACCEL
from microconveyor_env.physics.kinematics import (
    CLAMPED_BEAM, GAUSSIAN, SHAPES, SINUSOIDAL, shape_eval, stroke_eval,
    surface_eval, surface_profile, zone_strain,
)

KINDS = [GAUSSIAN, SINUSOIDAL, CLAMPED_BEAM]
COMPACT = [SINUSOIDAL, CLAMPED_BEAM]
WLS = [0.2e-3, 0.6e-3, 2e-3]
FREQS = [300.0, 950.0, 5000.0]
H = 200e-6


def shape_arrays(kind, u, wl):
    return np.array([shape_eval(kind, float(ui), wl) for ui in u]).T


def smooth_points(kind, wl, n=401, span=0.7, gap=1e-3):
    """Points in [-span wl, span wl] away from the kinks (|u| = wl/2; u = 0 for the clamped beam)."""
    u = np.linspace(-span * wl, span * wl, n)
    keep = np.abs(np.abs(u) - 0.5 * wl) > gap * wl
    if kind == CLAMPED_BEAM:
        keep &= np.abs(u) > gap * wl
    return u[keep]


# ---------------------------------------------------------------------------------------- shapes
def test_shape_names_select_their_shapes():
    """Each name in SHAPES selects the shape it names: the compiled shape_eval of its code
    equals the plain-numpy profile of the name and has that shape's signature values."""
    assert len(set(SHAPES.values())) == len(SHAPES)
    wl = 0.6e-3
    u = np.linspace(-0.7 * wl, 0.7 * wl, 57)
    for name, code in SHAPES.items():
        g = np.array([shape_eval(code, ui, wl)[0] for ui in u])
        np.testing.assert_allclose(g, surface_profile(u, 1.0, name, wl), rtol=1e-13, atol=1e-15)
    at_edge = {k: shape_eval(c, 0.5 * wl, wl)[0] for k, c in SHAPES.items()}
    assert at_edge["gaussian"] == pytest.approx(math.exp(-4.5), rel=1e-13)  # s = wl/6
    assert at_edge["sinusoidal"] == at_edge["clamped_beam"] == 0.0
    quarter = {k: shape_eval(c, 0.25 * wl, wl)[0] for k, c in SHAPES.items()}
    assert quarter["sinusoidal"] == pytest.approx(0.5, rel=1e-13)   # (1 + cos(pi/2)) / 2
    assert quarter["clamped_beam"] == pytest.approx(0.5, rel=1e-13)  # 4 (l/4)^2 (2 l) / l^3


@pytest.mark.parametrize("wl", WLS)
@pytest.mark.parametrize("kind", KINDS)
def test_peak_is_one(kind, wl):
    g, g_u, _ = shape_eval(kind, 0.0, wl)
    assert g == pytest.approx(1.0, abs=1e-15)
    assert g_u == 0.0
    u = np.linspace(-wl, wl, 2001)
    assert shape_arrays(kind, u, wl)[0].max() <= 1.0 + 1e-15


@pytest.mark.parametrize("wl", WLS)
@pytest.mark.parametrize("kind", KINDS)
def test_shape_derivatives_match_finite_differences(kind, wl):
    u = smooth_points(kind, wl)
    du = 1e-5 * wl
    g, g_u, g_uu = shape_arrays(kind, u, wl)
    gp, gup, _ = shape_arrays(kind, u + du, wl)
    gm, gum, _ = shape_arrays(kind, u - du, wl)
    scale_u = np.abs(g_u).max()
    scale_uu = np.abs(g_uu).max()
    np.testing.assert_allclose(g_u, (gp - gm) / (2 * du), rtol=1e-6, atol=1e-7 * scale_u)
    np.testing.assert_allclose(g_uu, (gup - gum) / (2 * du), rtol=1e-6, atol=1e-7 * scale_uu)
    np.testing.assert_allclose(g_uu, (gp - 2 * g + gm) / du**2, rtol=1e-4, atol=1e-4 * scale_uu)


@pytest.mark.parametrize("kind", KINDS)
def test_shape_parity(kind):
    wl = 0.6e-3
    u = np.linspace(0.0, wl, 301)
    gp = shape_arrays(kind, u, wl)
    gm = shape_arrays(kind, -u, wl)
    np.testing.assert_array_equal(gp[0], gm[0])      # g even
    np.testing.assert_array_equal(gp[1], -gm[1])     # g_u odd
    np.testing.assert_array_equal(gp[2], gm[2])      # g_uu even


@pytest.mark.parametrize("kind", COMPACT)
def test_compact_shapes_vanish_outside_support(kind):
    wl = 0.6e-3
    u = np.concatenate([np.linspace(0.5 * wl * (1 + 1e-12), 5 * wl, 200), [1.0, 1e3]])
    for sign in (1.0, -1.0):
        np.testing.assert_array_equal(shape_arrays(kind, sign * u, wl), 0.0)
    for edge in (0.5 * wl, -0.5 * wl):              # continuous g and g_u at the support edge
        g, g_u, _ = shape_eval(kind, edge, wl)
        assert abs(g) < 1e-15 and abs(g_u) * wl < 1e-12


def test_gaussian_width():
    wl = 0.6e-3
    assert shape_eval(GAUSSIAN, wl / 6, wl)[0] == pytest.approx(math.exp(-0.5), rel=1e-14)
    assert shape_eval(GAUSSIAN, 0.0, wl)[2] == pytest.approx(-36.0 / wl**2, rel=1e-14)


def test_sinusoid_special_points():
    wl = 0.6e-3
    k = 2 * math.pi / wl
    assert shape_eval(SINUSOIDAL, wl / 4, wl) == pytest.approx((0.5, -k / 2, 0.0), abs=1e-9 * k**2)
    assert shape_eval(SINUSOIDAL, 0.5 * wl, wl)[2] == pytest.approx(k**2 / 2, rel=1e-14)  # jumps to 0


@pytest.mark.parametrize("wl", WLS)
def test_clamped_beam_special_points(wl):
    # slope 0 at both clamped ends and at the centre
    for u in (-0.5 * wl, 0.0, 0.5 * wl):
        assert shape_eval(CLAMPED_BEAM, u, wl)[1] == 0.0
    assert shape_eval(CLAMPED_BEAM, 0.5 * wl, wl)[0] == 0.0
    # curvature: +24/wl^2 at the clamped ends (inside), -24/wl^2 at the centre
    assert shape_eval(CLAMPED_BEAM, 0.5 * wl, wl)[2] == pytest.approx(24 / wl**2, rel=1e-12)
    assert shape_eval(CLAMPED_BEAM, 0.0, wl)[2] == pytest.approx(-24 / wl**2, rel=1e-12)
    # the curvature is continuous through u = 0 (only the third derivative jumps there) ...
    for u in (1e-9 * wl, -1e-9 * wl):
        assert shape_eval(CLAMPED_BEAM, u, wl)[2] == pytest.approx(-24 / wl**2, rel=1e-7)
    # ... and g_uu changes sign at the inflection points |u| = wl/4, where g = 1/2
    g, g_u, g_uu = shape_eval(CLAMPED_BEAM, 0.25 * wl, wl)
    assert g == pytest.approx(0.5, rel=1e-14)
    assert g_u == pytest.approx(-3.0 / wl, rel=1e-14)     # steepest slope
    assert abs(g_uu) * wl**2 < 1e-12


def test_unknown_shape_is_nan():
    assert all(math.isnan(v) for v in shape_eval(7, 0.0, 0.6e-3))


@pytest.mark.parametrize("kind", KINDS)
def test_surface_profile_matches_shape_eval(kind):
    wl, x_act, amp = 0.6e-3, 1.5e-3, 150e-6
    x = np.linspace(0.0, 3e-3, 1001)
    expected = amp * shape_arrays(kind, x - x_act, wl)[0]
    name = [n for n, c in SHAPES.items() if c == kind][0]
    np.testing.assert_allclose(surface_profile(x, amp, kind, wl, x_act), expected, rtol=1e-13,
                               atol=1e-15 * amp)
    np.testing.assert_allclose(surface_profile(x, amp, name, wl, x_act), expected, rtol=1e-13,
                               atol=1e-15 * amp)


def test_surface_profile_rejects_unknown_shape():
    with pytest.raises(ValueError):
        surface_profile(np.zeros(3), 1e-4, 5, 0.6e-3)
    with pytest.raises(KeyError):
        surface_profile(np.zeros(3), 1e-4, "triangle", 0.6e-3)


# ---------------------------------------------------------------------------------------- stroke
def stroke_arrays(t, f, h):
    return np.array([stroke_eval(float(ti), f, h) for ti in t]).T


@pytest.mark.parametrize("f", FREQS)
def test_stroke_end_points(f):
    T = 1.0 / f
    half = T / 2
    vs, as_ = H / half, H / half**2                  # velocity and acceleration scales
    for t, p_expected in ((0.0, 0.0), (half, H), (T, 0.0)):
        p, p_t, p_tt = stroke_eval(t, f, H)
        assert p == pytest.approx(p_expected, abs=1e-15 * H)
        assert abs(p_t) <= 1e-14 * vs and abs(p_tt) <= 1e-14 * as_
    for t in (-1e-12, -1.0, T * (1 + 1e-9), 10 * T):
        assert stroke_eval(t, f, H) == (0.0, 0.0, 0.0)
    assert stroke_eval(T * (1 - 1e-3), f, H)[0] > 0.0  # the stroke lasts exactly 1/f


@pytest.mark.parametrize("f", FREQS)
def test_stroke_symmetric_about_half_period(f):
    T = 1.0 / f
    d = np.linspace(0.0, T / 2, 257)
    up = stroke_arrays(T / 2 - d, f, H)
    down = stroke_arrays(T / 2 + d, f, H)
    np.testing.assert_allclose(down[0], up[0], rtol=1e-12, atol=1e-14 * H)
    np.testing.assert_allclose(down[1], -up[1], rtol=1e-9, atol=1e-12 * H * f)
    np.testing.assert_allclose(down[2], up[2], rtol=1e-9, atol=1e-10 * H * f**2)
    assert np.all(up[0] >= 0.0) and np.all(up[0] <= H)


@pytest.mark.parametrize("f", FREQS)
def test_stroke_derivatives_match_finite_differences(f):
    T = 1.0 / f
    t = np.linspace(0.0, T, 803)[1:-1]
    t = t[np.abs(t - T / 2) > 1e-3 * T]              # jerk jumps at T/2 (and at 0, T)
    dt = 1e-6 * T
    p, p_t, p_tt = stroke_arrays(t, f, H)
    pp, ptp, _ = stroke_arrays(t + dt, f, H)
    pm, ptm, _ = stroke_arrays(t - dt, f, H)
    vmax, amax = np.abs(p_t).max(), np.abs(p_tt).max()
    np.testing.assert_allclose(p_t, (pp - pm) / (2 * dt), rtol=1e-6, atol=1e-7 * vmax)
    np.testing.assert_allclose(p_tt, (ptp - ptm) / (2 * dt), rtol=1e-6, atol=1e-7 * amax)


@pytest.mark.parametrize("f", FREQS)
def test_stroke_peak_acceleration(f):
    T = 1.0 / f
    half = T / 2
    expected = PEAK_QUINTIC_ACCEL * H / half**2  # the simulator's table-range check uses it
    t = np.linspace(0.0, T, 200_001)
    acc = stroke_arrays(t, f, H)[2]
    assert np.abs(acc).max() == pytest.approx(expected, rel=1e-8)
    # attained at tau = (1 -+ 1/sqrt(3))/2 (up: +, then -; mirrored on the way down)
    for tau, sign in (((1 - 1 / math.sqrt(3)) / 2, 1), ((1 + 1 / math.sqrt(3)) / 2, -1)):
        assert stroke_eval(tau * half, f, H)[2] == pytest.approx(sign * expected, rel=1e-12)
        assert stroke_eval(T - tau * half, f, H)[2] == pytest.approx(sign * expected, rel=1e-12)
    # the event mode's extra grid nodes sit exactly at the downward peaks
    assert stroke_eval(TAU_UNLOAD * half, f, H)[2] == pytest.approx(-expected, rel=1e-12)
    assert stroke_eval(T - TAU_UNLOAD * half, f, H)[2] == pytest.approx(-expected, rel=1e-12)


# --------------------------------------------------------------------------------------- surface
@pytest.mark.parametrize("kind", KINDS)
def test_surface_eval_is_stroke_times_shape(kind):
    f, wl, x_act = 950.0, 0.6e-3, 1e-3
    rng = np.random.default_rng(1)
    for x, t in zip(rng.uniform(0.0, 2e-3, 50), rng.uniform(-0.1 / f, 1.1 / f, 50), strict=True):
        p, p_t, p_tt = stroke_eval(t, f, H)
        g, g_u, g_uu = shape_eval(kind, x - x_act, wl)
        assert surface_eval(x, t, x_act, f, H, kind, wl) == (
            p * g, p * g_u, p_t * g, p_tt * g, p_t * g_u, p * g_uu)


@pytest.mark.parametrize("kind", KINDS)
def test_surface_derivatives_match_finite_differences(kind):
    f, wl, x_act = 950.0, 0.6e-3, 1e-3
    T = 1.0 / f
    dx, dt = 1e-5 * wl, 1e-6 * T
    x = x_act + smooth_points(kind, wl, n=61, gap=1e-2)
    t = np.linspace(0.0, T, 23)[1:-1]
    t = t[np.abs(t - T / 2) > 1e-2 * T]
    X, Tt = (a.ravel() for a in np.meshgrid(x, t))

    def ev(xs, ts):
        return np.array([surface_eval(a, b, x_act, f, H, kind, wl) for a, b in zip(xs, ts, strict=True)]).T

    Y, Y_x, Y_t, Y_tt, Y_xt, Y_xx = ev(X, Tt)
    xp, xm = ev(X + dx, Tt), ev(X - dx, Tt)
    tp, tm = ev(X, Tt + dt), ev(X, Tt - dt)

    def check(value, fd, rtol=1e-6):
        np.testing.assert_allclose(value, fd, rtol=rtol, atol=1e-7 * np.abs(value).max())

    check(Y_x, (xp[0] - xm[0]) / (2 * dx))
    check(Y_xx, (xp[1] - xm[1]) / (2 * dx))
    check(Y_t, (tp[0] - tm[0]) / (2 * dt))
    check(Y_tt, (tp[2] - tm[2]) / (2 * dt))
    check(Y_xt, (tp[1] - tm[1]) / (2 * dt))           # d/dt of Y_x
    check(Y_xt, (xp[2] - xm[2]) / (2 * dx))           # d/dx of Y_t


def test_surface_at_rest_outside_stroke():
    f = 950.0
    for t in (-1e-6, 1.0 / f + 1e-9):
        assert surface_eval(1e-3, t, 1e-3, f, H, GAUSSIAN, 0.6e-3) == (0.0,) * 6


# ----------------------------------------------------------------------------------- zone strain
def strain_reference(amplitude, kind, wl, zone_length):
    """(s - l)/l by adaptive quadrature over the whole zone, split at the kinks."""
    def integrand(u):
        q = amplitude * shape_eval(kind, u, wl)[1]
        return q * q / (1.0 + math.sqrt(1.0 + q * q))   # = sqrt(1 + q^2) - 1, no cancellation
    half = zone_length / 2
    points = [p for p in (-wl / 2, 0.0, wl / 2) if -half < p < half]
    with warnings.catch_warnings():
        warnings.simplefilter("error", IntegrationWarning)
        value, _ = quad(integrand, -half, half, points=points, epsabs=0.0, epsrel=1e-13,
                        limit=500)
    return value / zone_length


@pytest.mark.parametrize("wl", [0.2e-3, 0.6e-3, 2e-3])
@pytest.mark.parametrize("kind", KINDS)
def test_zone_strain_matches_quad(kind, wl):
    for amplitude in (1e-7, 20e-6, 150e-6, 300e-6):
        for zone_length in (0.5 * wl, wl, 0.5e-3, 1.5e-3):
            e = zone_strain(amplitude, kind, wl, zone_length)
            assert e == pytest.approx(strain_reference(amplitude, kind, wl, zone_length),
                                      rel=1e-9), (amplitude, zone_length)


@pytest.mark.parametrize("kind", KINDS)
def test_zone_strain_zero_and_increasing(kind):
    wl, zone = 0.6e-3, 1e-3
    assert zone_strain(0.0, kind, wl, zone) == 0.0
    amps = np.linspace(0.0, 300e-6, 61)
    e = np.array([zone_strain(a, kind, wl, zone) for a in amps])
    assert np.all(np.diff(e) > 0)
    assert zone_strain(-120e-6, kind, wl, zone) == zone_strain(120e-6, kind, wl, zone)


def test_zone_strain_small_amplitude_sinusoid():
    # e ~ (a^2 / 2l) * int g_u^2 du = a^2 pi^2 / (4 wl l) for the sinusoid
    wl, zone, a = 0.6e-3, 1e-3, 1e-8
    assert zone_strain(a, SINUSOIDAL, wl, zone) == pytest.approx(
        a**2 * math.pi**2 / (4 * wl * zone), rel=1e-8)


@pytest.mark.parametrize("kind", COMPACT)
def test_zone_strain_flat_beyond_support(kind):
    # beyond +-wl/2 the zone is flat: s - l, i.e. e*l, does not depend on l
    wl, a = 0.6e-3, 200e-6
    el = [zone_strain(a, kind, wl, zone) * zone for zone in (wl, 1e-3, 3e-3)]
    assert el == pytest.approx([el[0]] * 3, rel=1e-13)


def test_quadrature_rule_is_normalised():
    assert km.QUAD_W.sum() == pytest.approx(1.0, rel=1e-14)
    assert km.QUAD_X.min() > 0.0 and km.QUAD_X.max() < 1.0
    assert np.all(np.diff(km.QUAD_X) > 0)
