"""The plane's compiled per-part step: pick the actuator and decode the firing
(:func:`.task.pick`, :func:`..core.actions.decode`, with the execution noise), fire it
(:func:`...physics.plane.kernel.fire`), score and observe (:mod:`.task`).

As on the line (:mod:`..line.step`), the single env (N = 1) and the batched env run the very same per-part
function (:func:`_step_part`), serially or in numba's parallel loop, so their rollouts are
bit-identical; both reach it through :class:`.state.PlaneConveyor`, which owns the arrays
below (typed NamedTuples of arrays, one element or row per part, read by field name):

* :class:`PlaneParts`: the part state ``x, y, vx, vy, t, fired, tx, ty``;
* :class:`PlaneConstants`: what a step reads but does not write: ``dt``, ``min_steps``, the
  actuator positions ``ax, ay``, the physics rows ``P`` (one per part, with that part's friction
  and mass factors of the episode), the execution ``noise``, the contact-table arrays
  ``tu, tq, tqu`` and ``rec`` (no trajectories are recorded);
* :class:`PlaneOutputs`: what a step reports per part;
* :class:`~..core.actions.ActionConstants` and :class:`~.task.PlaneTaskConstants` (scalars),
  passed on their own (numba's parallel loop cannot take nested NamedTuples of scalars).

Execution noise: with ``AC.noise = sigma > 0`` part ``i`` fires ``clip(a + sigma * noise[i, k])``
for the firing components ``a`` (frequency, stroke, delay: actions 2-4) of its firing ``k``
(``noise``: standard normals drawn per episode, ``(N, max_firings, 3)``); the aim (actions 0-1)
picks an actuator by its address, exactly. With sigma = 0 the action is used as given and
``noise`` is not read (:data:`NO_NOISE`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel
from ...physics.plane import kernel as plane_kernel
from ..core.actions import decode
from .task import is_success, observe_part, pick, reward, stop_if_delivered

ACTION_DIM = 5  # (aim x, aim y, frequency, stroke, delay)
NO_RECORD = np.zeros((0, plane_kernel.N_REC))  # the env never records trajectories
NO_NOISE = np.zeros((0, 0, 3))  # no execution noise (action_noise = 0)


class PlaneParts(NamedTuple):
    """The state of N parts."""

    x: np.ndarray       # (N,) float64, position [m]
    y: np.ndarray       # (N,) float64 [m]
    vx: np.ndarray      # (N,) float64, velocity [m/s]
    vy: np.ndarray      # (N,) float64 [m/s]
    t: np.ndarray       # (N,) float64, simulated time [s]
    fired: np.ndarray   # (N,) int64, firings so far
    tx: np.ndarray      # (N,) float64, target [m]
    ty: np.ndarray      # (N,) float64 [m]


class PlaneConstants(NamedTuple):
    """What the step reads and never writes."""

    dt: float              # s, integrator step
    min_steps: int         # integrator steps per stroke, at least
    ax: np.ndarray         # (n_actuators,) float64, actuator x [m]
    ay: np.ndarray         # (n_actuators,) float64, actuator y [m]
    P: np.ndarray          # (N, n_params) float64, each part's physics constants (forces.I_*)
    noise: np.ndarray      # (N, max_firings, 3) float64 standard normals, or NO_NOISE
    tu: np.ndarray         # contact table (PlaneSimulator.tables)
    tq: np.ndarray
    tqu: np.ndarray
    rec: np.ndarray        # NO_RECORD


class PlaneOutputs(NamedTuple):
    """What a step reports, per part (an inactive part: reward 0, MOVING, no success, actuator
    -1, firing 0)."""

    reward: np.ndarray     # (N,) float64
    outcome: np.ndarray    # (N,) int64, dynamics_kernel outcome code
    success: np.ndarray    # (N,) bool
    actuator: np.ndarray   # (N,) int64, the actuator fired
    frequency: np.ndarray  # (N,) float64, as fired (noise included) [Hz]
    stroke: np.ndarray     # (N,) float64 [m]
    delay: np.ndarray      # (N,) float64 [s]
    obs: np.ndarray        # (N, OBS_DIM) float32, observation after the step
    kernel: np.ndarray     # (N, N_OUT) float64, plane_kernel.fire's output row (O_* columns)


@njit(cache=True)
def _step_part(i, actions, parts, c, AC, TC, out):
    x0, y0, vx0, vy0, t0 = parts.x[i], parts.y[i], parts.vx[i], parts.vy[i], parts.t[i]
    tx, ty = parts.tx[i], parts.ty[i]
    j = pick(x0, y0, actions[i, 0], actions[i, 1], TC)
    k = parts.fired[i]
    a2, a3, a4 = actions[i, 2], actions[i, 3], actions[i, 4]
    sigma = AC.noise
    if sigma > 0.0:
        a2 += sigma * c.noise[i, k, 0]
        a3 += sigma * c.noise[i, k, 1]
        a4 += sigma * c.noise[i, k, 2]
    f, h, d = decode(a2, a3, a4, AC)
    last = k >= TC.max_firings - 1
    kout = out.kernel[i]
    plane_kernel.reset_out(kout)
    x, y, vx, vy, t, code = plane_kernel.fire(x0, y0, vx0, vy0, t0, c.ax[j], c.ay[j], f, h, d,
                                              c.dt, c.min_steps, last, TC.max_time, c.P[i],
                                              c.tu, c.tq, c.tqu, c.rec, kout)
    if code == kernel.MOVING and not last:
        x, y, vx, vy, t, code = stop_if_delivered(x, y, vx, vy, t, tx, ty, TC, c.P[i], c.tu,
                                                  c.tq, c.tqu)
    plane_kernel.finish_out(kout, x, y, vx, vy, t, code)
    d_old = math.hypot(x0 - tx, y0 - ty)
    d_new = math.hypot(x - tx, y - ty)
    out.reward[i] = reward(code, d_old, d_new, t0, t, TC)
    out.success[i] = is_success(code, d_new, TC)
    out.outcome[i] = code
    out.actuator[i] = j
    out.frequency[i], out.stroke[i], out.delay[i] = f, h, d
    parts.x[i], parts.y[i], parts.vx[i], parts.vy[i], parts.t[i] = x, y, vx, vy, t
    parts.fired[i] = k + 1


@njit(cache=True)
def _skip_part(i, out):
    out.reward[i] = 0.0
    out.outcome[i] = kernel.MOVING
    out.success[i] = False
    out.actuator[i] = -1
    out.frequency[i], out.stroke[i], out.delay[i] = 0.0, 0.0, 0.0


@njit(cache=True)
def _observe(i, parts, TC, obs):
    observe_part(parts.x[i], parts.y[i], parts.vx[i], parts.vy[i], parts.t[i], parts.fired[i],
                 parts.tx[i], parts.ty[i], TC, obs[i])


@njit(cache=True, inline="always")
def _advance(i, actions, active, parts, c, AC, TC, out):
    """Part ``i``'s share of a step; 1 if the part left the contact table, else 0."""
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
    """Fire one actuator for every active part (``actions`` (N, 5) float64, ``active`` (N,)
    bool), fill ``out``; observe every part. Returns how many parts left the contact table."""
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
