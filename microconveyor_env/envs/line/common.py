"""What the line's single and batched envs share beyond the core (and the positioner, a line
too): the simulator a config builds and the check of a target option."""
from __future__ import annotations

import math
import numbers
import numpy as np

from ...physics.contact_table import TableRangeError
from ...physics.materials import ParameterError
from ...physics.simulator import Simulator
from ...presets import simulator
from . import task
from .config import EnvConfig


def make_simulator(cfg: EnvConfig) -> Simulator:
    """The env's simulator; refuses action ranges whose strongest stroke would load the part
    beyond the contact table (checked once here, so steps never need to)."""
    sim = simulator(cfg.preset, shape=cfg.shape, wavelength=cfg.wavelength,
                    kinematics=cfg.kinematics, mode=cfg.mode, dt=cfg.dt, max_time=cfg.max_time,
                    min_steps=cfg.min_steps, max_steps=cfg.max_steps)
    f, h = np.array([cfg.freq_range[1]]), np.array([cfg.stroke_range[1]])
    try:
        sim.check_firings(f, h)
    except TableRangeError as exc:
        raise ParameterError(f"EnvConfig.freq_range / stroke_range: {exc}") from None
    heaviest = cfg.mass_factor_range[1]
    if heaviest > 1.0:
        try:
            sim.check_firings(f, h, mass_factor=heaviest)
        except TableRangeError as exc:
            raise ParameterError(f"EnvConfig.mass_factor_range = {cfg.mass_factor_range!r} is "
                                 f"invalid with these freq_range / stroke_range: a part "
                                 f"{heaviest:g} times heavier: {exc}; lower the upper factor"
                                 ) from None
    return sim


def check_target(target: object) -> float:
    """A target from ``reset(options=...)`` [m]: finite and where the observation can show it."""
    limit = task.OBS_BOUND * task.LENGTH_SCALE
    t = math.nan
    if isinstance(target, (numbers.Real, np.floating, np.integer)) and not isinstance(
            target, (bool, np.bool_)):
        t = float(target)
    if not (np.isfinite(t) and abs(t) <= limit):
        raise ValueError(f"options['target'] = {target!r} is invalid: must be a finite distance "
                         f"beyond actuator 1 within ±{limit * 1e3:g} mm")
    return t


def check_targets(given: object, batched: bool, n: int) -> list[float]:
    """Every part's target [m] from reset's ``target`` option (:func:`check_target`):
    ``batched``, one for all ``n`` parts or a sequence of ``n``, one per part; else the single
    env's one."""
    from ..core.parts import for_part

    if not batched:
        return [check_target(given)]
    try:
        tv = np.broadcast_to(np.asarray(given, dtype=float), (n,))
    except (TypeError, ValueError):
        raise ValueError(f"options['target'] = {given!r} is invalid: give "
                         f"one target [m] or {n}, one per env") from None
    return [for_part(i, check_target, t) for i, t in enumerate(tv)]

