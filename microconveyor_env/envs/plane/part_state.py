"""A part's state between two firings on the plane, to save and to start episodes from.

:class:`PlaneState` is everything the next firings of the plane's envs depend on: the part's
position and velocity in the plane, its simulated time, how many firings of the grid's
actuators it has had, its target, and, with per-episode randomisation on (MicroConveyor2D-v1),
this episode's friction and mass factors and its execution-noise draws. A state whose
randomisation fields are None keeps the env's own draws.
``env.get_state()`` (the batched env: ``get_state(i)``) returns it after any step;
``env.reset(options={"state": s})`` starts an episode from it, and the episode then continues
exactly as the uninterrupted one would (bit for bit on the same machine:
``tests/envs/test_plane_part_state.py``).

What it shares with the line's :class:`~..line.part_state.PartState` (naming ``env_id`` and the
``scene``, the JSON-safe dict form with unit-suffixed keys, the refusal of another scene's state
or of a dict that names none, the speed and time bounds) is :mod:`..core.part_state`.

Bounds (:func:`check_plane_state`; a value outside is refused in one line naming the field, its
value and the range), with ``v_max`` the scene's fastest part
(:func:`~..core.part_state.max_speed`):

| field | unit | allowed | why |
|---|---|---|---|
| ``fired`` | firings | an integer in [0, ``max_firings`` - 1] | a firing must be left |
| ``time_s`` | s | [0, ``max_time``) | the episode's time is not spent |
| ``velocity_m_s`` | m/s | (vx, vy), speed ``hypot(vx, vy)`` at most ``v_max`` | no faster than the surface can drive it |
| ``position_m`` | m | (x, y), each within ``v_max * max_time`` of the start (``start`` ± ``start_jitter``) | no farther than the part can go in the episode's time |
| ``target_m`` | m | (x, y), each within ±10 mm of actuator 0 | where the observation can show it |
| ``friction_factor``, ``mass_factor`` | - | the env's ``friction_factor_range``, ``mass_factor_range`` | what the env draws |
| ``noise`` | - (standard normals) | shape ``(max_firings, 3)``, abs at most 13; only with ``action_noise`` > 0 | numpy's standard normals never reach 12.23 |
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..core.part_state import SavedState, check_fired, check_scene, check_time, max_speed, within
from ..core.randomised_state import check_saved
from . import task as plane_task
from .config import PlaneEnvConfig

__all__ = ["PlaneState", "check_plane_state"]
Pair = tuple[float, float]


@dataclass(frozen=True)
class PlaneState(SavedState):
    """One part on the plane between firings (SI units).

    ``position_m`` (x, y) [m] (actuator 0 at the origin), ``velocity_m_s`` (vx, vy) [m/s],
    ``time_s`` [s] simulated time since the episode began, ``fired`` [-] firings so far,
    ``target_m`` (x, y) [m]; with randomisation, ``friction_factor`` and ``mass_factor`` [-] this
    episode's factors and ``noise`` the ``(max_firings, 3)`` standard normals of its execution
    noise (None: the env's own draws); ``env_id`` and ``scene`` where it was saved (None: built
    in code, taken as the env's own)."""

    REQUIRED: ClassVar[tuple[str, ...]] = ("position_m", "velocity_m_s", "time_s", "fired",
                                           "target_m")
    NESTED: ClassVar[tuple[str, ...]] = ("position_m", "velocity_m_s", "target_m", "noise")

    position_m: Pair
    velocity_m_s: Pair
    time_s: float
    fired: int
    target_m: Pair
    friction_factor: float | None = None
    mass_factor: float | None = None
    noise: tuple[tuple[float, float, float], ...] | None = None
    env_id: str | None = None
    scene: dict[str, Any] | None = field(default=None, hash=False, repr=False)


def _pair(name: str, value: object) -> tuple[object, object]:
    """``value`` as two components, else a one-line ValueError naming ``name``."""
    if isinstance(value, (tuple, list, np.ndarray)) and len(value) == 2:
        return value[0], value[1]
    raise ValueError(f"part state {name} = {value!r} is invalid: must be an (x, y) pair")


def check_plane_state(state: PlaneState | dict, config: PlaneEnvConfig) -> PlaneState:
    """``state`` (a :class:`PlaneState` or its dict) checked against ``config``: of this scene,
    every component finite and within the scene's bounds (module docstring), a firing left, and
    randomisation fields only where the config randomises (factors inside its ranges, noise of
    shape ``(max_firings, 3)``). A one-line ValueError names the field, its value and the
    range."""
    s = state if isinstance(state, PlaneState) else PlaneState.from_dict(state)
    if s.scene is not None:
        check_scene(s, config)
    fired = check_fired(s.fired, config.max_firings)
    v_max = max_speed(config)
    reach = v_max * config.max_time + config.start_jitter
    pos = []
    for k, (c, start) in enumerate(zip(_pair("position_m", s.position_m), config.start,
                                       strict=True)):
        pos.append(within(f"position_m[{k}]", c, start - reach, start + reach, "mm", 1e3,
                          f"reachable from the start in max_time at {v_max * 1e3:.6g} mm/s"))
    why_v = "twice the peak surface speed of the fastest, highest stroke plus a slide down its bump"
    vel = [within(f"velocity_m_s[{k}]", c, -v_max, v_max, "mm/s", 1e3, why_v)
           for k, c in enumerate(_pair("velocity_m_s", s.velocity_m_s))]
    within("speed |velocity_m_s|", math.hypot(*vel), 0.0, v_max, "mm/s", 1e3, why_v)
    t = check_time(s.time_s, config)
    limit = plane_task.OBS_BOUND * plane_task.LENGTH_SCALE
    tgt = [within(f"target_m[{k}]", c, -limit, limit, "mm", 1e3,
                  "where the observation can show it")
           for k, c in enumerate(_pair("target_m", s.target_m))]
    ff, mf, noise = check_saved(s.friction_factor, s.mass_factor, s.noise, config,
                                config.max_firings)
    return PlaneState((pos[0], pos[1]), (vel[0], vel[1]), t, fired, (tgt[0], tgt[1]),
                      ff, mf, noise, s.env_id, s.scene)
