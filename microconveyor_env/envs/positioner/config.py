"""Validated configuration of MicroPositioner-v0 (defaults in
``configs/envs/MicroPositioner-v0.yaml``, where every key has its meaning and unit; SI units).

The positioner is a rail's scene (:class:`~..rail.config.RailConfig`, as the line: the same
surface, bump, start, targets, reward and randomisation fields, checked the same way) with two
fields of its own: ``pick_reach``, how far from the part the action's aim point can be (which actuator fires),
and ``max_firings``, the firings an episode may take. Every firing starts from rest (a step
ends with the part at rest), so there is no delay to choose: ``delay_range`` is [0, 0]; the
episode ends once the part rests within the tolerance (``stop_at_target`` is always true); the
observation holds the last firing, so there is no ``observe_history``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ...env_ids import POSITIONER_MAX_FIRINGS
from ...physics.materials import ParameterError, check_range
from ..rail.config import RailConfig

MAX_FIRINGS = POSITIONER_MAX_FIRINGS  # firings an episode may take at most


@dataclass(frozen=True)
class PositionerConfig(RailConfig):
    """All settings of MicroPositioner-v0 (SI units; meanings in its YAML file)."""

    CONFIG_FILE: ClassVar[str] = "MicroPositioner-v0.yaml"
    fires_from_rest: ClassVar[bool] = True   # each firing runs the part to rest

    pick_reach: float = 0.5e-3  # [m] action 0 (in [-1, 1]) times this: aim point's offset
    max_firings: int = 24       # [-] firings per episode at most

    def __post_init__(self) -> None:
        owner = type(self).__name__
        if self.delay_range != (0.0, 0.0) and list(self.delay_range) != [0.0, 0.0]:
            raise ParameterError(f"{owner}.delay_range = {self.delay_range!r} is invalid: must "
                                 "be [0, 0] (every firing starts from rest: a delay would only "
                                 "wait)")
        if self.stop_at_target is not True:
            raise ParameterError(f"{owner}.stop_at_target = {self.stop_at_target!r} is invalid: "
                                 "must be true (the episode ends once the part rests within "
                                 "the tolerance)")
        if self.observe_history != 0:
            raise ParameterError(f"{owner}.observe_history = {self.observe_history!r} is "
                                 "invalid: must be 0 (the observation holds the last firing)")
        self._check_integer("max_firings", 1, MAX_FIRINGS)
        self._set("pick_reach", check_range(owner, "pick_reach", self.pick_reach, 0.0, 1e-2,
                                            unit="m"))
        super().__post_init__()
        self._check_budget_and_choices(self.max_firings, "dt, freq_range, max_firings",
                                       (("mode", ("event", "karnopp")),))

    @property
    def episode_limit(self) -> tuple[int, str]:
        """``max_firings`` steps at most (each a firing run to rest)."""
        return self.max_firings, f"max_firings = {self.max_firings}"
