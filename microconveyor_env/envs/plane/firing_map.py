"""The firing map of a plane scene (:mod:`microconveyor_env.physics.plane.firing_map`): a firing
from rest, tabulated once over the radial offset, frequency and stroke on the scene's own
simulator.

* :func:`rest_grid`: radial offsets from 0 to ``REACH`` times the farthest actuator the aim can
  pick from a part inside the grid (``sqrt(2) (pick_reach + spacing / 2)``: the aim point lies
  within ``pick_reach`` of the part along each axis and the actuator within half a pitch of the
  aim point), one velocity (0), the scene's frequency and stroke ranges. A node every
  ``OFFSET_STEP_M`` of offset, ``FREQUENCY_NODES`` frequencies (log-spaced), ``STROKE_NODES``
  strokes.
* :func:`firing_map`: the map of a config, cached (memory, then disk).

On MicroConveyor2D-v0/-v1 (pitch 0.5 mm, reach 0.5 mm, wavelength 2 mm) that is offsets to
1.17 mm (beyond 0.9 mm no firing of the ranges moves a resting part), 235 x 61 x 11 nodes, built
in a few seconds. The error on held-out firings comes from the frequency and stroke axes: a
node every 2.5 µm of offset leaves it as it is (largest 1.4 µm), 16 strokes halve it; it is
bounded in ``tests/physics/test_plane_firing_map.py``.
"""
from __future__ import annotations

import math
from typing import Any

from ...physics.firing_map import MapGrid
from ...physics.plane.firing_map import PlaneFiringMap
from .config import PlaneEnvConfig
from .state import make_plane_simulator

OFFSET_STEP_M = 5e-6     # [m] between offset nodes
FREQUENCY_NODES = 61     # [-] log-spaced over the scene's frequency range
STROKE_NODES = 11        # [-] over the scene's stroke range
REACH = 1.1              # [-] times the farthest actuator an aim picks from inside the grid


def reach_m(config: PlaneEnvConfig) -> float:
    """The farthest an actuator the aim picks can be from a part inside the grid [m]."""
    return math.sqrt(2.0) * (float(config.pick_reach) + 0.5 * float(config.spacing))


def rest_grid(config: PlaneEnvConfig) -> MapGrid:
    """The grid of firings from rest on ``config``'s plane (module docstring)."""
    hi = REACH * reach_m(config)
    n = int(math.ceil(hi / OFFSET_STEP_M)) + 1
    return MapGrid((0.0, (n - 1) * OFFSET_STEP_M, n), (0.0, 0.0, 1),
                   (float(config.freq_range[0]), float(config.freq_range[1]), FREQUENCY_NODES),
                   (float(config.stroke_range[0]), float(config.stroke_range[1]), STROKE_NODES))


def firing_map(config: Any, grid: MapGrid | None = None) -> PlaneFiringMap:
    """The map of ``config``'s plane (its simulator: preset, shape, wavelength, kinematics, step,
    time limit; friction and mass factors 1) on ``grid`` (default :func:`rest_grid`), from the
    cache or built."""
    return PlaneFiringMap.cached(make_plane_simulator(config), grid or rest_grid(config))
