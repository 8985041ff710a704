"""Actuator arrays and firing schedules (docs/physics.md §1.1), validated, SI units.

A schedule is a sequence of firings; each names an actuator of the array, its stroke 'frequency'
``f`` [Hz] (the stroke lasts ``1/f``), its stroke height ``h`` [m] and the delay [s] before it
starts, measured from the end of the previous stroke (from t = 0 for the first). At most one
actuator is active at a time.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy.typing as npt

import numpy as np

from .materials import ParameterError, check_range


@dataclass(frozen=True)
class ActuatorArray:
    """Actuator positions along x [m] (strictly increasing)."""

    positions: tuple[float, ...]

    def __post_init__(self) -> None:
        pos = tuple(check_range("ActuatorArray", f"positions[{i}]", p, unit="m")
                    for i, p in enumerate(self.positions))
        if not pos:
            raise ParameterError("ActuatorArray.positions is empty: need at least one actuator")
        if any(b <= a for a, b in zip(pos[:-1], pos[1:], strict=True)):
            raise ParameterError(f"ActuatorArray.positions = {pos} must be strictly increasing")
        object.__setattr__(self, "positions", pos)

    @classmethod
    def uniform(cls, count: int, spacing: float, first: float = 0.0) -> ActuatorArray:
        """``count`` [-] actuators, ``spacing`` [m] apart, the first at ``first`` [m]."""
        n = int(check_range("ActuatorArray", "count", count, 1, 10_000))
        sp = check_range("ActuatorArray", "spacing", spacing, 0, 1.0, True, unit="m")
        return cls(tuple(first + sp * i for i in range(n)))

    def __len__(self) -> int:
        return len(self.positions)


@dataclass(frozen=True)
class Firing:
    """One stroke: actuator index, frequency [Hz] (> 0), stroke height [m] (>= 0), delay [s] (>= 0)."""

    actuator: int
    frequency: float
    stroke: float
    delay: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.actuator, (int, np.integer)) or self.actuator < 0:
            raise ParameterError(f"Firing.actuator = {self.actuator!r} is invalid: must be an "
                                 "integer index >= 0")
        object.__setattr__(self, "frequency",
                           check_range("Firing", "frequency", self.frequency, 0, 1e6, True,
                                       unit="Hz"))
        object.__setattr__(self, "stroke",
                           check_range("Firing", "stroke", self.stroke, 0, 1e-2, unit="m"))
        object.__setattr__(self, "delay", check_range("Firing", "delay", self.delay, 0, 1e4,
                                                      unit="s"))


def checked_firings(firings: Iterable[Any], n_actuators: int, owner: str,
                    holder: str) -> tuple[Firing, ...]:
    """``firings`` as a tuple, each a :class:`Firing` of one of ``n_actuators`` [-] actuators;
    ParameterError naming ``owner`` (the schedule class) and ``holder`` (what holds the
    actuators) otherwise."""
    out = tuple(firings)
    for f in out:
        if not isinstance(f, Firing):
            raise ParameterError(f"{owner}.firings must hold Firing objects, got {f!r}")
        if f.actuator >= n_actuators:
            raise ParameterError(f"Firing.actuator = {f.actuator} is invalid: the {holder} has "
                                 f"{n_actuators} actuators")
    return out


@dataclass(frozen=True)
class Schedule:
    """Firings on an actuator array."""

    array: ActuatorArray
    firings: tuple[Firing, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "firings",
                           checked_firings(self.firings, len(self.array), "Schedule", "array"))

    @classmethod
    def single(cls, frequency: float, stroke: float, delay: float = 0.0,
               position: float = 0.0) -> Schedule:
        """One actuator at ``position`` [m] fired once at ``frequency`` [Hz] with ``stroke`` [m]
        after ``delay`` [s]."""
        return cls(ActuatorArray((position,)), (Firing(0, frequency, stroke, delay),))

    @classmethod
    def sequence(cls, array: ActuatorArray, frequency: npt.ArrayLike, stroke: npt.ArrayLike,
                 delay: npt.ArrayLike = 0.0) -> Schedule:
        """Fire every actuator of ``array`` once, in order, at ``frequency`` [Hz] with ``stroke`` [m]
        after ``delay`` [s]; scalars or per-firing sequences."""
        n = len(array)
        f, h, d = (np.broadcast_to(np.asarray(a, float), (n,)) for a in (frequency, stroke, delay))
        return cls(array, tuple(Firing(i, float(f[i]), float(h[i]), float(d[i])) for i in range(n)))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(x_act [m], f [Hz], h [m], delay [s]) as float64 arrays over the firings."""
        xa = np.array([self.array.positions[f.actuator] for f in self.firings], dtype=float)
        f = np.array([fi.frequency for fi in self.firings], dtype=float)
        h = np.array([fi.stroke for fi in self.firings], dtype=float)
        d = np.array([fi.delay for fi in self.firings], dtype=float)
        return xa, f, h, d

