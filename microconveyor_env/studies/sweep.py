"""Sweeps of a single firing over one parameter, and the feasible frequency window.

The scene is the seed's single-actuator experiment (docs/physics.md §5): one actuator at x = 0,
the part starting at ``x0`` beside it, one stroke, then coasting to rest. Any of
:data:`SWEEPABLE` can be swept; the others keep their base values.
"""
from __future__ import annotations

import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..physics.materials import ParameterError
from ..physics.schedule import Schedule
from ..physics.simulator import Result, Simulator

# parameter -> (unit, where it goes)
SWEEPABLE = {
    "freq": ("Hz", "firing"), "stroke": ("m", "firing"), "x0": ("m", "start"),
    "wavelength": ("m", "scene"), "profile": ("-", "scene"),
    "mass": ("kg", "contact"), "sigma": ("m", "contact"), "dgamma": ("J/m^2", "contact"),
}
_CONTACT_FIELD = {"mass": "part__mass", "sigma": "surface__sigma", "dgamma": "surface__dgamma"}
MIN_TRAVEL_M = 10e-6  # lower bound of the feasible window: at least this much travel


@dataclass
class Scene:
    """Base values of a single-firing experiment (SI units)."""

    preset: str = "feasibility"
    freq: float = 950.0          # Hz
    stroke: float = 200e-6       # m
    x0: float = 0.125e-3         # m, start position (actuator at 0)
    wavelength: float = 0.6e-3   # m
    profile: str = "gaussian"
    mass: float | None = None    # kg (None: the preset's)
    sigma: float | None = None   # m
    dgamma: float | None = None  # J/m^2
    sim_kw: dict[str, Any] = field(default_factory=dict)  # mode, kinematics, dt, ...

    def simulator(self) -> Simulator:
        """The scene's :class:`Simulator` (the preset's contact with the scene's changes)."""
        from ..presets import load_preset

        contact = load_preset(self.preset).contact
        changes = {_CONTACT_FIELD[k]: getattr(self, k) for k in _CONTACT_FIELD
                   if getattr(self, k) is not None}
        if changes:
            contact = contact.replace(**changes)
        return Simulator.from_keywords(contact, shape=self.profile, wavelength=self.wavelength,
                                       **self.sim_kw)

    def run(self, record: bool = False) -> Result:
        """The scene's single firing (``record``: keep the trajectory)."""
        sim = self.simulator()
        return sim.simulate(Schedule.single(self.freq, self.stroke), x0=self.x0, record=record)


MAX_POINTS = 10_000  # default cap on the points of one sweep (each is a full simulation)


def parse_values(spec: str, param: str, max_points: int = MAX_POINTS) -> list[Any]:
    """``"200:1500:25"`` (start:stop:step, stop included) or ``"a,b,c"``; at least one and at most
    ``max_points`` finite values (else :class:`ParameterError`, before anything is built), in
    ``param``'s unit (:data:`SWEEPABLE`); profile names for ``profile``."""
    usage = (f"--{param} {spec!r} is invalid: use start:stop:step (finite numbers, step > 0, "
             "stop >= start) or a comma-separated list of finite numbers")
    if param == "profile":
        values: list[Any] = [s.strip() for s in spec.split(",") if s.strip()]
    elif ":" in spec:
        try:
            a, b, c = (float(v) for v in spec.split(":"))
        except ValueError:
            raise ParameterError(usage) from None
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            count = np.floor((np.float64(b) - a) / c + 1e-9) + 1
        if not (np.isfinite([a, b, c]).all() and c > 0 and b >= a):
            raise ParameterError(usage)
        _check_count(param, spec, float(count) if np.isfinite(count) else np.inf, max_points)
        values = [a + i * c for i in range(int(count))]
    else:
        try:
            values = [float(v) for v in spec.split(",") if v.strip()]
        except ValueError:
            raise ParameterError(usage) from None
        if not np.isfinite(values).all():
            raise ParameterError(usage)
    if not values:
        raise ParameterError(f"--{param} {spec!r} is invalid: it gives no values")
    _check_count(param, spec, len(values), max_points)
    return values


def _check_count(param: str, spec: str, count: float, max_points: int) -> None:
    if count > max_points:
        raise ParameterError(f"--{param} {spec!r} gives {count:.4g} points, more than the sweep "
                             f"limit of {max_points} (each is a full simulation); use a coarser "
                             "step, or raise the limit (--max-points) if you mean it")


def feasible_window(values: Iterable[Any], travel: Iterable[float],
                    outcomes: Iterable[str]) -> list[Any] | None:
    """[lo, hi]: lowest value with >= 10 um travel (``travel`` [m]), highest value below the first
    detachment; in the values' own unit."""
    lo = hi = None
    for v, d, o in zip(values, travel, outcomes, strict=True):
        if o == "detached":
            break
        if lo is None and abs(d) >= MIN_TRAVEL_M:
            lo = v
        if lo is not None:
            hi = v
    return None if lo is None else [lo, hi]


def no_window_reason(travel: Iterable[float], outcomes: Iterable[str]) -> str:
    """Why a sweep has no feasible window, in words (for text and charts)."""
    travel, outcomes = list(travel), list(outcomes)
    if outcomes and all(o == "detached" for o in outcomes):
        return "no window: the part detached at every value"
    if outcomes and outcomes[0] == "detached":
        return "no window: the part detached already at the first value"
    if not any(abs(d) >= MIN_TRAVEL_M for d, o in zip(travel, outcomes, strict=True)
               if o != "detached"):
        return (f"no window: the part never moved {MIN_TRAVEL_M * 1e6:g} µm or more "
                f"({sum(o == 'detached' for o in outcomes)} of {len(outcomes)} values detached)")
    return "no window"


def sweep(scene: Scene, param: str, values: Iterable[Any], progress: bool = True,
          max_points: int = MAX_POINTS) -> dict[str, Any]:
    """Run the scene for each value of ``param`` (in its unit, :data:`SWEEPABLE`); travel [m],
    outcomes and (for freq) the window.
    More than ``max_points`` values are refused."""
    if param not in SWEEPABLE:
        raise ParameterError(f"cannot sweep {param!r}; sweepable: {sorted(SWEEPABLE)}")
    values = list(values)
    if not values:
        raise ParameterError(f"sweep of {param!r}: no values given")
    _check_count(param, f"{len(values)} values", len(values), max_points)
    from tqdm import tqdm

    rows: list[Result] = []
    it = tqdm(values, desc=f"sweep {param}", file=sys.stderr, disable=not progress, leave=False)
    for v in it:
        s = Scene(**{**scene.__dict__, param: v})
        r = s.run()
        rows.append(r)
    travel = [r.displacement_m for r in rows]
    outcomes = [r.outcome for r in rows]
    key = value_key(param)
    out: dict[str, Any] = {
           "param": param, "unit": SWEEPABLE[param][0], "values_key": key, key: list(values),
           "displacement_m": travel, "outcome": outcomes,
           "rest_time_s": [r.rest_time_s for r in rows],
           "detach_time_s": [r.detach_time_s for r in rows],
           "wall_time_s": float(sum(r.wall_time_s for r in rows))}
    if param != "profile":
        suffix = key[len(param):]
        out["window" + suffix] = feasible_window(values, travel, outcomes)
        if out["window" + suffix] is None:
            out["no_window_reason"] = no_window_reason(travel, outcomes)
        ok = [i for i, o in enumerate(outcomes) if o != "detached"]
        if ok:
            best = max(ok, key=lambda i: abs(travel[i]))
            out["max_travel_m"] = abs(travel[best])
            out["max_travel_at" + suffix] = values[best]
    return out


_SUFFIX = {"Hz": "_hz", "m": "_m", "kg": "_kg", "J/m^2": "_J_m2", "-": ""}


def value_key(param: str) -> str:
    """The JSON key of a swept parameter's values: its name with its unit's suffix
    (``freq_hz``, ``stroke_m``, ``profile``); ``window`` and ``max_travel_at`` take the same suffix."""
    return param + _SUFFIX[SWEEPABLE[param][0]]
