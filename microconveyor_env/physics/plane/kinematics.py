"""Surface kinematics of the plane (docs/physics.md §10.1), SI units, compiled.

The carrier is a surface over the plane ``(x, y)`` whose material points move **vertically only**
(as the 1-D carrier, docs/physics.md §1.1). With the actuator at ``(x_a, y_a)`` firing, its height
is

    Z(x, y, t) = p(t) g(r),      r = sqrt((x - x_a)^2 + (y - y_a)^2),

a radially symmetric bump: the 1-D shape ``g`` (:func:`..kinematics.shape_eval`, peak 1 at
``r = 0``, wavelength ``wl``) taken as a function of the radial distance, and the 1-D quintic
stroke ``p(t)`` (:func:`..kinematics.stroke_eval`). The plane is level (no tilt).

With ``e = (x - x_a, y - y_a) / r`` the unit radial vector and primes for derivatives in ``r``:

    grad Z   = p g'(r) e                                    [-]
    grad Z_t = p' g'(r) e                                   [1/s]
    Hess Z   = p [g''(r) e e^T + (g'(r)/r) (I - e e^T)]     [1/m]

``g'(r)/r`` is evaluated without dividing by ``r`` (:func:`radial_slope_over_r`), so the
Hessian is finite and isotropic at the bump's centre (``g'(r)/r -> g''(0)``, every shape has a
continuous curvature there). On the line ``y = y_a`` these are the 1-D ``Y_x``, ``Y_xt`` and
``Y_xx`` bit for bit (``sqrt((x - x_a)^2) = |x - x_a|`` exactly and ``e = (+-1, 0)``).

No input checking here (the Python layer, :mod:`.simulator`, validates).
"""
from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ..kinematics import (
    CLAMPED_BEAM,
    GAUSSIAN,
    SHAPES,
    SINUSOIDAL,
    shape_eval,
    stroke_eval,
    surface_profile,
)


@njit(cache=True)
def radial_slope_over_r(kind, r, wl, g, g_r):
    """``g'(r) / r`` [1/m^2] of shape ``kind`` at radial distance ``r >= 0`` [m], exact at r = 0,
    from ``g`` [-] and ``g_r = g'(r)`` [1/m] there (:func:`..kinematics.shape_eval`).

    Gaussian ``-g / s^2``; sinusoid ``g_r / r`` (``-k^2/2`` at 0, ``k = 2 pi / wl``); clamped beam
    ``-48 v / wl^3`` with ``v = wl/2 - r`` (its ``g_r = -48 v r / wl^3``, whose form in
    :func:`..kinematics.shape_eval` cancels near the centre); 0 outside the compact shapes'
    support ``r > wl/2``.
    """
    if kind == GAUSSIAN:
        s = wl / 6.0
        return -g / (s * s)
    if kind == SINUSOIDAL:
        if r > 0.5 * wl:
            return 0.0
        if r == 0.0:
            k = 2.0 * math.pi / wl
            return -0.5 * k * k
        return g_r / r
    if kind == CLAMPED_BEAM:
        if r > 0.5 * wl:
            return 0.0
        return -48.0 * (0.5 * wl - r) / (wl * wl * wl)
    return math.nan


@njit(cache=True)
def plane_surface_eval(x, y, t, xa, ya, f, h, kind, wl):
    """The surface and its derivatives at ``(x, y)`` [m], ``t`` [s] into the stroke of the actuator
    at ``(xa, ya)`` [m] (frequency ``f`` [Hz], stroke ``h`` [m], shape code ``kind``, wavelength
    ``wl`` [m]).

    Returns ``(Z [m], Z_x, Z_y [-], Z_tt [m/s^2], Z_xt, Z_yt [1/s], Z_xx, Z_xy, Z_yy [1/m])``.
    """
    p, p_t, p_tt = stroke_eval(t, f, h)
    dx = x - xa
    dy = y - ya
    r = math.sqrt(dx * dx + dy * dy)
    g, g_r, g_rr = shape_eval(kind, r, wl)
    if r > 0.0:
        ex = dx / r
        ey = dy / r
    else:            # the centre: grad Z = 0 and the Hessian is isotropic, e is moot
        ex = 0.0
        ey = 0.0
    k = radial_slope_over_r(kind, r, wl, g, g_r)
    pg = p * g_r
    ptg = p_t * g_r
    return (p * g, pg * ex, pg * ey, p_tt * g, ptg * ex, ptg * ey,
            p * (g_rr * ex * ex + k * (1.0 - ex * ex)), p * ((g_rr - k) * ex * ey),
            p * (g_rr * ey * ey + k * (1.0 - ey * ey)))


def plane_surface_height(x: npt.ArrayLike, y: npt.ArrayLike, amplitude: float, shape: str | int,
                         wavelength: float, xa: float = 0.0, ya: float = 0.0) -> np.ndarray:
    """Surface height ``Z = amplitude g(r)`` [m] over arrays ``x``, ``y`` [m] (broadcast), for an
    actuator at ``(xa, ya)`` [m] displaced by ``amplitude`` [m] (plain numpy, for height maps)."""
    r = np.hypot(np.asarray(x, dtype=float) - xa, np.asarray(y, dtype=float) - ya)
    return surface_profile(r, amplitude, SHAPES[shape] if isinstance(shape, str) else shape,
                           wavelength)


refresh_jit_cache(globals())
