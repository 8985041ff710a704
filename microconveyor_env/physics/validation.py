"""Validators of the simulation settings that both the simulator and the env's configuration
check: the time step and the step budget, ``max_steps``, the kinematics level. Kept apart from
:mod:`.simulator` (and from the compiled kernel it loads) so that a configuration layer can
validate without importing either; :mod:`.simulator` re-exports every name.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import numpy.typing as npt

from .materials import ParameterError

KINEMATICS = ("reduced", "exact")
RENAMED_KINEMATICS = {"seed": "reduced"}  # old name -> new name (deprecated, still accepted)
MIN_DT = 1e-12             # s
MIN_WAVELENGTH = 1e-6      # m
MAX_STEPS = 10_000_000     # default cap on the RK4 steps of one run (~10 s of kernel time)
MAX_STEPS_LIMIT = 10 ** 12  # largest cap one may ask for


def stroke_steps(f: npt.ArrayLike, dt: float, min_steps: int) -> np.ndarray:
    """RK4 steps of strokes at frequencies ``f`` [Hz] with step ``dt`` [s] and at least ``min_steps``
    [-] per stroke (as the kernel's ``steps_for``), as floats
    that never overflow: ``inf`` where ``1/(f dt)`` is beyond float range."""
    f = np.asarray(f, dtype=float)
    fd = f * dt
    if fd.size and fd.min() > 1e-300:  # the common case: no overflow possible, no errstate cost
        n = np.maximum(np.ceil(1.0 / fd - 1e-9), max(int(min_steps), 2))
        return n + n % 2
    with np.errstate(over="ignore", divide="ignore", under="ignore", invalid="ignore"):
        n = np.maximum(np.ceil(1.0 / fd - 1e-9), max(int(min_steps), 2))
        return np.where(np.isfinite(n), n + n % 2, n)


def check_step_budget(owner: str, f: npt.ArrayLike, dt: float, min_steps: int, max_steps: int,
                      max_time: float = math.inf) -> float:
    """Total RK4 steps of strokes at ``f`` [Hz] with step ``dt`` [s] (a stroke is cut at ``max_time``
    [s], so at most the steps of its first ``max_time``); ParameterError if above ``max_steps`` [-].
    ``owner`` names the caller in the message."""
    return _check_budget(owner, f, dt, stroke_steps(f, dt, min_steps), max_steps, max_time)


def _check_budget(owner: str, f: npt.ArrayLike, dt: float, steps: np.ndarray, max_steps: int,
                  max_time: float) -> float:
    cut = max_time * np.asarray(f, dtype=float)  # a stroke longer than max_time is cut there
    if not np.all(np.isfinite(cut)) or cut.min() < 1.0:
        with np.errstate(over="ignore", invalid="ignore"):
            steps = steps * np.minimum(1.0, cut)
    total = float(np.sum(steps))
    if not total <= max_steps:
        f = np.atleast_1d(np.asarray(f, dtype=float))
        raise ParameterError(
            f"{owner}: dt = {dt:g} s with strokes down to f = {f.min():g} Hz needs {total:.3g} RK4 "
            f"steps, more than max_steps = {max_steps:g} (about a second per million steps); "
            f"raise dt or the lowest frequency, or raise max_steps (at most "
            f"{MAX_STEPS_LIMIT:g}) if you mean it")
    return total


def check_max_steps(owner: str, value: object) -> int:
    """``max_steps`` [-]: an integer in [1, MAX_STEPS_LIMIT]; ``owner`` names the caller."""
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
            or not 1 <= value <= MAX_STEPS_LIMIT):
        raise ParameterError(f"{owner}.max_steps = {value!r} is invalid: must be an integer in "
                             f"[1, {MAX_STEPS_LIMIT:g}]")
    return int(value)


def kinematics_level(name: str, owner: str) -> str:
    """A kinematics level: ``reduced`` (the dissertation's model: the velocity terms of the normal
    load dropped) or ``exact``; the former name ``seed`` still works with a DeprecationWarning."""
    if name in RENAMED_KINEMATICS:
        warnings.warn(f"{owner}: kinematics {name!r} is now called "
                      f"{RENAMED_KINEMATICS[name]!r}", DeprecationWarning, stacklevel=3)
        name = RENAMED_KINEMATICS[name]
    if name not in KINEMATICS:
        raise ParameterError(f"kinematics = {name!r} is invalid: must be one of {KINEMATICS}")
    return name
