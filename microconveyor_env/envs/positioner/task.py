"""The positioning task of MicroPositioner-v0: which actuator fires, the observation, the
episode's end.

Which actuator fires (:func:`pick`): action 0 in [-1, 1] (clipped) times ``pick_reach`` is an
offset from the part; the actuator nearest that aim point fires (ties to the lower index; an aim
point off the array fires the nearest end actuator; halfway between two, the downstream one),
as the plane picks its actuator. A resting part moves towards and past the actuator that fires
(docs/physics.md §5, "One actuator"), so aiming ahead of the part carries it downstream and
aiming behind it carries it back.

Start and target are every rail's (:func:`..rail.parts.initial_state`); reward and success the
line's (:mod:`..line.task`, :mod:`..core.reward`):
the potential ``-min(|x - target|, H) / progress_scale``, the time cost, the success bonus when
the part rests within the tolerance, detachment scored as the worst state there is. Every step
ends at rest, so success can be decided after any step; the episode then ends.

The observation (:func:`observe_part`) is what a rig's camera and controller know between two
firings: where the part rests (against the target and against the array), and the last firing
as commanded with what it did. The last firing is one observed transition of the dynamics: with
the friction and mass factors hidden, the displacement a known firing gave from a known offset
tells a controller how this episode's part responds.
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ..core.reward import is_success, potential, reward, reward_constants

__all__ = ["COARSE_SCALE", "FINE_SCALE", "OBS_BOUND", "OBS_DIM", "PositionerTaskConstants",
           "constants", "is_success", "observe_part", "pick", "potential", "reward"]

OBS_DIM = 12
OBS_BOUND = 10.0        # observations are clipped to [-OBS_BOUND, OBS_BOUND]
COARSE_SCALE = 2e-3     # m: the position error seen over +-20 mm
FINE_SCALE = 10e-6      # m: sign(e) log(1 + |e| / FINE_SCALE), fine near the target and
                        # never clipped (7.6 at 20 mm)
STEP_SCALE = 1e-3       # m: the last displacement
ARRAY_SCALE = 10e-3     # m: position and target along the array


class PositionerTaskConstants(NamedTuple):
    """The task's constants (compiled code reads the fields by name)."""

    n_actuators: int         # [-]
    spacing: float           # m
    reach: float             # m, pick_reach
    max_firings: int         # [-]
    max_time: float          # s
    progress_scale: float    # m
    time_cost: float         # 1/s
    success_bonus: float     # -
    detach_penalty: float    # -
    tolerance: float         # m
    progress_horizon: float  # m
    stop_at_target: bool


def constants(cfg: Any) -> PositionerTaskConstants:
    """The task constants of ``cfg`` (a :class:`~.config.PositionerConfig`)."""
    return PositionerTaskConstants(
        n_actuators=int(cfg.n_actuators), spacing=float(cfg.spacing),
        reach=float(cfg.pick_reach), max_firings=int(cfg.max_firings), **reward_constants(cfg))


@njit(cache=True)
def nearest(x, TC):
    """Index of the actuator nearest ``x`` [m] (actuator i at i * spacing; a point halfway
    between two picks the downstream one)."""
    j = int(math.floor(x / TC.spacing + 0.5))
    return min(max(j, 0), TC.n_actuators - 1)


@njit(cache=True)
def pick(x, a0, TC):
    """The actuator that fires for action 0 ``a0`` from a part at ``x`` [m] (module docstring)."""
    return nearest(x + min(max(a0, -1.0), 1.0) * TC.reach, TC)


@njit(cache=True)
def observe_part(x, t, fired, target, last_step, last_f, last_h, last_off, TC, row):
    """The observation row of one part (the env card's table)."""
    s = TC.spacing
    err = x - target
    has = 1.0 if fired > 0 else 0.0
    fine = math.copysign(math.log1p(abs(err) / FINE_SCALE), err)
    vals = (err / COARSE_SCALE, fine, (nearest(x, TC) * s - x) / s,
            last_step / STEP_SCALE, last_f, last_h, last_off / s, has,
            fired / TC.max_firings, t / TC.max_time, target / ARRAY_SCALE, x / ARRAY_SCALE)
    for j in range(OBS_DIM):
        row[j] = min(max(vals[j], -OBS_BOUND), OBS_BOUND)


refresh_jit_cache(globals())
