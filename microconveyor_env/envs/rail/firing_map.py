"""The firing map of a rail's scene (:mod:`microconveyor_env.physics.firing_map`): the states its
firings start from, tabulated once on the scene's own simulator.

* :func:`rest_grid`: firings from rest (the positioner: every firing runs the part to rest, and the
  next starts there): offsets within 1.6 actuator pitches of the actuator (the candidates a
  planner aims at lie within 1.5), one velocity (0), the scene's frequency and stroke ranges.
* :func:`firing_map`: the map of a config on a grid, cached (memory, then disk).

Resolution: a node every 2.5 µm of offset, 61 frequencies (log-spaced) and 11 strokes: the
held-out error this gives is measured by ``microconveyor firing-map`` and bounded in
``tests/physics/test_firing_map.py``.
"""
from __future__ import annotations

from typing import Any

from ...physics.firing_map import FiringMap, MapGrid
from .config import RailConfig
from .parts import make_simulator

OFFSET_STEP_M = 2.5e-6   # [m] between offset nodes
FREQUENCY_NODES = 61     # [-] log-spaced over the scene's frequency range
STROKE_NODES = 11        # [-] over the scene's stroke range
REST_REACH = 1.6         # [pitches] offsets of a map of firings from rest


def rest_grid(config: RailConfig) -> MapGrid:
    """The grid of firings from rest on ``config``'s array (module docstring)."""
    half = REST_REACH * float(config.spacing)
    n = int(round(2 * half / OFFSET_STEP_M)) + 1
    return MapGrid((-half, half, n), (0.0, 0.0, 1),
                   (float(config.freq_range[0]), float(config.freq_range[1]), FREQUENCY_NODES),
                   (float(config.stroke_range[0]), float(config.stroke_range[1]), STROKE_NODES))


def firing_map(config: Any, grid: MapGrid | None = None) -> FiringMap:
    """The map of ``config``'s scene (its simulator: preset, shape, wavelength, kinematics,
    integrator, step; friction and mass factors 1) on ``grid`` (default :func:`rest_grid`),
    from the cache or built (seconds)."""
    return FiringMap.cached(make_simulator(config), grid or rest_grid(config))
