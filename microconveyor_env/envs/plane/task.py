"""The reach-target task of MicroConveyor2D-v0: start, actuator pick, observation, reward, success.

The plane's counterpart of the line's :mod:`..line.task`, with the Euclidean distance ``|p - target|`` in place of
``|x - target|``: the potential ``Phi(p) = -min(|p - target|, H) / progress_scale`` saturating at
``H = progress_horizon`` (validated >= the farthest start-to-target distance), the time cost, the
success bonus (at rest within ``tolerance``, a disc) and detachment scored as the worst state
there is (the horizon's potential, the time cost up to ``max_time``, then ``detach_penalty`` >
0), with the arithmetic every scene shares (:mod:`..core.reward`). The 1-D task's ranking
therefore carries over word for word, for every configuration validation accepts:

* any episode that ends at rest returns more than any episode that detaches;
* at equal simulated time, resting closer to the target returns more (strictly, within the
  horizon), and resting within tolerance adds ``success_bonus`` on top.

``tests/envs/test_plane_env_reward.py`` checks both as hypothesis properties.

Which actuator fires (:func:`pick`): actions 0-1 in [-1, 1] (clipped) times ``pick_reach`` are
an offset from the part; the actuator of the grid nearest to that aim point fires (ties to the
lower index; an aim point off the grid fires the nearest edge actuator).
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel
from ...physics.plane import kernel as plane_kernel
from ..core.randomisation import uniform
from ..core.reward import is_success, potential, reward, reward_constants

__all__ = ["LENGTH_SCALE", "OBS_BOUND", "OBS_DIM", "PlaneTaskConstants", "constants",
           "initial_state", "is_success", "observe_part", "pick", "potential", "reward",
           "stop_if_delivered"]

OBS_DIM = 10
OBS_BOUND = 10.0          # observations are clipped to [-OBS_BOUND, OBS_BOUND]
LENGTH_SCALE = 1e-3       # m: position error and target are divided by this
VELOCITY_SCALE = 0.1      # m/s
PICK_DIMS = 2             # actions 0-1: the aim point's offset


class PlaneTaskConstants(NamedTuple):
    """The task's constants (compiled code reads the fields by name)."""

    nx: int                  # [-]
    ny: int                  # [-]
    spacing: float           # m
    reach: float             # m, pick_reach
    cx: float                # m, grid centre
    cy: float                # m
    max_firings: int         # [-]
    max_time: float          # s
    progress_scale: float    # m
    time_cost: float         # 1/s
    success_bonus: float     # -
    detach_penalty: float    # -
    tolerance: float         # m
    progress_horizon: float  # m
    stop_at_target: bool


def constants(cfg: Any) -> PlaneTaskConstants:
    """The task constants of ``cfg`` (a :class:`~.config.PlaneEnvConfig`)."""
    cx, cy = cfg.centre
    return PlaneTaskConstants(
        nx=int(cfg.nx), ny=int(cfg.ny), spacing=float(cfg.spacing), reach=float(cfg.pick_reach),
        cx=float(cx), cy=float(cy), max_firings=int(cfg.max_firings), **reward_constants(cfg))


def initial_state(cfg: Any, rng: np.random.Generator,
                  target: tuple[float, float] | None = None) -> tuple[float, float, float, float]:
    """``(x0, y0, tx, ty)`` [m] of a new episode: the part at ``start`` (each coordinate jittered
    uniformly by up to ``start_jitter``), the target uniform on the grid's box unless given
    (already checked). The target is drawn first, then the jitter, so the jitter does not change
    the targets of a seed."""
    (x0, x1), (y0, y1) = cfg.grid_box
    tx, ty = uniform(rng, x0, x1), uniform(rng, y0, y1)
    sx, sy = cfg.start
    if cfg.start_jitter:
        sx += uniform(rng, -1.0, 1.0) * cfg.start_jitter
        sy += uniform(rng, -1.0, 1.0) * cfg.start_jitter
    if target is not None:
        tx, ty = target
    return float(sx), float(sy), float(tx), float(ty)


@njit(cache=True)
def _nearest(u: float, n: int) -> int:
    """The grid index nearest to ``u`` (in pitches), clipped to [0, n - 1]."""
    k = math.floor(u + 0.5)
    return int(min(max(k, 0), n - 1))


@njit(cache=True)
def pick(x: float, y: float, a0: float, a1: float, TC: PlaneTaskConstants) -> int:
    """The actuator index nearest to the aim point ``(x, y) + reach * clip(a0, a1)`` [m]."""
    ax = x + min(max(a0, -1.0), 1.0) * TC.reach
    ay = y + min(max(a1, -1.0), 1.0) * TC.reach
    return _nearest(ax / TC.spacing, TC.nx) + TC.nx * _nearest(ay / TC.spacing, TC.ny)


@njit(cache=True)
def stop_if_delivered(x, y, vx, vy, t, tx, ty, TC, P, tu, tq, tqu):
    """After a stroke that left the part moving (not the last firing): with ``stop_at_target``,
    if the part left alone comes to rest within the tolerance of the target before
    ``max_time``, it does and the outcome is REST; otherwise the state is returned unchanged
    with outcome MOVING (as :func:`.task.stop_if_delivered`)."""
    if TC.stop_at_target:
        xr, yr, _, _, used, rest, _ = plane_kernel.coast(x, y, vx, vy,
                                                         max(TC.max_time - t, 0.0), P, tu, tq,
                                                         tqu)
        if rest and math.hypot(xr - tx, yr - ty) <= TC.tolerance:
            return xr, yr, 0.0, 0.0, t + used, kernel.REST
    return x, y, vx, vy, t, kernel.MOVING


@njit(cache=True)
def observe_part(x, y, vx, vy, t, fired, tx, ty, TC, row):
    """The observation row of one part (the env card's table)."""
    s = TC.spacing
    gx = _nearest(x / s, TC.nx) * s
    gy = _nearest(y / s, TC.ny) * s
    vals = ((x - tx) / LENGTH_SCALE, (y - ty) / LENGTH_SCALE,
            vx / VELOCITY_SCALE, vy / VELOCITY_SCALE,
            (x - gx) / s, (y - gy) / s,
            t / TC.max_time, fired / TC.max_firings,
            (tx - TC.cx) / LENGTH_SCALE, (ty - TC.cy) / LENGTH_SCALE)
    for j in range(OBS_DIM):
        row[j] = min(max(vals[j], -OBS_BOUND), OBS_BOUND)


refresh_jit_cache(globals())
