"""A lower bound on the conveyor line's placement time (MicroConveyor-v1's nominal model).

The placement time ``T`` is the time from the start until the part rests (the env's info
``sim_time_s``). The bound, :func:`line_time_bound_s`, is in closed form from the scene's own
numbers:

**The flat-surface deceleration.** Between strokes, and wherever no bump reaches it, the part
presses on the flat still surface with its weight ``m g0`` and slides against the friction
``Q(m g0)`` of the simulator's contact table, so it decelerates at exactly ``a_f = Q(m g0) / m``
(:func:`flat_deceleration`; 8.77 m/s² on v1's surface): the closed-form coast the simulator
plays (:func:`microconveyor_env.physics.dynamics_kernel.coast`).

**The last bump's reach.** A part is pushed only while an actuator's bump reaches it: beyond
``X = a_last + reach`` (the last actuator at ``a_last``; the Gaussian bump's reach ``4 s =
2 WL / 3``, 0.4 mm on v1, :func:`reach_m`) the surface under it stays flat whatever fires. On
v1, no firing of the last actuator (41 frequencies by 5 strokes over their ranges) changes by
1 µm the rest of a part 0.3 mm past it at up to 0.6 m/s, nor by 0.05 µm at 0.4 mm.

**The bound.** A part that rests at ``x > X`` passed ``X`` at some time ``t_X >= 0`` with some
speed ``v``, then coasted: ``x - X = v² / (2 a_f)`` and ``T = t_X + v / a_f``, so

    T >= sqrt(2 (x - X) / a_f),

whatever happened before (zero for ``x <= X``). What it leaves out makes it loose: the time to
get to ``X`` (the firings' own durations, their delays and the part's ride over the bumps; the
part moves during a firing, so the durations do not add on their own), and the push past the
last actuator (the part leaves its bump short of ``X``). On v1 no nominal episode played beat
it (220,000: random plans, the staged expert, the shipped policies, and differential evolution
and CMA-ES searching for plans that beat it); the fastest found come to 1.15x it (a part sent
20 mm) and 1.30x at 10 mm, where the staged expert (:mod:`agents.mpc.staged`) takes 1.31x it
(54.5 ms against 41.6 ms). Nearer it is looser (1.4x at 8 mm), and within the bumps' reach it
says nothing.

A tighter-looking envelope, ``T >= sqrt(2 (x - x0) / a_f)`` from the start ``x0`` (true if the
part never decelerated faster than ``a_f``), does not hold: a bump that loads a sliding part
harder brakes it beyond ``a_f``, and the firings' kicks carry it fast within their reach (a
searched plan rests the part at 1.66 mm after 11.3 ms, where the envelope says 20.3 ms).

On v1 the bound rules out the dissertation's 10 mm in 37 ms on this surface: the part coasts
at least 7.6 mm past ``X``, 41.6 ms at 8.77 m/s².

The bound is for the nominal model: a friction factor scales ``a_f`` with it, a mass factor
changes it through the part's load.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from microconveyor_env.envs.rail.config import RailConfig
from microconveyor_env.envs.rail.parts import make_simulator
from microconveyor_env.physics import dynamics_kernel as kernel

__all__ = ["flat_deceleration", "reach_m", "line_time_bound_s"]

# the Gaussian bump's reach past its actuator in units of its width s = WL / 6 (module
# docstring)
REACH_WIDTHS = 4.0


def flat_deceleration(config: RailConfig) -> float:
    """``a_f = Q(m g0) / m`` [m/s²]: the deceleration of a part sliding on the flat still surface
    of ``config``'s nominal model (the simulator's own closed-form coast, timed from 1 m/s)."""
    sim = make_simulator(config)
    tu, tq, tqu = sim.tables
    _, _, used, rest, _ = kernel.coast(0.0, 1.0, np.inf, sim.params, tu, tq, tqu)
    if not rest or not used > 0.0:
        raise ValueError("the part does not stop on the flat surface: no finite bound")
    return 1.0 / used


def reach_m(config: RailConfig) -> float:
    """[m] how far past its actuator a bump still pushes a part: ``4 s = 2 WL / 3`` for the
    Gaussian shape (module docstring), half the wavelength for the shapes that end there."""
    if config.shape == "gaussian":
        return REACH_WIDTHS * config.wavelength / 6.0
    return config.wavelength / 2.0


def line_time_bound_s(config: RailConfig, targets_m: npt.ArrayLike) -> np.ndarray:
    """A lower bound [s] on the placement time of a part that rests at each of ``targets_m`` [m]
    on the line of ``config`` (nominal model; module docstring): ``sqrt(2 max(x - X, 0) /
    a_f)``, ``X`` the last actuator plus :func:`reach_m`."""
    x = np.asarray(targets_m, float)
    origin = float(config.actuator_positions[-1]) + reach_m(config)
    return np.sqrt(2.0 * np.maximum(x - origin, 0.0) / flat_deceleration(config))
