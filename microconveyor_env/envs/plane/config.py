"""Validated configuration of the plane's envs, MicroConveyor2D-v0 and -v1 (defaults in
``configs/envs/MicroConveyor2D-v0.yaml``, where every key has its meaning and unit; v1's beyond
them in ``configs/envs/MicroConveyor2D-v1.yaml``; SI units).

A field that means what a field of the line's :class:`~..line.config.EnvConfig` means is checked
the same way (the checks every scene shares: :mod:`..core.config`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from ...env_ids import PLANE_MAX_FIRINGS
from ...physics.materials import ParameterError, check_range
from ...physics.validation import MAX_STEPS, MIN_DT, MIN_WAVELENGTH
from ..core.config import MIN_LENGTH, SceneConfig
from ..core.randomisation import FACTOR_PAIRS, NOISE_RANGE

CONFIG_FILE = "MicroConveyor2D-v0.yaml"
MAX_FIRINGS = PLANE_MAX_FIRINGS  # an episode has at most this many steps (spec.max_episode_steps)
MAX_GRID = 100       # actuators per side at most
_RANGES = {  # field -> (lo, hi, lo_open, unit)
    "spacing": (1e-6, 1e-2, False, "m"), "wavelength": (MIN_WAVELENGTH, 1.0, False, "m"),
    "start_jitter": (0.0, 1e-2, False, "m"), "tolerance": (MIN_LENGTH, 1e-2, False, "m"),
    "pick_reach": (0.0, 1e-2, False, "m"),
    "time_cost": (0.0, 1e6, False, "1/s"), "success_bonus": (0.0, 1e6, False, "-"),
    "detach_penalty": (0.0, 1e6, True, "-"), "max_time": (1e-6, 1e6, False, "s"),
    "dt": (MIN_DT, 1.0, False, "s"), **NOISE_RANGE,
}
_PAIRS = {"freq_range": (0.0, 1e6, "Hz"), "stroke_range": (0.0, 1e-2, "m"),
          "delay_range": (0.0, 1e4, "s"), **FACTOR_PAIRS}


@dataclass(frozen=True)
class PlaneEnvConfig(SceneConfig):
    """All settings of the plane's envs (SI units; meanings in MicroConveyor2D-v0's YAML file)."""

    CONFIG_FILE: ClassVar[str] = CONFIG_FILE

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
    # per-episode randomisation, off by default (..core.randomisation; docs/randomisation.md)
    action_noise: float = 0.0                   # [action units] sigma on each fired f, h, delay
    friction_factor_range: tuple = (1.0, 1.0)   # [-] factor on the friction Q, uniform per episode
    mass_factor_range: tuple = (1.0, 1.0)       # [-] factor on the part mass, uniform per episode

    def __post_init__(self) -> None:
        self._check_ranges(_RANGES)
        self._check_integer("nx", 1, MAX_GRID)
        self._check_integer("ny", 1, MAX_GRID)
        self._check_integer("max_firings", 1, MAX_FIRINGS)
        self._check_integer("min_steps", 2, 100000)
        self._check_integer("num_threads", 1, 1024, optional=True)
        self._check_flag("stop_at_target")
        self._check_pairs(_PAIRS)
        self._check_start()
        self._check_horizon(self.farthest_target, "")
        self._check_budget_and_choices(self.max_firings, "dt, freq_range, max_firings")
        if not isinstance(self.preset, str) or not self.preset:
            raise ParameterError(f"PlaneEnvConfig.preset = {self.preset!r} is invalid: must be "
                                 "a preset name or YAML path")

    def _check_start(self) -> None:
        s = self.start
        if not isinstance(s, (list, tuple)) or len(s) != 2:
            raise ParameterError(f"PlaneEnvConfig.start = {s!r} is invalid: must be [x, y] [m]")
        (x0, x1), (y0, y1) = self.grid_box
        sx = check_range("PlaneEnvConfig", "start[0]", s[0], x0, x1, unit="m")
        sy = check_range("PlaneEnvConfig", "start[1]", s[1], y0, y1, unit="m")
        self._set("start", (sx, sy))

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
    def episode_limit(self) -> tuple[int, str]:
        """``max_firings`` steps at most."""
        return self.max_firings, f"max_firings = {self.max_firings}"

    @property
    def actuator_positions(self) -> tuple[tuple[float, float], ...]:
        """``((x, y), ...)`` [m], index ``i + nx j`` at ``(i, j) * spacing``."""
        return tuple((i * self.spacing, j * self.spacing)
                     for j in range(self.ny) for i in range(self.nx))
