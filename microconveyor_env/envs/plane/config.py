"""Validated configuration of MicroConveyor2D-v0 (defaults in
``configs/envs/MicroConveyor2D-v0.yaml``, where every key has its meaning and unit; SI units).

The plane's own dataclass (the 1-D :class:`.config.EnvConfig` describes a line of actuators); the
checks are the 1-D ones wherever a field means the same thing.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from ...env_ids import PLANE_MAX_FIRINGS
from ...physics.kinematics import SHAPES
from ...physics.materials import ParameterError, check_range
from ...physics.validation import (
    MAX_STEPS,
    MIN_DT,
    MIN_WAVELENGTH,
    check_max_steps,
    check_step_budget,
    kinematics_level,
)

CONFIG_FILE = "MicroConveyor2D-v0.yaml"
MAX_FIRINGS = PLANE_MAX_FIRINGS  # an episode has at most this many steps (spec.max_episode_steps)
MAX_GRID = 100       # actuators per side at most
MIN_LENGTH = 1e-9    # m, as the 1-D config: below it distance / tolerance overflows
_RANGES = {  # field -> (lo, hi, lo_open, unit)
    "spacing": (1e-6, 1e-2, False, "m"), "wavelength": (MIN_WAVELENGTH, 1.0, False, "m"),
    "start_jitter": (0.0, 1e-2, False, "m"), "tolerance": (MIN_LENGTH, 1e-2, False, "m"),
    "pick_reach": (0.0, 1e-2, False, "m"),
    "time_cost": (0.0, 1e6, False, "1/s"), "success_bonus": (0.0, 1e6, False, "-"),
    "detach_penalty": (0.0, 1e6, True, "-"), "max_time": (1e-6, 1e6, False, "s"),
    "dt": (MIN_DT, 1.0, False, "s"),
}
_PAIRS = {"freq_range": (0.0, 1e6, "Hz"), "stroke_range": (0.0, 1e-2, "m"),
          "delay_range": (0.0, 1e4, "s")}


def _integer(name: str, value: Any, lo: int, hi: int) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, float, np.integer))
            or not math.isfinite(value) or value != int(value) or not lo <= value <= hi):
        raise ParameterError(f"PlaneEnvConfig.{name} = {value!r} is invalid: must be an integer "
                             f"in [{lo}, {hi}]")
    return int(value)


@dataclass(frozen=True)
class PlaneEnvConfig:
    """All settings of MicroConveyor2D-v0 (SI units; meanings in its YAML file)."""

    preset: str = "conveyor"
    nx: int = 5                       # [-] actuators along x
    ny: int = 5                       # [-] actuators along y
    spacing: float = 0.5e-3           # [m] grid pitch
    shape: str = "gaussian"
    wavelength: float = 2.0e-3        # [m] bump wavelength
    start: tuple = (1.0e-3, 1.0e-3)   # [m] (x, y) start of the part
    start_jitter: float = 0.0         # [m] uniform jitter +- of each start coordinate
    tolerance: float = 50e-6          # [m] Euclidean success radius
    pick_reach: float = 0.5e-3        # [m] actions 0-1 times this: offset of the aim point
    max_firings: int = 8              # [-] firings per episode at most
    freq_range: tuple = (200.0, 2000.0)        # [Hz]
    stroke_range: tuple = (100e-6, 200e-6)     # [m]
    delay_range: tuple = (0.0, 0.1)            # [s]
    progress_scale: float | None = None        # [m] None: the tolerance
    progress_horizon: float | None = None      # [m] None: twice the farthest start-to-target
    time_cost: float = 1.0            # [1/s]
    success_bonus: float = 10.0       # [-]
    detach_penalty: float = 10.0      # [-]
    max_time: float = 1.0             # [s]
    stop_at_target: bool = True
    kinematics: str = "reduced"
    dt: float = 1e-4                  # [s]
    min_steps: int = 48               # [-]
    num_threads: int | None = None    # batched env only
    max_steps: int = MAX_STEPS        # [-]

    def __post_init__(self) -> None:
        for name, (lo, hi, lo_open, unit) in _RANGES.items():
            object.__setattr__(self, name, check_range("PlaneEnvConfig", name, getattr(self, name),
                                                       lo, hi, lo_open, unit=unit))
        if self.progress_scale is None:
            object.__setattr__(self, "progress_scale", self.tolerance)
        object.__setattr__(self, "progress_scale", check_range(
            "PlaneEnvConfig", "progress_scale", self.progress_scale, MIN_LENGTH, 1.0, unit="m"))
        object.__setattr__(self, "nx", _integer("nx", self.nx, 1, MAX_GRID))
        object.__setattr__(self, "ny", _integer("ny", self.ny, 1, MAX_GRID))
        object.__setattr__(self, "max_firings", _integer("max_firings", self.max_firings, 1,
                                                         MAX_FIRINGS))
        object.__setattr__(self, "min_steps", _integer("min_steps", self.min_steps, 2, 100000))
        if self.num_threads is not None:
            object.__setattr__(self, "num_threads",
                               _integer("num_threads", self.num_threads, 1, 1024))
        if not isinstance(self.stop_at_target, bool):
            raise ParameterError(f"PlaneEnvConfig.stop_at_target = {self.stop_at_target!r} is "
                                 "invalid: must be true or false")
        self._check_pairs()
        self._check_start_and_horizon()
        object.__setattr__(self, "max_steps", check_max_steps("PlaneEnvConfig", self.max_steps))
        check_step_budget("PlaneEnvConfig (dt, freq_range, max_firings)",
                          [self.freq_range[0]] * self.max_firings, self.dt, self.min_steps,
                          self.max_steps, self.max_time)
        if isinstance(self.kinematics, str):
            object.__setattr__(self, "kinematics",
                               kinematics_level(self.kinematics, "PlaneEnvConfig.kinematics"))
        for name, allowed in (("shape", tuple(SHAPES)), ("kinematics", ("reduced", "exact"))):
            if getattr(self, name) not in allowed:
                raise ParameterError(f"PlaneEnvConfig.{name} = {getattr(self, name)!r} is "
                                     f"invalid: must be one of {allowed}")
        if not isinstance(self.preset, str) or not self.preset:
            raise ParameterError(f"PlaneEnvConfig.preset = {self.preset!r} is invalid: must be "
                                 "a preset name or YAML path")

    def _check_pairs(self) -> None:
        for name, (lo, hi, unit) in _PAIRS.items():
            pair = getattr(self, name)
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise ParameterError(f"PlaneEnvConfig.{name} = {pair!r} is invalid: must be "
                                     "[low, high]")
            a = check_range("PlaneEnvConfig", f"{name}[0]", pair[0], lo, hi, unit=unit)
            b = check_range("PlaneEnvConfig", f"{name}[1]", pair[1], lo, hi, unit=unit)
            if b < a:
                raise ParameterError(f"PlaneEnvConfig.{name} = {pair!r} is invalid: low > high")
            object.__setattr__(self, name, (a, b))
        if self.freq_range[0] <= 0:
            raise ParameterError(f"PlaneEnvConfig.freq_range = {self.freq_range!r} is invalid: "
                                 "frequencies must be > 0 Hz")

    def _check_start_and_horizon(self) -> None:
        s = self.start
        if not isinstance(s, (list, tuple)) or len(s) != 2:
            raise ParameterError(f"PlaneEnvConfig.start = {s!r} is invalid: must be [x, y] [m]")
        (x0, x1), (y0, y1) = self.grid_box
        sx = check_range("PlaneEnvConfig", "start[0]", s[0], x0, x1, unit="m")
        sy = check_range("PlaneEnvConfig", "start[1]", s[1], y0, y1, unit="m")
        object.__setattr__(self, "start", (sx, sy))
        if self.progress_horizon is None:
            object.__setattr__(self, "progress_horizon", 2.0 * self.farthest_target)
        object.__setattr__(self, "progress_horizon", check_range(
            "PlaneEnvConfig", "progress_horizon", self.progress_horizon, MIN_LENGTH, 10.0,
            unit="m"))
        horizon: Any = self.progress_horizon
        if horizon < self.farthest_target:
            raise ParameterError(f"PlaneEnvConfig.progress_horizon = {self.progress_horizon!r} "
                                 f"is invalid: must be >= the farthest start-to-target distance "
                                 f"{self.farthest_target!r} m, so all progress from the start is "
                                 "paid")

    @classmethod
    def from_yaml(cls, path: str | None = None, **overrides: object) -> PlaneEnvConfig:
        """Defaults from ``configs/envs/MicroConveyor2D-v0.yaml`` (or ``path``), then
        ``overrides``."""
        from ...presets import parse_yaml

        if path is None:
            text = (resources.files("microconveyor_env.configs") / "envs"
                    / CONFIG_FILE).read_text()
        else:
            with open(path) as fh:
                text = fh.read()
        data = parse_yaml(text, f"env config {path or CONFIG_FILE}") or {}
        if not isinstance(data, dict):
            raise ParameterError(f"env config {path!r} is not a YAML mapping")
        data = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        data.update(overrides)
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ParameterError(f"PlaneEnvConfig: unknown keys {unknown}; known: {sorted(known)}")
        return cls(**data)

    # ------------------------------------------------------------------ derived
    @property
    def n_actuators(self) -> int:
        """Actuators in the grid, ``nx * ny`` [-]."""
        return self.nx * self.ny

    @property
    def grid_box(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """``((x_lo, x_hi), (y_lo, y_hi))`` [m]: the grid's bounding box, where targets are."""
        return (0.0, (self.nx - 1) * self.spacing), (0.0, (self.ny - 1) * self.spacing)

    @property
    def centre(self) -> tuple[float, float]:
        """The grid's centre [m]."""
        (x0, x1), (y0, y1) = self.grid_box
        return 0.5 * (x0 + x1), 0.5 * (y0 + y1)

    @property
    def farthest_target(self) -> float:
        """The farthest a drawn target can be from a start [m] (a corner of the grid's box, the
        start jittered)."""
        (x0, x1), (y0, y1) = self.grid_box
        j = self.start_jitter
        dx = max(abs(x1 - self.start[0]), abs(self.start[0] - x0)) + j
        dy = max(abs(y1 - self.start[1]), abs(self.start[1] - y0)) + j
        return math.hypot(dx, dy)

    @property
    def actuator_positions(self) -> tuple[tuple[float, float], ...]:
        """``((x, y), ...)`` [m], index ``i + nx j`` at ``(i, j) * spacing``."""
        return tuple((i * self.spacing, j * self.spacing)
                     for j in range(self.ny) for i in range(self.nx))

    @property
    def log_freq_span(self) -> float:
        """ln(freq_range[1] / freq_range[0]) [-] (the action decoding's, :mod:`.actions`)."""
        return math.log(self.freq_range[1] / self.freq_range[0])

    action_noise = 0.0  # [action units] no execution noise in MicroConveyor2D-v0
