"""Instantaneous mechanics of a part on the plane, compiled (docs/physics.md §10.2-10.5).

The plane's counterpart of :mod:`.forces`: the normal load, the friction's direction, the
acceleration, one RK4 step and the stick test of a part at ``(x, y)`` [m] with velocity
``(vx, vy)`` [m/s]. The model constants are the 1-D array ``P`` (:mod:`.forces` indices;
``P[I_SLOPE]`` must be 0 and the roughness constant: the plane is level and has no stretch) and
the contact table arrays ``tu, tq, tqu`` (:func:`..forces.friction_of_load`).

Friction acts in the tangent plane against the sliding velocity relative to the surface,
``w = (vx, vy, grad Z . v)``; its horizontal part is ``-Q(N) d / sqrt(1 + (grad Z . d)^2)`` with
``d`` the unit horizontal sliding direction. How ``d`` is taken over one RK4 step
(:func:`step_direction`): it follows each stage's velocity while that is well conditioned, and is
held for the step from rest and at low speed, where the direction's own dynamics is stiff. On a
line every choice is the 1-D kernel's fixed slip sign ``s`` (``d = (s, 0)``), and the forces are
the 1-D ones bit for bit.
"""
from __future__ import annotations

import math

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ..forces import I_EXACT, I_FSCALE, I_G0, I_MASS, I_NMIN, I_SHAPE, I_WL, friction_of_load
from .kinematics import plane_surface_eval

STIFF_DIRECTION = 1.0  # [-] largest h Q / (m |v|) at which friction follows the stage velocity
                       # (RK4 is stable on the transverse mode up to ~2.8)
STAGE_FLOOR = 1e-3     # [-] a stage slower than this * the step's starting speed slides along e


@njit(cache=True)
def plane_normal_load(x, y, vx, vy, tl, xa, ya, f, h, P):
    """``(N [N], Z_x, Z_y [-], cos(theta) [-], Z [m])``: the normal load on a part at ``(x, y)``
    with velocity ``(vx, vy)``, ``tl`` [s] into the stroke of the actuator at ``(xa, ya)``.

    ``N = m cos(theta) (g0 + A)``, ``cos(theta) = 1 / sqrt(1 + |grad Z|^2)``; ``A = Z_tt`` (reduced
    kinematics) or ``Z_tt + 2 grad Z_t . v + v^T (Hess Z) v`` (exact).
    """
    Z, Zx, Zy, Ztt, Zxt, Zyt, Zxx, Zxy, Zyy = plane_surface_eval(
        x, y, tl, xa, ya, f, h, int(P[I_SHAPE]), P[I_WL])
    c = 1.0 / math.sqrt(1.0 + (Zx * Zx + Zy * Zy))
    acc = P[I_G0] + Ztt
    if P[I_EXACT] != 0.0:
        acc += 2.0 * (Zxt * vx + Zyt * vy) + (Zxx * vx * vx + 2.0 * Zxy * vx * vy + Zyy * vy * vy)
    return P[I_MASS] * c * acc, Zx, Zy, c, Z


@njit(cache=True)
def plane_friction(N, P, tu, tq, tqu):
    """Maximum static (and sliding) friction Q(N) [N]: the contact table times ``P[I_FSCALE]``."""
    return friction_of_load(N, tu, tq, tqu, P[I_NMIN]) * P[I_FSCALE]


@njit(cache=True)
def slip_direction(vx, vy, ex, ey, floor):
    """Unit horizontal sliding direction of velocity ``(vx, vy)`` [m/s], continued through
    ``v = 0`` along the reference direction ``(ex, ey)``: ``v/|v|`` while ``v . e >= 0``, ``-v/|v|``
    past it, and ``e`` itself at speeds up to ``floor`` [m/s] (there the velocity's direction is
    rounding noise: a stage of a step that ends at, or just past, a stop)."""
    sp = math.sqrt(vx * vx + vy * vy)
    if sp <= floor:
        return ex, ey
    if vx * ex + vy * ey < 0.0:
        return -vx / sp, -vy / sp
    return vx / sp, vy / sp


@njit(cache=True)
def plane_load_friction(x, y, vx, vy, tl, xa, ya, f, h, P, tu, tq, tqu):
    """``(N [N], Z_x, Z_y [-], cos(theta) [-], Q(N) [N])`` at the part."""
    N, Zx, Zy, c, _ = plane_normal_load(x, y, vx, vy, tl, xa, ya, f, h, P)
    return N, Zx, Zy, c, plane_friction(N, P, tu, tq, tqu)


@njit(cache=True)
def _accel(N, Zx, Zy, c, Q, dx, dy, m):
    """Horizontal acceleration [m/s^2] with friction Q against the sliding direction ``d``."""
    gd = Zx * dx + Zy * dy
    cw = 1.0 / math.sqrt(1.0 + gd * gd)
    return (-dx * Q * cw - N * Zx * c) / m, (-dy * Q * cw - N * Zy * c) / m


@njit(cache=True)
def plane_accel(x, y, vx, vy, tl, ex, ey, follow, floor, xa, ya, f, h, P, tu, tq, tqu):
    """Horizontal acceleration ``(ax, ay)`` [m/s^2] of a sliding part: friction against
    :func:`slip_direction` of the velocity (``follow``; reference ``e``, speed floor ``floor``
    [m/s]) or against ``e``."""
    N, Zx, Zy, c, Q = plane_load_friction(x, y, vx, vy, tl, xa, ya, f, h, P, tu, tq, tqu)
    if follow:
        ex, ey = slip_direction(vx, vy, ex, ey, floor)
    return _accel(N, Zx, Zy, c, Q, ex, ey, P[I_MASS])


@njit(cache=True)
def step_direction(vx, vy, ex, ey, h_dir, N, Zx, Zy, c, Q, m):
    """How friction is directed over a step from velocity ``v`` (reference direction ``e``):
    ``(follow, dx, dy)``.

    * from rest (``v = 0``): against ``e`` (the break-away direction), held for the step;
    * ``h_dir Q / (m |v|) <= STIFF_DIRECTION``: against each stage's velocity (``follow``);
    * otherwise the direction's own dynamics is stiff on the step ``h_dir`` [s] (a transverse
      velocity decays at the rate ``Q / (m |v|)``, beyond the stability of an explicit step at
      low speed), and the friction is held for the step: along the implicit-Euler direction
      ``w = v + h_dir D`` (``D = -N cos(theta) grad Z / m``, the acceleration without friction;
      signed to agree with ``e``) if the part keeps sliding, ``|w| > h_dir Q_h / m`` (``Q_h`` the
      friction's horizontal part along ``w``; a step that
      ends with the velocity along it leaves no transverse velocity to oscillate); along ``e``
      (the velocity's own direction) if friction stops it within the step.

    On a line both held directions are ``e`` itself, the 1-D kernel's slip sign.
    """
    sp = math.sqrt(vx * vx + vy * vy)
    if sp == 0.0:
        return False, ex, ey
    if h_dir * Q <= STIFF_DIRECTION * m * sp:
        return True, ex, ey
    k = h_dir * N * c / m
    wx = vx - k * Zx
    wy = vy - k * Zy
    wn = math.sqrt(wx * wx + wy * wy)
    if wn == 0.0:
        return False, ex, ey
    gw = (Zx * wx + Zy * wy) / wn
    if wn * m * math.sqrt(1.0 + gw * gw) <= h_dir * Q:
        return False, ex, ey  # friction (horizontal part Q cos) stops it: held along e = v/|v|
    if wx * ex + wy * ey < 0.0:
        wn = -wn
    return False, wx / wn, wy / wn


@njit(cache=True)
def plane_rk4(x, y, vx, vy, tl, dt, ex, ey, h_dir, xa, ya, f, h, P, tu, tq, tqu):
    """One classical RK4 step of length ``dt`` [s] from ``tl``: the new ``(x, y, vx, vy)``, with
    the friction directed by :func:`step_direction` (judged on the step ``h_dir`` [s], the one
    being located in: constant over a root search, so the partial steps are one family)."""
    m = P[I_MASS]
    N, Zx, Zy, c, Q = plane_load_friction(x, y, vx, vy, tl, xa, ya, f, h, P, tu, tq, tqu)
    follow, ex, ey = step_direction(vx, vy, ex, ey, h_dir, N, Zx, Zy, c, Q, m)
    ax1, ay1 = _accel(N, Zx, Zy, c, Q, ex, ey, m)
    floor = STAGE_FLOOR * math.sqrt(vx * vx + vy * vy)
    hd = 0.5 * dt
    x2, y2, vx2, vy2 = x + hd * vx, y + hd * vy, vx + hd * ax1, vy + hd * ay1
    ax2, ay2 = plane_accel(x2, y2, vx2, vy2, tl + hd, ex, ey, follow, floor, xa, ya, f, h, P, tu,
                           tq, tqu)
    x3, y3, vx3, vy3 = x + hd * vx2, y + hd * vy2, vx + hd * ax2, vy + hd * ay2
    ax3, ay3 = plane_accel(x3, y3, vx3, vy3, tl + hd, ex, ey, follow, floor, xa, ya, f, h, P, tu,
                           tq, tqu)
    x4, y4, vx4, vy4 = x + dt * vx3, y + dt * vy3, vx + dt * ax3, vy + dt * ay3
    ax4, ay4 = plane_accel(x4, y4, vx4, vy4, tl + dt, ex, ey, follow, floor, xa, ya, f, h, P, tu,
                           tq, tqu)
    w = dt / 6.0
    return (x + w * (vx + 2.0 * vx2 + 2.0 * vx3 + vx4), y + w * (vy + 2.0 * vy2 + 2.0 * vy3 + vy4),
            vx + w * (ax1 + 2.0 * ax2 + 2.0 * ax3 + ax4),
            vy + w * (ay1 + 2.0 * ay2 + 2.0 * ay3 + ay4))


@njit(cache=True)
def plane_stick_state(x, y, tl, xa, ya, f, h, P, tu, tq, tqu):
    """A part at rest at ``(x, y)``: ``(margin [N], N - N_min [N], ex, ey)``, the stick margin
    ``Q(N) - |N| |grad Z|`` (the disc ``|F_t| <= Q`` holds while it is >= 0), the load above
    pull-off, and the unit horizontal direction of the unbalanced force ``-N grad Z`` (where it
    breaks away to; ``(1, 0)`` on a level spot)."""
    N, Zx, Zy, c, _ = plane_normal_load(x, y, 0.0, 0.0, tl, xa, ya, f, h, P)
    Q = plane_friction(N, P, tu, tq, tqu)
    gn = math.sqrt(Zx * Zx + Zy * Zy)
    if gn > 0.0 and N != 0.0:
        sg = -1.0 if N > 0.0 else 1.0
        ex, ey = sg * Zx / gn, sg * Zy / gn
    else:
        ex, ey = 1.0, 0.0
    return Q - abs(N * gn), N - P[I_NMIN], ex, ey


refresh_jit_cache(globals())
