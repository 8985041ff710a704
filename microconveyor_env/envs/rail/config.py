"""Validated configuration every rail's scene builds on (a linear array of actuators: the line,
MicroConveyor-v0/-v1, and the positioner, MicroPositioner-v0; SI units). The checks every scene
shares: :mod:`..core.config`; randomisation's bounds: :mod:`..core.randomisation`."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ...env_ids import MAX_ACTUATORS
from ...physics.materials import ParameterError
from ...physics.validation import MAX_STEPS, MIN_DT, MIN_WAVELENGTH
from ..core.config import MIN_LENGTH, SceneConfig
from ..core.randomisation import FACTOR_PAIRS, NOISE_RANGE
from .step import MAX_TARGET

_RANGES = {  # field -> (lo, hi, lo_open, unit)
    "spacing": (1e-6, 1.0, False, "m"), "wavelength": (MIN_WAVELENGTH, 1.0, False, "m"),
    "start_offset": (0.0, 1.0, False, "m"), "start_jitter": (0.0, 1.0, False, "m"),
    "tolerance": (MIN_LENGTH, 1.0, False, "m"),
    "time_cost": (0.0, 1e6, False, "1/s"), "success_bonus": (0.0, 1e6, False, "-"),
    "detach_penalty": (0.0, 1e6, True, "-"), "max_time": (1e-6, 1e6, False, "s"),
    "dt": (MIN_DT, 1.0, False, "s"), **NOISE_RANGE,
}
_PAIRS = {"target_range": (0.0, MAX_TARGET, "m"), "freq_range": (0.0, 1e6, "Hz"),
          "stroke_range": (0.0, 1e-2, "m"), "delay_range": (0.0, 1e4, "s"), **FACTOR_PAIRS}


@dataclass(frozen=True)
class RailConfig(SceneConfig):
    """The settings of a rail's scene (SI units; ``configs/envs/MicroConveyor-v0.yaml`` gives
    each field's meaning, unit and MicroConveyor-v0's value). ``stop_at_target`` and
    ``observe_history`` are the line's task options; a scene that fixes them checks its values
    before these checks. ``fires_from_rest``: every firing of the scene starts with the part at
    rest (what its firing map tabulates: :mod:`.firing_map`)."""

    fires_from_rest: ClassVar[bool] = False

    preset: str = "feasibility"
    n_actuators: int = 5
    spacing: float = 0.5e-3
    shape: str = "gaussian"
    wavelength: float = 0.6e-3
    start_offset: float = 0.15e-3
    start_jitter: float = 0.0
    target_range: tuple = (0.5e-3, 3e-3)
    tolerance: float = 50e-6
    freq_range: tuple = (200.0, 10000.0)
    stroke_range: tuple = (100e-6, 200e-6)
    delay_range: tuple = (0.0, 0.1)
    progress_scale: float | None = None  # None: the tolerance
    progress_horizon: float | None = None  # None: twice the farthest start-to-target distance
    time_cost: float = 1.0
    success_bonus: float = 10.0
    detach_penalty: float = 10.0
    max_time: float = 1.0
    stop_at_target: bool = True  # end the episode once the part would rest within tolerance
    mode: str = "event"
    kinematics: str = "reduced"
    dt: float = 1e-4
    min_steps: int = 48  # floor on RK4 steps per stroke
    num_threads: int | None = None  # batched env only; None: the measured rule (core/threads.py)
    max_steps: int = MAX_STEPS
    # per-episode randomisation, off by default (docs/randomisation.md)
    action_noise: float = 0.0  # [action units] sigma of Gaussian noise on each fired action
    friction_factor_range: tuple = (1.0, 1.0)  # [-] factor on the friction Q, uniform per episode
    mass_factor_range: tuple = (1.0, 1.0)  # [-] factor on the part mass, uniform per episode
    # observation history, off by default (the line's env card, "Observation history")
    observe_history: int = 0  # [firings] previous firings appended to the observation

    def __post_init__(self) -> None:
        self._check_ranges(_RANGES)
        if self.start_jitter > self.start_offset:
            raise ParameterError(f"{type(self).__name__}.start_jitter = {self.start_jitter!r} is "
                                 f"invalid: must be <= start_offset ({self.start_offset!r} m) so "
                                 "the part starts upstream of actuator 1")
        self._check_integers()
        self._check_pairs(_PAIRS)
        self._check_horizon(self.target_range[1] + self.start_offset + self.start_jitter,
                            "target_range[1] + start_offset + start_jitter = ")
        self._check_budget_and_choices(self.n_actuators, "dt, freq_range, n_actuators",
                                       (("mode", ("event", "karnopp")),))

    def _check_integers(self) -> None:
        self._check_integer("n_actuators", 1, MAX_ACTUATORS)
        self._check_flag("stop_at_target")
        self._check_integer("min_steps", 2, 100000)
        self._check_integer("num_threads", 1, 1024, optional=True,
                            must="null (automatic) or an integer in [1, 1024]")
        self._check_integer("observe_history", 0, self.n_actuators - 1,
                            must=f"an integer in [0, n_actuators - 1 = {self.n_actuators - 1}] "
                                 "(firings to remember; the last firing's decision sees at most "
                                 "n_actuators - 1 before it)")

    @property
    def actuator_positions(self) -> tuple:
        """Actuator i at i * ``spacing`` [m] (actuator 1 at the origin)."""
        return tuple(i * self.spacing for i in range(self.n_actuators))
