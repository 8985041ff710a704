"""Validated configuration of MicroConveyor-v0 (defaults in ``configs/envs/MicroConveyor-v0.yaml``)."""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from importlib import resources

from ...env_ids import MAX_ACTUATORS
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
from .task import LENGTH_SCALE, OBS_BOUND

# Position error and target are observed / LENGTH_SCALE, clipped to +-OBS_BOUND: targets beyond
# this distance could not be seen.
MAX_TARGET = OBS_BOUND * LENGTH_SCALE  # m
MIN_LENGTH = 1e-9  # m: below it, |x - target| / tolerance overflows (NaN rewards)
# Randomisation (docs/randomisation.md): sigma of the execution noise, in action units (the action
# box is [-1, 1], so sigma = 1 already spreads a firing over the whole box); the per-episode
# friction and mass factors within an order of magnitude of the preset (beyond it, make a preset)
MAX_ACTION_NOISE = 1.0
FACTOR_BOUNDS = (0.1, 10.0)
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
class EnvConfig:
    """All settings of the environment; see ``configs/envs/MicroConveyor-v0.yaml`` for meanings and units."""

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

    def __post_init__(self):
        self._check_ranges()
        self._check_integers()
        self._check_pairs()
        self._check_horizon()
        self._check_budget_and_choices()

    def _check_ranges(self) -> None:
        for name, (lo, hi, lo_open, unit) in _RANGES.items():
            object.__setattr__(self, name, check_range("EnvConfig", name, getattr(self, name),
                                                       lo, hi, lo_open, unit=unit))
        if self.progress_scale is None:
            object.__setattr__(self, "progress_scale", self.tolerance)
        object.__setattr__(self, "progress_scale", check_range(
            "EnvConfig", "progress_scale", self.progress_scale, MIN_LENGTH, 1.0, unit="m"))
        if self.start_jitter > self.start_offset:
            raise ParameterError(f"EnvConfig.start_jitter = {self.start_jitter!r} is invalid: must "
                                 f"be <= start_offset ({self.start_offset!r} m) so the part starts "
                                 "upstream of actuator 1")

    def _check_integers(self) -> None:
        n = self.n_actuators
        if (isinstance(n, bool) or not isinstance(n, numbers.Real) or not math.isfinite(n)
                or n != int(n) or not 1 <= n <= MAX_ACTUATORS):
            raise ParameterError(f"EnvConfig.n_actuators = {n!r} is invalid: must be an integer "
                                 f"in [1, {MAX_ACTUATORS}]")
        object.__setattr__(self, "n_actuators", int(n))
        if not isinstance(self.stop_at_target, bool):
            raise ParameterError(f"EnvConfig.stop_at_target = {self.stop_at_target!r} is invalid: "
                                 "must be true or false")
        ms = self.min_steps
        if isinstance(ms, bool) or not isinstance(ms, (int, float)) or ms != int(ms) \
                or not 2 <= ms <= 100000:
            raise ParameterError(f"EnvConfig.min_steps = {ms!r} is invalid: must be an integer "
                                 "in [2, 100000]")
        object.__setattr__(self, "min_steps", int(ms))
        nt = self.num_threads
        if nt is not None:
            if isinstance(nt, bool) or not isinstance(nt, (int, float)) or nt != int(nt) \
                    or not 1 <= nt <= 1024:
                raise ParameterError(f"EnvConfig.num_threads = {nt!r} is invalid: must be null "
                                     "(automatic) or an integer in [1, 1024]")
            object.__setattr__(self, "num_threads", int(nt))
        k = self.observe_history
        if isinstance(k, bool) or not isinstance(k, (int, float)) or not math.isfinite(k) \
                or k != int(k) or not 0 <= k <= self.n_actuators - 1:
            raise ParameterError(f"EnvConfig.observe_history = {k!r} is invalid: must be an "
                                 f"integer in [0, n_actuators - 1 = {self.n_actuators - 1}] "
                                 "(firings to remember; the last firing's decision sees at most "
                                 "n_actuators - 1 before it)")
        object.__setattr__(self, "observe_history", int(k))

    def _check_pairs(self) -> None:
        for name, (lo, hi, unit) in _PAIRS.items():
            pair = getattr(self, name)
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise ParameterError(f"EnvConfig.{name} = {pair!r} is invalid: must be [low, high]")
            a = check_range("EnvConfig", f"{name}[0]", pair[0], lo, hi, unit=unit)
            b = check_range("EnvConfig", f"{name}[1]", pair[1], lo, hi, unit=unit)
            if b < a:
                raise ParameterError(f"EnvConfig.{name} = {pair!r} is invalid: low > high")
            object.__setattr__(self, name, (a, b))
        if self.freq_range[0] <= 0:
            raise ParameterError(f"EnvConfig.freq_range = {self.freq_range!r} is invalid: "
                                 "frequencies must be > 0 Hz")

    def _check_horizon(self) -> None:
        far = self.target_range[1] + self.start_offset + self.start_jitter
        if self.progress_horizon is None:
            object.__setattr__(self, "progress_horizon", 2.0 * far)
        object.__setattr__(self, "progress_horizon", check_range(
            "EnvConfig", "progress_horizon", self.progress_horizon, MIN_LENGTH, 10.0, unit="m"))
        if self.progress_horizon < far:
            raise ParameterError(f"EnvConfig.progress_horizon = {self.progress_horizon!r} is "
                                 f"invalid: must be >= the farthest start-to-target distance "
                                 f"target_range[1] + start_offset + start_jitter = {far!r} m, so "
                                 "all progress from the start is paid")

    def _check_budget_and_choices(self) -> None:
        object.__setattr__(self, "max_steps", check_max_steps("EnvConfig", self.max_steps))
        # the slowest strokes of a whole episode must fit the step budget
        check_step_budget("EnvConfig (dt, freq_range, n_actuators)",
                          [self.freq_range[0]] * self.n_actuators, self.dt,
                          self.min_steps, self.max_steps, self.max_time)
        if isinstance(self.kinematics, str):
            object.__setattr__(self, "kinematics",
                               kinematics_level(self.kinematics, "EnvConfig.kinematics"))
        for name, allowed in (("shape", tuple(SHAPES)), ("mode", ("event", "karnopp")),
                              ("kinematics", ("reduced", "exact"))):
            if getattr(self, name) not in allowed:
                raise ParameterError(f"EnvConfig.{name} = {getattr(self, name)!r} is invalid: "
                                     f"must be one of {allowed}")

    @classmethod
    def from_yaml(cls, path: str | None = None, **overrides) -> EnvConfig:
        """Defaults from ``configs/envs/MicroConveyor-v0.yaml`` (or ``path``), then ``overrides``."""
        from ...presets import parse_yaml

        if path is None:
            text = (resources.files("microconveyor_env.configs") / "envs" / "MicroConveyor-v0.yaml").read_text()
        else:
            with open(path) as fh:
                text = fh.read()
        data = parse_yaml(text, f"env config {path or 'defaults'}") or {}
        if not isinstance(data, dict):
            raise ParameterError(f"env config {path!r} is not a YAML mapping")
        data = dict(data)
        data.update(overrides)
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ParameterError(f"EnvConfig: unknown keys {unknown}; known: {sorted(known)}")
        return cls(**data)

    @property
    def actuator_positions(self) -> tuple:
        return tuple(i * self.spacing for i in range(self.n_actuators))

    @property
    def randomised(self) -> bool:
        """Whether any per-episode randomisation is on (noise > 0 or a factor range not (1, 1))."""
        return (self.action_noise > 0.0 or self.friction_factor_range != (1.0, 1.0)
                or self.mass_factor_range != (1.0, 1.0))

    @property
    def log_freq_span(self) -> float:
        return math.log(self.freq_range[1] / self.freq_range[0])
