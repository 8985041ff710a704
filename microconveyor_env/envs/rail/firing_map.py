"""The firing map of a rail's scene (:mod:`microconveyor_env.physics.firing_map`): the states its
firings start from, tabulated once on the scene's own simulator.

* :func:`rest_grid`: firings from rest (the positioner: every firing runs the part to rest, and the
  next starts there): offsets within 1.6 actuator pitches of the actuator (the candidates a
  planner aims at lie within 1.5), one velocity (0), the scene's frequency and stroke ranges.
* :func:`moving_grid`: firings of a part that may still be moving (the line: the next actuator
  fires after a delay, often while the part still slides): offsets from 1.6 pitches upstream to
  0.8 downstream of the actuator, velocities 0-0.5 m/s, the scene's frequency and stroke ranges.
* :func:`firing_map`: the map of a config (from rest where its scene's firings all start from
  rest, ``fires_from_rest``), cached (memory, then disk).

Resolution. From rest: a node every 2.5 µm of offset, 61 frequencies (log-spaced), 11 strokes.
Moving: 10 µm, 0.01 m/s, 31 frequencies, 6 strokes (1.2 million strokes; a finer grid costs
more than the searches it would serve). The held-out error of each is measured by
``microconveyor firing-map``; the rest map's is bounded in ``tests/physics/test_firing_map.py``.
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
MOVING_OFFSETS = (-1.6, 0.8)   # [pitches] offsets of a map of moving parts
MOVING_STEP_M = 10e-6    # [m] between their offset nodes
MOVING_VELOCITY = (0.0, 0.5, 51)   # [m/s] lo, hi, nodes
MOVING_FREQUENCY_NODES = 31
MOVING_STROKE_NODES = 6


def rest_grid(config: RailConfig) -> MapGrid:
    """The grid of firings from rest on ``config``'s array (module docstring)."""
    half = REST_REACH * float(config.spacing)
    n = int(round(2 * half / OFFSET_STEP_M)) + 1
    return MapGrid((-half, half, n), (0.0, 0.0, 1),
                   (float(config.freq_range[0]), float(config.freq_range[1]), FREQUENCY_NODES),
                   (float(config.stroke_range[0]), float(config.stroke_range[1]), STROKE_NODES))


def moving_grid(config: RailConfig) -> MapGrid:
    """The grid of firings of parts that may be moving on ``config``'s array (module docstring)."""
    s = float(config.spacing)
    lo, hi = MOVING_OFFSETS[0] * s, MOVING_OFFSETS[1] * s
    n = int(round((hi - lo) / MOVING_STEP_M)) + 1
    return MapGrid((lo, hi, n), MOVING_VELOCITY,
                   (float(config.freq_range[0]), float(config.freq_range[1]),
                    MOVING_FREQUENCY_NODES),
                   (float(config.stroke_range[0]), float(config.stroke_range[1]),
                    MOVING_STROKE_NODES))


def scene_grid(config: RailConfig) -> MapGrid:
    """:func:`rest_grid` where every firing of the scene starts from rest
    (``config.fires_from_rest``), else :func:`moving_grid`."""
    return rest_grid(config) if config.fires_from_rest else moving_grid(config)


def firing_map(config: Any, grid: MapGrid | None = None) -> FiringMap:
    """The map of ``config``'s scene (its simulator: preset, shape, wavelength, kinematics,
    integrator, step; friction and mass factors 1) on ``grid`` (default :func:`scene_grid`),
    from the cache or built (seconds to a minute)."""
    return FiringMap.cached(make_simulator(config), grid or scene_grid(config))
