"""What the part containers of a rail's scenes share (the line's
:class:`~..line.state.Conveyor`, the positioner's :class:`~..positioner.state.PositionerParts`,
both on the container every scene shares, :class:`~..core.parts.PartsBase`): the simulator a
config builds, the actuator positions and the step's constants, the start and target of an
episode and the check of a target option; and what the envs expose of the container they own.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...physics.simulator import Simulator
from ...presets import simulator
from ..core import actions
from ..core.parts import PartsBase, check_table_reach, for_part
from ..core.randomisation import AFFINE_UNIFORM, uniform
from .config import RailConfig
from .step import MAX_TARGET, NO_NOISE, NO_RECORD, Constants


def make_simulator(cfg: RailConfig) -> Simulator:
    """The env's simulator; refuses action ranges whose strongest stroke would load the part
    beyond the contact table (:func:`~..core.parts.check_table_reach`, once here, so steps never
    need to)."""
    sim = simulator(cfg.preset, shape=cfg.shape, wavelength=cfg.wavelength,
                    kinematics=cfg.kinematics, mode=cfg.mode, dt=cfg.dt, max_time=cfg.max_time,
                    min_steps=cfg.min_steps, max_steps=cfg.max_steps)
    check_table_reach(sim, cfg)
    return sim


def initial_state(cfg: Any, rng: np.random.Generator, target: float | None = None) -> tuple:
    """(start position [m], target [m]) of a new episode: the part ``start_offset`` upstream of
    actuator 1 (jittered by up to ``start_jitter``), the target drawn uniformly from
    ``target_range`` unless given (already checked)."""
    jitter = uniform(rng, -1.0, 1.0) * cfg.start_jitter if cfg.start_jitter else 0.0
    drawn = uniform(rng, *cfg.target_range)
    return -cfg.start_offset + jitter, drawn if target is None else target


def initial_states(cfg: Any, rngs: Sequence[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """(start positions [m], targets [m]) of new episodes, part ``k`` drawing from ``rngs[k]``:
    :func:`initial_state` for each part (the same numbers, bit for bit), the arithmetic done
    once on arrays."""
    if not AFFINE_UNIFORM:
        rows = [initial_state(cfg, rng) for rng in rngs]
        return (np.array([r[0] for r in rows], dtype=float),
                np.array([r[1] for r in rows], dtype=float))
    lo, hi = cfg.target_range
    if cfg.start_jitter:  # the jitter's draw first, then the target's
        u = np.array([(rng.random(), rng.random()) for rng in rngs], dtype=float).reshape(-1, 2)
        jitter = (-1.0 + (1.0 - -1.0) * u[:, 0]) * cfg.start_jitter
        return -cfg.start_offset + jitter, lo + (hi - lo) * u[:, 1]
    u_t = np.array([rng.random() for rng in rngs], dtype=float)
    return np.full(len(u_t), -cfg.start_offset + 0.0), lo + (hi - lo) * u_t


def check_target(target: object) -> float:
    """A target from ``reset(options=...)`` [m]: finite and where the observation can show it."""
    t = math.nan
    if isinstance(target, (numbers.Real, np.floating, np.integer)) and not isinstance(
            target, (bool, np.bool_)):
        t = float(target)
    if not (np.isfinite(t) and abs(t) <= MAX_TARGET):
        raise ValueError(f"options['target'] = {target!r} is invalid: must be a finite distance "
                         f"beyond actuator 1 within ±{MAX_TARGET * 1e3:g} mm")
    return t


def check_targets(given: object, batched: bool, n: int) -> list[float]:
    """Every part's target [m] from reset's ``target`` option (:func:`check_target`):
    ``batched``, one for all ``n`` parts or a sequence of ``n``, one per part; else the single
    env's one."""
    if not batched:
        return [check_target(given)]
    try:
        tv = np.broadcast_to(np.asarray(given, dtype=float), (n,))
    except (TypeError, ValueError):
        raise ValueError(f"options['target'] = {given!r} is invalid: give "
                         f"one target [m] or {n}, one per env") from None
    return [for_part(i, check_target, t) for i, t in enumerate(tv)]


class RailParts(PartsBase):
    """``n`` parts on a rail: the simulator, the actuator ``positions``, the action's constants
    and the step's :class:`~.step.Constants` (:meth:`_start_rail`, with ``rows`` noise rows a
    part: one per firing an episode can have), the targets of reset options, and the position
    error the envs' info reports."""

    config: RailConfig
    sim: Simulator

    def _start_rail(self, config: RailConfig, n: int, rows: int) -> None:
        self.config = config
        self.n = n
        self.sim = make_simulator(config)
        self.positions: np.ndarray = np.asarray(config.actuator_positions, dtype=np.float64)
        self.action = actions.constants(config, config.action_noise)
        tu, tq, tqu = self.sim.tables
        self.consts = Constants(
            dt=float(self.sim.dt), min_steps=int(self.sim.min_steps), positions=self.positions,
            P=np.tile(self.sim.params, (n, 1)),
            noise=(np.zeros((n, rows, 3)) if config.action_noise > 0 else NO_NOISE),
            tu=tu, tq=tq, tqu=tqu, rec=NO_RECORD)

    def check_targets(self, given: Any, batched: bool) -> list[float]:
        """Every part's target [m] (:func:`check_targets`)."""
        return check_targets(given, batched, self.n)

    def errors(self) -> dict[str, np.ndarray]:
        """``position_error_m``: each part's signed x − target [m]."""
        return {"position_error_m": self.parts.x - self.parts.target}

    def errors_of(self, i: int) -> dict[str, Any]:
        """Part ``i``'s ``position_error_m`` [m] (the same float64 subtraction as :meth:`errors`)."""
        return {"position_error_m": float(self.parts.x[i]) - float(self.parts.target[i])}


class OwnsRail:
    """What a rail's envs expose of the container they own (``self.conveyor``)."""

    conveyor: RailParts

    @property
    def sim(self) -> Simulator:
        """The simulator (its constants, contact table and integrator settings)."""
        return self.conveyor.sim

    @property
    def positions(self) -> np.ndarray:
        """Actuator positions [m] (float64)."""
        return self.conveyor.positions
