"""MicroPositioner-v0's compiled per-part step: pick the actuator (:func:`.task.pick`), decode
the firing (:mod:`..core.actions`), fire it and run the part to rest
(:func:`...physics.dynamics_kernel.fire`), score and observe (:mod:`.task`).

As the line's :mod:`..line.step`: the single env (N = 1) and the batched env run the very same
per-part function, serially or in numba's parallel loop, so their rollouts are bit-identical;
the state is typed NamedTuples of arrays, one element or row per part (:class:`Parts`,
:class:`Outputs`; the constants are the line's :class:`~..line.step.Constants`).

Outcome codes: a firing that leaves the part at rest short of the episode's end reports
``MOVING`` (the episode goes on); ``REST`` ends it (the part rests within the tolerance, or the
last firing is spent); detachment, the time limit and unresolved chatter are the kernel's.

Execution noise: with ``AC.noise = sigma > 0`` firing ``k`` of part ``i`` fires frequency
``clip(a1 + sigma * noise[i, k, 0])`` and stroke ``clip(a2 + sigma * noise[i, k, 1])``; the aim
(which actuator fires) is not perturbed.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel
from ..core.actions import decode
from .task import is_success, observe_part, pick, reward


class Parts(NamedTuple):
    """The state of N parts (each at rest between steps)."""

    x: np.ndarray          # (N,) float64, position [m]
    t: np.ndarray          # (N,) float64, simulated time [s]
    fired: np.ndarray      # (N,) int64, firings so far
    target: np.ndarray     # (N,) float64, target [m]
    last_step: np.ndarray  # (N,) float64, the last firing's displacement [m] (0 before one)
    last_f: np.ndarray     # (N,) float64, the last firing's frequency as commanded [action units]
    last_h: np.ndarray     # (N,) float64, its stroke as commanded [action units]
    last_off: np.ndarray   # (N,) float64, the fired actuator minus the part's position before [m]


class Outputs(NamedTuple):
    """What a step reports, per part (an inactive part: reward 0, MOVING, no success, no firing)."""

    reward: np.ndarray     # (N,) float64
    outcome: np.ndarray    # (N,) int64, dynamics_kernel outcome code (module docstring)
    success: np.ndarray    # (N,) bool
    actuator: np.ndarray   # (N,) int64, index of the actuator fired (-1: none)
    frequency: np.ndarray  # (N,) float64, as fired (noise included) [Hz]
    stroke: np.ndarray     # (N,) float64 [m]
    obs: np.ndarray        # (N, OBS_DIM) float32, observation after the step
    kernel: np.ndarray     # (N, N_OUT) float64, dynamics_kernel.fire's output row (O_* columns)


@njit(cache=True)
def _step_part(i, actions, parts, c, AC, TC, out):
    a0, a1, a2 = actions[i, 0], actions[i, 1], actions[i, 2]
    k = parts.fired[i]
    f_cmd, h_cmd = min(max(a1, -1.0), 1.0), min(max(a2, -1.0), 1.0)
    if AC.noise > 0.0:
        a1 += AC.noise * c.noise[i, k, 0]
        a2 += AC.noise * c.noise[i, k, 1]
    f, h, d = decode(a1, a2, -1.0, AC)
    x0, t0, target = parts.x[i], parts.t[i], parts.target[i]
    j = pick(x0, a0, TC)
    xa = c.positions[j]
    kout = out.kernel[i]
    kernel.reset_out(kout)
    x, v, t, code = kernel.fire(x0, 0.0, t0, xa, f, h, d, c.dt, c.min_steps, True,
                                TC.max_time, c.P[i], c.tu, c.tq, c.tqu, c.rec, kout)
    kernel.finish_out(kout, x, v, t, code)
    out.reward[i] = reward(code, abs(x0 - target), abs(x - target), t0, t, TC)
    ok = is_success(code, abs(x - target), TC)
    out.success[i] = ok
    if code == kernel.REST and not ok and k + 1 < TC.max_firings:
        code = kernel.MOVING  # at rest, the episode goes on
    out.outcome[i] = code
    out.actuator[i] = j
    out.frequency[i], out.stroke[i] = f, h
    parts.last_step[i] = x - x0
    parts.last_f[i], parts.last_h[i] = f_cmd, h_cmd
    parts.last_off[i] = xa - x0
    parts.x[i], parts.t[i] = x, t
    parts.fired[i] = k + 1


@njit(cache=True)
def _skip_part(i, out):
    out.reward[i] = 0.0
    out.outcome[i] = kernel.MOVING
    out.success[i] = False
    out.actuator[i] = -1
    out.frequency[i], out.stroke[i] = 0.0, 0.0


@njit(cache=True)
def _observe(i, parts, TC, obs):
    observe_part(parts.x[i], parts.t[i], parts.fired[i], parts.target[i], parts.last_step[i],
                 parts.last_f[i], parts.last_h[i], parts.last_off[i], TC, obs[i])


@njit(cache=True, inline="always")
def _advance(i, actions, active, parts, c, AC, TC, out):
    """Part ``i``'s share of a step (fire or skip, then observe); 1 if it left the contact
    table, else 0."""
    beyond = 0
    if active[i]:
        _step_part(i, actions, parts, c, AC, TC, out)
        if out.outcome[i] == kernel.BEYOND_TABLE:
            beyond = 1
    else:
        _skip_part(i, out)
    _observe(i, parts, TC, out.obs)
    return beyond


@njit(cache=True)
def step_serial(actions, active, parts, c, AC, TC, out):
    """Fire once for every active part (``actions`` (N, 3) float64, ``active`` (N,) bool), fill
    ``out``; observe every part. Returns how many parts left the contact table."""
    beyond = 0
    for i in range(parts.x.shape[0]):
        beyond += _advance(i, actions, active, parts, c, AC, TC, out)
    return beyond


@njit(cache=True, parallel=True)
def step_parallel(actions, active, parts, c, AC, TC, out):
    """:func:`step_serial` in numba's parallel loop (the same per-part code)."""
    beyond = 0
    for i in prange(parts.x.shape[0]):
        beyond += _advance(i, actions, active, parts, c, AC, TC, out)
    return beyond


@njit(cache=True)
def observe_all(parts, TC, obs):
    """The observation rows of every part, into ``obs``."""
    for i in range(parts.x.shape[0]):
        _observe(i, parts, TC, obs)


refresh_jit_cache(globals())
