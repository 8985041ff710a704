"""A part's state between two firings, to save and to start episodes from.

:class:`PartState` is everything the next firings depend on: the part's position, velocity and
simulated time, how many actuators have fired, the target, and, with per-episode randomisation
on, this episode's friction and mass factors and its execution-noise draws. ``env.get_state()``
returns it after any step; ``env.reset(options={"state": s})`` starts an episode from it, and the
episode then continues exactly as the uninterrupted one would (bit for bit on the same machine:
``tests/envs/test_part_state.py``). That is what model-predictive control needs (plan the
remaining firings from the observed state, :mod:`agents.mpc`), and what lets a long study
restart from a saved state.

As data it is a plain dict of SI numbers with unit-suffixed keys (:meth:`PartState.to_dict`,
:meth:`PartState.from_dict`), JSON-safe. A state *observed* by a controller leaves the
randomisation fields ``None``: an env started from it keeps its own (drawn) factors and noise.

A state names where it was saved: ``env_id`` (the registered id the env was made with, ``None``
for an env made without ``gym.make``) and ``scene``, the env's config fields that are its scene
(:func:`~..core.versions.scene_of`: what :func:`~..core.versions.scene_differences` compares;
per-episode randomisation, runtime knobs and the reward's weights are not the scene). What every
scene's saved state shares (naming the scene, the dict form, the refusal of another scene's
state or of a dict that names none, the common bounds) is :mod:`..core.part_state`, what every
rail's does :mod:`..rail.part_state`; a :class:`PartState` built in code without a scene (as a
controller builds the state it observed) is taken as the
env's own, and ``PartState(**d)`` does the same for a dict.

Bounds (:func:`check_state`; a value outside is refused in one line naming the field, its value
and the range). With ``h``, ``f`` the top of the scene's ``stroke_range`` and ``freq_range``:

| field | unit | allowed | why |
|---|---|---|---|
| ``fired`` | firings | an integer in [0, ``n_actuators`` - 1] | a firing must be left |
| ``time_s`` | s | [0, ``max_time``) | the episode's time is not spent |
| ``velocity_m_s`` | m/s | abs at most ``v_max = 2 (15/4) h f + sqrt(2 g h)`` | the surface moves vertically only and drives the part: its fastest point moves at the quintic stroke's peak speed (15/4) h f; twice that, plus the speed of a slide down the highest bump (g = 9.81 m/s²), bounds the part (random firings, measured: at most 0.51 m/s where the peak is 0.75 m/s and ``v_max`` 1.56 m/s, h = 200 µm, f = 1 kHz; at most 0.40 m/s against ``v_max`` = 15.1 m/s on v0's and v1's scenes) |
| ``position_m`` | m | within ``v_max * max_time`` of the start positions (``-start_offset`` ± ``start_jitter``) | no farther than the part can go in the episode's time |
| ``target_m`` | m | abs at most 0.1 | where the observation can show it (10 x 10 mm) |
| ``friction_factor``, ``mass_factor`` | - | the env's ``friction_factor_range``, ``mass_factor_range`` | what the env draws |
| ``noise`` | - (standard normals) | shape ``(n_actuators, 3)``, abs at most 13; only with ``action_noise`` > 0 | numpy's standard normals never reach 12.23 (P(abs z > 13) = 1.2e-38) |
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from ..core.part_state import SavedState, check_fired, check_scene, check_time, within
from ..core.randomised_state import check_saved
from ..rail.part_state import state_bounds
from ..rail.step import MAX_TARGET
from .config import EnvConfig

__all__ = ["PartState", "check_state"]


@dataclass(frozen=True)
class PartState(SavedState):
    """One part between firings (SI units).

    ``position_m`` [m] (from actuator 1), ``velocity_m_s`` [m/s], ``time_s`` [s] simulated time
    since the episode began, ``fired`` [-] actuators fired so far (the next firing is actuator
    ``fired + 1``), ``target_m`` [m]; with randomisation, ``friction_factor`` and ``mass_factor``
    [-] this episode's factors and ``noise`` the ``(n_actuators, 3)`` standard normals of its
    execution noise (None: the env's own draws); ``env_id`` and ``scene`` where it was saved
    (None: built in code, taken as the env's own; module docstring)."""

    REQUIRED: ClassVar[tuple[str, ...]] = ("position_m", "velocity_m_s", "time_s", "fired",
                                           "target_m")
    NESTED: ClassVar[tuple[str, ...]] = ("noise",)

    position_m: float
    velocity_m_s: float
    time_s: float
    fired: int
    target_m: float
    friction_factor: float | None = None
    mass_factor: float | None = None
    noise: tuple[tuple[float, float, float], ...] | None = None
    env_id: str | None = None
    scene: dict[str, Any] | None = field(default=None, hash=False, repr=False)


def check_state(state: PartState | dict, config: EnvConfig) -> PartState:
    """``state`` (a :class:`PartState` or its dict) checked against ``config``: every field
    finite and within the scene's bounds (module docstring), a firing left, and randomisation
    fields only where the config randomises (factors inside its ranges, noise of shape
    ``(n_actuators, 3)``). A one-line ValueError names the field, its value and the range."""
    s = state if isinstance(state, PartState) else PartState.from_dict(state)
    if s.scene is not None:
        check_scene(s, config)
    n = config.n_actuators
    fired = check_fired(s.fired, n)
    bounds = state_bounds(config)
    v_max, (x_lo, x_hi) = bounds.speed_m_s, bounds.position_m
    x = within("position_m", s.position_m, x_lo, x_hi, "mm", 1e3,
               f"reachable from the start in max_time at {v_max * 1e3:.6g} mm/s")
    v = within("velocity_m_s", s.velocity_m_s, -v_max, v_max, "mm/s", 1e3,
               "twice the peak surface speed of the fastest, highest stroke plus a slide down "
               "its bump")
    t = check_time(s.time_s, config)
    target = within("target_m", s.target_m, -MAX_TARGET, MAX_TARGET, "mm", 1e3,
                    "where the observation can show it")
    ff, mf, noise = check_saved(s.friction_factor, s.mass_factor, s.noise, config, n)
    return PartState(x, v, t, fired, target, ff, mf, noise, s.env_id, s.scene)

