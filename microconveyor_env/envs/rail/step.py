"""What the compiled steps of a rail's scenes (the line's :mod:`..line.step`, the positioner's
:mod:`..positioner.step`) share: the constants a step reads and never writes
(:class:`Constants`, one row per part where it varies) and the scales the line's observation
embeds, which bound the targets every rail takes (:data:`MAX_TARGET`).

Compiled code embeds these values, so this module counts as compiled for the cache
(:mod:`microconveyor_env.jit_cache`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel

OBS_BOUND = 10.0          # observations are clipped to [-OBS_BOUND, OBS_BOUND]
LENGTH_SCALE = 10e-3      # m: position error and target are divided by this
# Position error and target are observed / LENGTH_SCALE, clipped to +-OBS_BOUND: targets beyond
# this distance could not be seen.
MAX_TARGET = OBS_BOUND * LENGTH_SCALE  # m
NO_RECORD = np.zeros((0, kernel.N_REC))  # the env never records trajectories
NO_NOISE = np.zeros((0, 0, 3))  # no execution noise (action_noise = 0)


class Constants(NamedTuple):
    """What the step reads and never writes (``P`` and ``noise`` change only at a part's reset)."""

    dt: float              # s, integrator step
    min_steps: int         # integrator steps per stroke, at least
    positions: np.ndarray  # (n_actuators,) float64, actuator positions [m]
    P: np.ndarray          # (N, n_params) float64, each part's physics constants (forces.I_*)
    noise: np.ndarray      # (N, firings, 3) float64 standard normals, or NO_NOISE
    tu: np.ndarray         # contact table (Simulator.tables)
    tq: np.ndarray
    tqu: np.ndarray
    rec: np.ndarray        # NO_RECORD


refresh_jit_cache(globals())
