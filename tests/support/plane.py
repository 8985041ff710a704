"""Shared helpers of the plane tests (tests/physics/test_plane*.py): simulators, scenes and the
rotation of a scene."""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from microconveyor_env.physics.plane.simulator import ActuatorGrid, PlaneSchedule, PlaneSimulator
from microconveyor_env.physics.schedule import Firing
from microconveyor_env.physics.simulator import StepSizeWarning
from microconveyor_env.presets import load_preset


@functools.cache
def plane_sim(preset: str = "feasibility", **kw) -> PlaneSimulator:
    """Cached PlaneSimulator of a preset (the table is built once per setting)."""
    return PlaneSimulator(load_preset(preset).contact, **kw)


def steps_sim(freq: float, n: int, **kw) -> PlaneSimulator:
    """A PlaneSimulator resolving a stroke at ``freq`` with exactly ``n`` (even) RK4 steps."""
    return plane_sim(dt=1.0 / (freq * n), min_steps=2, **kw)


def quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepSizeWarning)
        return fn(*a, **kw)


# Genuinely 2-D scenes: three actuators off one line, a part off every actuator's axis.
GRID = ((0.0, 0.0), (0.5e-3, 0.0), (0.25e-3, 0.4e-3))
SCENES = {
    # a part passing an actuator sideways: curved path, no event
    "pass_by": (((0, 700.0, 200e-6, 0.0),), (0.12e-3, 0.05e-3, 0.0, 0.03)),
    # three actuators in turn from rest: break-away, curved slides, stop
    "relay": (((0, 950.0, 200e-6, 0.0), (2, 800.0, 180e-6, 1e-3), (1, 600.0, 150e-6, 0.0)),
              (0.1e-3, -0.06e-3, 0.0, 0.0)),
    # a slow oblique part on a rising bump: slows to a stop sideways, sticks, breaks away
    # radially, stops again (low-speed, stiff friction-direction dynamics)
    "oblique_stop": (((2, 500.0, 200e-6, 0.0),), (0.3e-3, 0.2e-3, -0.02, 0.01)),
}


def scene(name: str, angle: float = 0.0, shift: tuple[float, float] = (0.0, 0.0)):
    """(schedule, start) of a scene, rotated by ``angle`` [rad] about the origin and shifted."""
    firings, (x, y, vx, vy) = SCENES[name]
    c, s = math.cos(angle), math.sin(angle)
    grid = ActuatorGrid(tuple((c * px - s * py + shift[0], s * px + c * py + shift[1])
                              for px, py in GRID))
    sched = PlaneSchedule(grid, tuple(Firing(*f) for f in firings))
    return sched, (c * x - s * y + shift[0], s * x + c * y + shift[1], c * vx - s * vy,
                   s * vx + c * vy)


def rotate(p, angle: float) -> np.ndarray:
    """Rotate a point (x, y) by ``angle`` [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]])


def distance(p, q) -> float:
    return math.hypot(p[0] - q[0], p[1] - q[1])
