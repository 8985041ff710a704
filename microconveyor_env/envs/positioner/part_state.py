"""A part's state between two firings of MicroPositioner-v0, to save and to start episodes
from.

:class:`PositionerState` is everything the next firings and observations depend on: where the
part rests, its simulated time, how many firings it has had, its target, the last firing as
commanded and what it did (the observation shows them), and, with per-episode randomisation on,
this episode's friction and mass factors and execution-noise draws. ``env.get_state()`` returns
it after any step; ``env.reset(options={"state": s})`` continues the episode from it, bit for
bit on the same machine, observations included (``tests/envs/test_positioner.py``). Between
firings the part is at rest, so the state holds no velocity.

What it shares with the line's and the plane's saved states (naming ``env_id`` and ``scene``,
the JSON-safe dict with unit-suffixed keys, the refusal of another scene's state or of a dict
that names none, the time and position bounds, the randomisation fields) is
:mod:`..core.part_state` and :mod:`..core.randomised_state`.

Bounds (:func:`check_positioner_state`; a value outside is refused in one line):

| field | unit | allowed |
|---|---|---|
| ``fired`` | firings | an integer in [0, ``max_firings`` - 1] (a firing must be left) |
| ``time_s`` | s | [0, ``max_time``) |
| ``position_m``, ``last_step_m`` | m | within a rail's reachable span (:func:`~..rail.part_state.state_bounds`) |
| ``target_m`` | m | abs at most 0.1 (as the line) |
| ``last_frequency``, ``last_stroke`` | action units | [-1, 1] (as commanded, clipped) |
| ``last_offset_m`` | m | within the array's length plus ``pick_reach`` |
| ``friction_factor``, ``mass_factor``, ``noise`` | - | as the line's (noise: ``(max_firings, 3)``) |
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from ..core.part_state import SavedState, check_fired, check_scene, check_time, within
from ..core.randomised_state import check_saved
from ..rail.part_state import state_bounds
from ..rail.step import MAX_TARGET
from .config import PositionerConfig

__all__ = ["PositionerState", "check_positioner_state"]


@dataclass(frozen=True)
class PositionerState(SavedState):
    """One part of MicroPositioner-v0 between firings (SI units; module docstring).

    ``position_m`` [m] (from actuator 1), ``time_s`` [s], ``fired`` [-] firings so far,
    ``target_m`` [m]; the last firing: ``last_step_m`` [m] its displacement,
    ``last_frequency`` and ``last_stroke`` [action units] as commanded, ``last_offset_m`` [m] the
    fired actuator's position minus the part's before it (all 0 before the first firing); with
    randomisation, ``friction_factor``, ``mass_factor`` [-] and ``noise`` (``(max_firings, 3)``
    standard normals; None: the env's own draws); ``env_id`` and ``scene`` where it was saved."""

    REQUIRED: ClassVar[tuple[str, ...]] = ("position_m", "time_s", "fired", "target_m",
                                           "last_step_m", "last_frequency", "last_stroke",
                                           "last_offset_m")
    NESTED: ClassVar[tuple[str, ...]] = ("noise",)

    position_m: float
    time_s: float
    fired: int
    target_m: float
    last_step_m: float = 0.0
    last_frequency: float = 0.0
    last_stroke: float = 0.0
    last_offset_m: float = 0.0
    friction_factor: float | None = None
    mass_factor: float | None = None
    noise: tuple[tuple[float, float, float], ...] | None = None
    env_id: str | None = None
    scene: dict[str, Any] | None = field(default=None, hash=False, repr=False)


def check_positioner_state(state: PositionerState | dict,
                           config: PositionerConfig) -> PositionerState:
    """``state`` (a :class:`PositionerState` or its dict) checked against ``config``: of this
    scene, every field finite and within its bounds (module docstring), a firing left. A
    one-line ValueError names the field, its value and the range."""
    s = state if isinstance(state, PositionerState) else PositionerState.from_dict(state)
    if s.scene is not None:
        check_scene(s, config)
    fired = check_fired(s.fired, config.max_firings)
    lo, hi = state_bounds(config).position_m
    why = "reachable from the start in max_time"
    x = within("position_m", s.position_m, lo, hi, "mm", 1e3, why)
    step = within("last_step_m", s.last_step_m, lo - hi, hi - lo, "mm", 1e3, why)
    t = check_time(s.time_s, config)
    target = within("target_m", s.target_m, -MAX_TARGET, MAX_TARGET, "mm", 1e3,
                    "where the observation can show it")
    f, h = (within(name, getattr(s, name), -1.0, 1.0, "", 1.0, "action units, as commanded")
            for name in ("last_frequency", "last_stroke"))
    span = config.actuator_positions[-1] + config.pick_reach + (hi - lo)
    off = within("last_offset_m", s.last_offset_m, -span, span, "mm", 1e3,
                 "the array's length, the reach and the part's span")
    ff, mf, noise = check_saved(s.friction_factor, s.mass_factor, s.noise, config,
                                config.max_firings)
    return PositionerState(x, t, fired, target, step, f, h, off, ff, mf, noise, s.env_id,
                           s.scene)
