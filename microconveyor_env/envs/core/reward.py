"""The reward and success every scene's task scores with, in distances to the target.

A scene's task constants (the line's :class:`~..line.task.TaskConstants`, the plane's
:class:`~..plane.task.PlaneTaskConstants`: NamedTuples read by field name in compiled code)
hold the fields :data:`REWARD_FIELDS`, built by :func:`reward_constants`; the compiled
functions here take a distance to the target [m] (the line's ``|x - target|``, the plane's
Euclidean one), so both scenes score with the very same arithmetic. Why the reward ranks
episodes as it does: the line's :mod:`..line.task`.
"""
from __future__ import annotations

from typing import Any

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel

# the task constants the reward, success and delivery read (each scene's NamedTuple has them)
REWARD_FIELDS = ("max_time", "progress_scale", "time_cost", "success_bonus", "detach_penalty",
                 "tolerance", "progress_horizon", "stop_at_target")


def reward_constants(cfg: Any) -> dict[str, Any]:
    """The :data:`REWARD_FIELDS` of a scene's config, typed as compiled code reads them."""
    return {"max_time": float(cfg.max_time), "progress_scale": float(cfg.progress_scale),
            "time_cost": float(cfg.time_cost), "success_bonus": float(cfg.success_bonus),
            "detach_penalty": float(cfg.detach_penalty), "tolerance": float(cfg.tolerance),
            "progress_horizon": float(cfg.progress_horizon),
            "stop_at_target": bool(cfg.stop_at_target)}


@njit(cache=True)
def potential(dist: float, TC: Any) -> float:
    """Phi = -min(distance to the target [m], progress_horizon) / progress_scale."""
    return -min(dist, TC.progress_horizon) / TC.progress_scale


@njit(cache=True)
def is_success(code: int, dist: float, TC: Any) -> bool:
    """At rest within the tolerance of the target (``dist`` [m] from it)."""
    return code == kernel.REST and dist <= TC.tolerance


@njit(cache=True)
def reward(code: int, d_old: float, d_new: float, t_old: float, t_new: float,
           TC: Any) -> float:
    """Potential-based progress (distances to the target [m] before and after), minus the time
    cost, plus the success bonus; on detachment the horizon's potential, the time cost up to
    ``max_time`` and the penalty."""
    if code == kernel.DETACHED:
        return -TC.progress_horizon / TC.progress_scale - potential(d_old, TC) \
            - TC.time_cost * (max(TC.max_time, t_new) - t_old) - TC.detach_penalty
    r = potential(d_new, TC) - potential(d_old, TC) - TC.time_cost * (t_new - t_old)
    if is_success(code, d_new, TC):
        r += TC.success_bonus
    return r


refresh_jit_cache(globals())
