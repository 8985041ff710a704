"""Surface and actuator kinematics (docs/physics.md §1 and §4), SI units.

Model
-----
The carrier surface moves **vertically only**; with one actuator at ``x_act`` active,

    Y(x, t) = p(t) * g(x - x_act),

where ``g(u)`` is the deformation shape (peak 1 at ``u = 0``, wavelength ``wl``) and ``p(t)`` the
actuator displacement during one stroke (``t`` measured from the stroke start).

Shapes (integer codes, so they can be passed into numba code):

* ``GAUSSIAN``:     ``g = exp(-u^2 / (2 s^2))``, ``s = wl / 6`` (not truncated: ``g(+-wl/2) = e^-4.5``);
* ``SINUSOIDAL``:   ``g = (1 + cos(2 pi u / wl)) / 2`` for ``|u| <= wl/2``, else 0;
* ``CLAMPED_BEAM``: ``g = 4 v^2 (3 l - 4 v) / l^3`` with ``v = wl/2 - |u|``, ``l = wl``, for
  ``|u| <= wl/2``, else 0 -- the Euler-Bernoulli deflection of a beam clamped at ``+-wl/2`` under a
  central point load.

Smoothness: the Gaussian is analytic. The sinusoid and the clamped beam have ``g = g_u = 0`` at
``|u| = wl/2`` but a curvature jump there (``g_uu`` is ``(2 pi/wl)^2 / 2`` resp. ``24/wl^2`` inside,
0 outside). The clamped beam's curvature is *continuous* at ``u = 0`` (``-24/wl^2``); only its
third derivative (the shear force of the point load) jumps there. At the support edge itself the
inside formula is used (``|u| <= wl/2``).

Stroke: quintic rest-to-rest up from 0 to ``h`` in ``T/2`` (``T = 1/f``), then its mirror image
down; with ``tau = t / (T/2)``, ``p = h (10 tau^3 - 15 tau^4 + 6 tau^5)``. Velocity and acceleration
vanish at 0, T/2 and T; the peak acceleration is ``(10/sqrt(3)) h / (T/2)^2`` at
``tau = (1 -+ 1/sqrt(3)) / 2``. Outside ``[0, T]`` the actuator rests at 0.

Zone strain (§4): an active zone of length ``l`` centred on the actuator has arc length
``s = int_{-l/2}^{l/2} sqrt(1 + (a g_u)^2) du`` and uniform strain ``e = (s - l)/l``. It is computed
as ``e = (2/l) int_0^{l/2} q^2 / (1 + sqrt(1 + q^2)) du`` with ``q = a g_u`` (the integrand is even;
this form has no cancellation, so ``e`` is accurate relative to itself even for tiny amplitudes), by
fixed composite Gauss-Legendre quadrature on ``[0, b]``: ``b = min(l/2, wl/2)`` for the compactly
supported shapes (beyond ``wl/2`` the surface is flat and contributes nothing; ending the interval
there keeps the integrand smooth) and ``b = min(l/2, wl)`` (= 6 s) for the Gaussian (the neglected
tail is ~e^-36 relative).

Validation: the ``@njit`` functions do **no** input checking (the Python layer validates
frequencies, strokes, wavelengths and shape codes before calling them). An unknown shape code
gives NaNs rather than an exception.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from ..jit_cache import refresh as refresh_jit_cache

GAUSSIAN = 0
SINUSOIDAL = 1
CLAMPED_BEAM = 2
SHAPES = {"gaussian": GAUSSIAN, "sinusoidal": SINUSOIDAL, "clamped_beam": CLAMPED_BEAM}

# Composite Gauss-Legendre rule on [0, 1]: _QUAD_SUB sub-intervals x _QUAD_NODES nodes.
_QUAD_SUB = 64
_QUAD_NODES = 8
_gl_x, _gl_w = np.polynomial.legendre.leggauss(_QUAD_NODES)
QUAD_X = ((np.arange(_QUAD_SUB)[:, None] + 0.5 * (_gl_x[None, :] + 1.0)) / _QUAD_SUB).ravel()
QUAD_W = np.tile(_gl_w, _QUAD_SUB) / (2.0 * _QUAD_SUB)
del _gl_x, _gl_w


@njit(cache=True)
def shape_constant(kind, wl):
    """The constant of shape ``kind`` that depends on the wavelength ``wl`` [m] alone: ``1/s^2``
    [1/m^2] (Gaussian), the wavenumber ``2 pi / wl`` [1/m] (sinusoid), ``wl^3`` [m^3] (clamped
    beam). :func:`shape_with` takes it, so a caller on one wavelength computes it once."""
    if kind == GAUSSIAN:
        s = wl / 6.0
        return 1.0 / (s * s)
    if kind == SINUSOIDAL:
        return 2.0 * math.pi / wl
    if kind == CLAMPED_BEAM:
        return wl * wl * wl
    return math.nan


@njit(cache=True)
def shape_with(kind, u, wl, const):
    """:func:`shape_eval` given ``const = shape_constant(kind, wl)``: the same values."""
    if kind == GAUSSIAN:
        inv_s2 = const
        g = math.exp(-0.5 * u * u * inv_s2)
        return g, -u * inv_s2 * g, (u * u * inv_s2 - 1.0) * inv_s2 * g
    return _compact_shape(kind, u, wl, const)


@intrinsic
def _opaque(typingctx, x):
    """``x`` (float64) unchanged, through an empty assembly statement with side effects that the
    optimiser may neither look through nor move: what is computed from the result stays on the
    branch that needs it (else the compiler evaluates the compact shapes' sine and cosine on the
    Gaussian's path too, only to discard them)."""
    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        bits = builder.bitcast(args[0], i64)
        kept = builder.asm(ir.FunctionType(i64, [i64]), "", "=r,0", [bits], side_effect=True)
        return builder.bitcast(kept, ir.DoubleType())
    return types.float64(types.float64), codegen


@njit(cache=True)
def _compact_shape(kind, u, wl, const):
    """The shapes of compact support (:func:`shape_with`)."""
    u = _opaque(u)
    if kind == SINUSOIDAL:
        if abs(u) > 0.5 * wl:
            return 0.0, 0.0, 0.0
        k = const
        c = math.cos(k * u)
        return 0.5 * (1.0 + c), -0.5 * k * math.sin(k * u), -0.5 * k * k * c
    if kind == CLAMPED_BEAM:
        if abs(u) > 0.5 * wl:
            return 0.0, 0.0, 0.0
        l3 = const
        v = 0.5 * wl - abs(u)                        # dv/du = -sign(u)
        g = 4.0 * v * v * (3.0 * wl - 4.0 * v) / l3
        g_v = 24.0 * v * (wl - 2.0 * v) / l3         # 0 at v = 0 and v = wl/2 (u = 0)
        g_vv = (24.0 * wl - 96.0 * v) / l3
        sgn = 1.0 if u > 0.0 else -1.0               # g_v = 0 at u = 0, so sign(0) is moot
        return g, -sgn * g_v, g_vv
    nan = math.nan
    return nan, nan, nan


@njit(cache=True)
def shape_eval(kind, u, wl):
    """Shape ``g(u)`` and its derivatives ``(g, g_u [1/m], g_uu [1/m^2])`` for shape code ``kind``."""
    return shape_with(kind, u, wl, shape_constant(kind, wl))


@njit(cache=True)
def stroke_with(t, period, half, half2, h):
    """:func:`stroke_eval` given ``period = 1/f`` [s], ``half = period / 2`` [s] and
    ``half2 = half^2`` [s^2] (a caller on one stroke computes them once): the same values."""
    if t < 0.0 or t > period:
        return 0.0, 0.0, 0.0
    if t <= half:
        tau, sign = t / half, 1.0
    else:                                            # mirror image: p(t) = p(T - t)
        tau, sign = (period - t) / half, -1.0
    t2 = tau * tau
    p = h * t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau))
    p_t = h * 30.0 * t2 * (1.0 + tau * (-2.0 + tau)) / half
    p_tt = h * 60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau)) / half2
    return p, sign * p_t, p_tt


@njit(cache=True)
def stroke_eval(t, f, h):
    """Actuator displacement ``(p [m], p_t [m/s], p_tt [m/s^2])`` at time ``t`` since stroke start.

    Stroke of height ``h`` and duration ``T = 1/f``; zero outside ``[0, T]``.
    """
    period = 1.0 / f
    half = 0.5 * period
    return stroke_with(t, period, half, half * half, h)


@njit(cache=True)
def surface_eval(x, t, x_act, f, h, kind, wl):
    """``(Y, Y_x, Y_t, Y_tt, Y_xt, Y_xx)`` of ``Y = p(t) g(x - x_act)`` (one active actuator)."""
    p, p_t, p_tt = stroke_eval(t, f, h)
    g, g_u, g_uu = shape_eval(kind, x - x_act, wl)
    return p * g, p * g_u, p_t * g, p_tt * g, p_t * g_u, p * g_uu


@njit(cache=True)
def zone_strain(amplitude, kind, wl, zone_length):
    """Uniform strain ``e = (s - l)/l`` of a zone of length ``l = zone_length`` centred on the
    actuator, deflected as ``amplitude * g`` (docs/physics.md §4); see the module docstring."""
    half = 0.5 * zone_length
    b = min(half, wl) if kind == GAUSSIAN else min(half, 0.5 * wl)
    acc = 0.0
    for i in range(QUAD_X.shape[0]):
        q = amplitude * shape_eval(kind, b * QUAD_X[i], wl)[1]
        q2 = q * q
        acc += QUAD_W[i] * q2 / (1.0 + math.sqrt(1.0 + q2))
    return 2.0 * b * acc / zone_length


def surface_profile(x_array, amplitude, kind, wl, x_act=0.0):
    """Surface height ``Y = amplitude * g(x - x_act)`` over an array (plain numpy, for plotting).

    ``kind`` is a shape code or a name from :data:`SHAPES`.
    """
    if isinstance(kind, str):
        kind = SHAPES[kind]
    if kind not in SHAPES.values():
        raise ValueError(f"unknown shape code {kind!r}; expected one of {SHAPES}")
    u = np.asarray(x_array, dtype=float) - x_act
    inside = np.abs(u) <= 0.5 * wl
    if kind == GAUSSIAN:
        g = np.exp(-0.5 * (u / (wl / 6.0)) ** 2)
    elif kind == SINUSOIDAL:
        g = np.where(inside, 0.5 * (1.0 + np.cos(2.0 * np.pi * u / wl)), 0.0)
    else:
        v = np.where(inside, 0.5 * wl - np.abs(u), 0.0)
        g = 4.0 * v * v * (3.0 * wl - 4.0 * v) / wl ** 3
    return amplitude * g


refresh_jit_cache(globals())
