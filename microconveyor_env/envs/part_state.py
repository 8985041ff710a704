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
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from .common import check_target
from .config import EnvConfig

_FIELDS = ("position_m", "velocity_m_s", "time_s", "fired", "target_m", "friction_factor",
           "mass_factor", "noise")


@dataclass(frozen=True)
class PartState:
    """One part between firings (SI units).

    ``position_m`` [m] (from actuator 1), ``velocity_m_s`` [m/s], ``time_s`` [s] simulated time
    since the episode began, ``fired`` [-] actuators fired so far (the next firing is actuator
    ``fired + 1``), ``target_m`` [m]; with randomisation, ``friction_factor`` and ``mass_factor``
    [-] this episode's factors and ``noise`` the ``(n_actuators, 3)`` standard normals of its
    execution noise (None: the env's own draws)."""

    position_m: float
    velocity_m_s: float
    time_s: float
    fired: int
    target_m: float
    friction_factor: float | None = None
    mass_factor: float | None = None
    noise: tuple[tuple[float, float, float], ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (the randomisation keys only when set)."""
        d: dict[str, Any] = {k: getattr(self, k) for k in _FIELDS[:5]}
        for k in _FIELDS[5:]:
            val = getattr(self, k)
            if val is not None:
                d[k] = [list(r) for r in val] if k == "noise" else val
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PartState:
        """The state a dict of :meth:`to_dict` describes (unknown or missing keys refused)."""
        if not isinstance(d, dict):
            raise ValueError(f"a part state must be a dict or PartState, got {type(d).__name__}")
        unknown = sorted(set(d) - set(_FIELDS))
        missing = [k for k in _FIELDS[:5] if k not in d]
        if unknown or missing:
            raise ValueError(f"part state: unknown keys {unknown}, missing keys {missing} "
                             f"(keys: {list(_FIELDS)})")
        noise = d.get("noise")
        return cls(**{**d, "noise": None if noise is None else tuple(map(tuple, noise))})


def _real(name: str, value: object, lo: float = -math.inf, hi: float = math.inf,
          unit: str = "") -> float:
    x = math.nan
    if isinstance(value, (numbers.Real, np.floating, np.integer)) and not isinstance(
            value, (bool, np.bool_)):
        x = float(value)
    if not (math.isfinite(x) and lo <= x <= hi):
        raise ValueError(f"part state {name} = {value!r} is invalid: must be finite in "
                         f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''}")
    return x


def check_state(state: PartState | dict, config: EnvConfig) -> PartState:
    """``state`` (a :class:`PartState` or its dict) checked against ``config``: a firing left
    (``fired < n_actuators``), time in [0, max_time), finite position and velocity, a valid
    target, and randomisation fields only where the config randomises (factors inside its
    ranges, noise of shape ``(n_actuators, 3)``)."""
    s = state if isinstance(state, PartState) else PartState.from_dict(state)
    n = config.n_actuators
    fired = s.fired
    if (isinstance(fired, (bool, np.bool_)) or not isinstance(fired, (numbers.Integral,))
            or not 0 <= int(fired) < n):
        raise ValueError(f"part state fired = {fired!r} is invalid: must be an integer in "
                         f"[0, {n - 1}] (a firing must be left)")
    limit = 10.0  # m: far beyond any scene (positions are finite, the check catches NaN/inf)
    x = _real("position_m", s.position_m, -limit, limit, "m")
    v = _real("velocity_m_s", s.velocity_m_s, unit="m/s")
    t = _real("time_s", s.time_s, 0.0, config.max_time, "s")
    if t >= config.max_time:
        raise ValueError(f"part state time_s = {t!r} is invalid: the episode's max_time "
                         f"({config.max_time} s) is spent")
    target = check_target(s.target_m)
    ff, mf, noise = s.friction_factor, s.mass_factor, s.noise
    for name, val, rng in (("friction_factor", ff, config.friction_factor_range),
                           ("mass_factor", mf, config.mass_factor_range)):
        if val is not None:
            _real(name, val, *rng)
    if noise is not None:
        arr = np.asarray(noise, dtype=float)
        if config.action_noise <= 0.0:
            raise ValueError("part state noise is given but the env has no execution noise "
                             "(action_noise = 0)")
        if arr.shape != (n, 3) or not np.all(np.isfinite(arr)):
            raise ValueError(f"part state noise must be ({n}, 3) finite numbers, got shape "
                             f"{arr.shape}")
        noise = tuple(map(tuple, arr.tolist()))
    return PartState(x, v, t, int(fired), target,
                     None if ff is None else float(ff), None if mf is None else float(mf),
                     noise)


def reset_state(options: dict[str, Any] | None) -> Any:
    """The ``"state"`` of reset ``options`` (None without one); refuses it beside a ``"target"``
    (the state holds its target)."""
    if not options or options.get("state") is None:
        return None
    if "target" in options:
        raise ValueError("reset options: give 'state' (which holds its target) or 'target', "
                         "not both")
    return options["state"]
