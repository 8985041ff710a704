"""What every scene's config shares: the field checks and the defaults file.

:class:`SceneConfig` is the base of every scene's config (frozen dataclasses, SI units): reading the defaults from
``configs/envs/<file>`` then keyword overrides (:meth:`SceneConfig.from_yaml`), and the checks a
field of either goes through (numbers within a range, integers, ``[low, high]`` pairs, a
choice among names, the reward's progress scale, the integrator's step budget). A refused value
raises :class:`~...physics.materials.ParameterError` naming ``<Class>.<field>``, its value and
what is allowed.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import Any, ClassVar, TypeVar

from ...physics.kinematics import SHAPES
from ...physics.materials import ParameterError, check_range
from ...physics.validation import check_max_steps, check_step_budget, kinematics_level
from .randomisation import is_randomised

MIN_LENGTH = 1e-9  # m: below it, a distance / tolerance overflows (NaN rewards)
C = TypeVar("C", bound="SceneConfig")


class SceneConfig:
    """The checks and the defaults file of a scene's config (a frozen dataclass subclassing
    this): ``CONFIG_FILE`` names its file in ``configs/envs`` (None: the dataclass's defaults
    alone)."""

    CONFIG_FILE: ClassVar[str | None] = None
    freq_range: tuple
    stroke_range: tuple
    delay_range: tuple
    tolerance: float
    progress_scale: float | None
    progress_horizon: float | None
    dt: float
    min_steps: int
    max_time: float
    max_steps: int
    kinematics: Any

    def _set(self, name: str, value: Any) -> None:
        """Store a checked value in the frozen dataclass."""
        object.__setattr__(self, name, value)

    def _check_ranges(self, ranges: Mapping[str, tuple[float, float, bool, str]]) -> None:
        """Each field of ``ranges`` (name -> (lo, hi, lo_open, unit)) a finite number within
        its range; then ``progress_scale`` (None: the tolerance) within [MIN_LENGTH, 1] m."""
        owner = type(self).__name__
        for name, (lo, hi, lo_open, unit) in ranges.items():
            self._set(name, check_range(owner, name, getattr(self, name), lo, hi, lo_open,
                                        unit=unit))
        if self.progress_scale is None:
            self._set("progress_scale", self.tolerance)
        self._set("progress_scale", check_range(owner, "progress_scale", self.progress_scale,
                                                MIN_LENGTH, 1.0, unit="m"))

    def _check_integer(self, name: str, lo: int, hi: int, must: str = "",
                       optional: bool = False) -> None:
        """Field ``name`` an integer in [lo, hi] (``optional``: or None), stored as ``int``;
        ``must`` replaces the message's "an integer in [lo, hi]"."""
        value = getattr(self, name)
        if optional and value is None:
            return
        x = math.nan
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            x = float(value)
        if not math.isfinite(x) or x != int(x) or not lo <= x <= hi:
            raise ParameterError(f"{type(self).__name__}.{name} = {value!r} is invalid: must be "
                                 f"{must or f'an integer in [{lo}, {hi}]'}")
        self._set(name, int(x))

    def _check_flag(self, name: str) -> None:
        """Field ``name`` true or false."""
        if not isinstance(getattr(self, name), bool):
            raise ParameterError(f"{type(self).__name__}.{name} = {getattr(self, name)!r} is "
                                 "invalid: must be true or false")

    def _check_pairs(self, pairs: Mapping[str, tuple[float, float, str]]) -> None:
        """Each field of ``pairs`` (name -> (lo, hi, unit)) a ``[low, high]`` pair within the
        bounds, stored as a tuple; frequencies > 0 Hz."""
        owner = type(self).__name__
        for name, (lo, hi, unit) in pairs.items():
            pair = getattr(self, name)
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise ParameterError(f"{owner}.{name} = {pair!r} is invalid: must be [low, high]")
            a = check_range(owner, f"{name}[0]", pair[0], lo, hi, unit=unit)
            b = check_range(owner, f"{name}[1]", pair[1], lo, hi, unit=unit)
            if b < a:
                raise ParameterError(f"{owner}.{name} = {pair!r} is invalid: low > high")
            self._set(name, (a, b))
        if self.freq_range[0] <= 0:
            raise ParameterError(f"{owner}.freq_range = {self.freq_range!r} is invalid: "
                                 "frequencies must be > 0 Hz")

    def _check_horizon(self, far: float, far_is: str) -> None:
        """``progress_horizon`` (None: twice ``far``, the farthest start-to-target distance [m],
        ``far_is`` saying what it is) within [MIN_LENGTH, 10] m and at least ``far``."""
        owner = type(self).__name__
        horizon = self.progress_horizon
        if horizon is None:
            horizon = 2.0 * far
        horizon = check_range(owner, "progress_horizon", horizon, MIN_LENGTH, 10.0, unit="m")
        self._set("progress_horizon", horizon)
        if horizon < far:
            raise ParameterError(f"{owner}.progress_horizon = {horizon!r} is invalid: must be >= "
                                 f"the farthest start-to-target distance {far_is}{far!r} m, so "
                                 "all progress from the start is paid")

    def _check_budget_and_choices(self, firings: int, budget_fields: str,
                                  choices: Sequence[tuple[str, tuple[str, ...]]] = ()) -> None:
        """``max_steps``; the slowest strokes of a whole episode (``firings`` of them) within
        the step budget (``budget_fields`` named in its message); the kinematics level, the
        bump ``shape`` and each of ``choices`` (name, allowed) one of its names."""
        owner = type(self).__name__
        self._set("max_steps", check_max_steps(owner, self.max_steps))
        check_step_budget(f"{owner} ({budget_fields})", [self.freq_range[0]] * firings, self.dt,
                          self.min_steps, self.max_steps, self.max_time)
        if isinstance(self.kinematics, str):
            self._set("kinematics", kinematics_level(self.kinematics, f"{owner}.kinematics"))
        for name, allowed in (("shape", tuple(SHAPES)), *choices,
                              ("kinematics", ("reduced", "exact"))):
            if getattr(self, name) not in allowed:
                raise ParameterError(f"{owner}.{name} = {getattr(self, name)!r} is invalid: "
                                     f"must be one of {allowed}")

    @classmethod
    def from_yaml(cls: type[C], path: str | None = None, **overrides: object) -> C:
        """Defaults from ``configs/envs/<CONFIG_FILE>`` (or ``path``; neither: the dataclass's
        own), then ``overrides`` (unknown keys refused, naming the known ones)."""
        from ...presets import parse_yaml

        if path is None:
            file = cls.CONFIG_FILE
            text = "" if file is None else (resources.files("microconveyor_env.configs") / "envs"
                                            / file).read_text()
        else:
            with open(path) as fh:
                text = fh.read()
        data = parse_yaml(text, f"env config {path or cls.CONFIG_FILE}") or {}
        if not isinstance(data, dict):
            raise ParameterError(f"env config {path!r} is not a YAML mapping")
        data = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        data.update(overrides)
        known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        unknown = sorted(set(data) - known)
        if unknown:
            raise ParameterError(f"{cls.__name__}: unknown keys {unknown}; known: "
                                 f"{sorted(known)}")
        return cls(**data)

    @property
    def episode_limit(self) -> tuple[int, str]:
        """The most steps (firings) an episode takes, and how to say it."""
        raise NotImplementedError

    @property
    def randomised(self) -> bool:
        """Whether any per-episode randomisation is on (:func:`.randomisation.is_randomised`: the
        fields ``action_noise``, ``friction_factor_range``, ``mass_factor_range``); a scene
        without those fields says False."""
        return is_randomised(self)  # type: ignore[arg-type]

    @property
    def log_freq_span(self) -> float:
        """ln(freq_range[1] / freq_range[0]) [-] (the action decoding's, :mod:`.actions`)."""
        return math.log(self.freq_range[1] / self.freq_range[0])
