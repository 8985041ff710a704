"""Validated configuration of the line's envs, MicroConveyor-v0 and -v1 and the goal env
(defaults in ``configs/envs/MicroConveyor-v0.yaml``, a later version's beyond them in its own
``configs/envs/<id>.yaml``; SI units). The checks every scene shares: :mod:`..core.config`."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ...env_ids import MAX_ACTUATORS
from ...physics.materials import ParameterError
from ...physics.validation import MAX_STEPS, MIN_DT, MIN_WAVELENGTH
from ..core.config import MIN_LENGTH, SceneConfig
from ..core.randomisation import FACTOR_BOUNDS, MAX_ACTION_NOISE
from .task import LENGTH_SCALE, OBS_BOUND

# Position error and target are observed / LENGTH_SCALE, clipped to +-OBS_BOUND: targets beyond
# this distance could not be seen.
MAX_TARGET = OBS_BOUND * LENGTH_SCALE  # m
# Randomisation's bounds (MAX_ACTION_NOISE, FACTOR_BOUNDS: docs/randomisation.md) are every
# scene's: ..core.randomisation
_RANGES = {  # field -> (lo, hi, lo_open, unit)
    "spacing": (1e-6, 1.0, False, "m"), "wavelength": (MIN_WAVELENGTH, 1.0, False, "m"),
    "start_offset": (0.0, 1.0, False, "m"), "start_jitter": (0.0, 1.0, False, "m"),
    "tolerance": (MIN_LENGTH, 1.0, False, "m"),
    "time_cost": (0.0, 1e6, False, "1/s"), "success_bonus": (0.0, 1e6, False, "-"),
    "detach_penalty": (0.0, 1e6, True, "-"), "max_time": (1e-6, 1e6, False, "s"),
    "dt": (MIN_DT, 1.0, False, "s"),
    "action_noise": (0.0, MAX_ACTION_NOISE, False, "action units"),
}
_PAIRS = {"target_range": (0.0, MAX_TARGET, "m"), "freq_range": (0.0, 1e6, "Hz"),
          "stroke_range": (0.0, 1e-2, "m"), "delay_range": (0.0, 1e4, "s"),
          "friction_factor_range": (*FACTOR_BOUNDS, "-"), "mass_factor_range": (*FACTOR_BOUNDS, "-")}


@dataclass(frozen=True)
class EnvConfig(SceneConfig):
    """All settings of the line's envs (SI units); ``configs/envs/MicroConveyor-v0.yaml`` gives
    each field's meaning, unit and MicroConveyor-v0's value."""

    CONFIG_FILE: ClassVar[str] = "MicroConveyor-v0.yaml"

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
    num_threads: int | None = None  # batched env only; None: the measured rule (envs/line/vector.py)
    max_steps: int = MAX_STEPS
    # per-episode randomisation, off by default (docs/randomisation.md)
    action_noise: float = 0.0  # [action units] sigma of Gaussian noise on each fired action
    friction_factor_range: tuple = (1.0, 1.0)  # [-] factor on the friction Q, uniform per episode
    mass_factor_range: tuple = (1.0, 1.0)  # [-] factor on the part mass, uniform per episode
    # observation history, off by default (the env card, "Observation history")
    observe_history: int = 0  # [firings] previous firings appended to the observation

    def __post_init__(self) -> None:
        self._check_ranges(_RANGES)
        if self.start_jitter > self.start_offset:
            raise ParameterError(f"EnvConfig.start_jitter = {self.start_jitter!r} is invalid: must "
                                 f"be <= start_offset ({self.start_offset!r} m) so the part starts "
                                 "upstream of actuator 1")
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
    def episode_limit(self) -> tuple[int, str]:
        """One firing per actuator: ``n_actuators`` steps at most."""
        return self.n_actuators, f"the {self.n_actuators} actuators"

    @property
    def actuator_positions(self) -> tuple:
        return tuple(i * self.spacing for i in range(self.n_actuators))

    @property
    def randomised(self) -> bool:
        """Whether any per-episode randomisation is on (noise > 0 or a factor range not (1, 1))."""
        return (self.action_noise > 0.0 or self.friction_factor_range != (1.0, 1.0)
                or self.mass_factor_range != (1.0, 1.0))

