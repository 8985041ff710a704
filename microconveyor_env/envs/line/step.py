"""The line's compiled per-part step: decode the action (:mod:`..core.actions`), fire the next
actuator (:func:`...physics.dynamics_kernel.fire`), score and observe (:mod:`.task`).

The single env (N = 1) and the batched env run the very same per-part function
(:func:`_step_part`), serially or in numba's parallel loop, so their rollouts are bit-identical;
both reach it through :class:`.state.Conveyor`, which owns the arrays below.

The conveyor's state as the compiled code sees it (typed NamedTuples of arrays, one element or row
per part; compiled code reads them by field name, so there are no index constants to keep in
step):

* :class:`Parts`: the part state ``x, v, t, fired, target``;
* :class:`~..rail.step.Constants` (every rail's): what a step reads but does not write: ``dt``,
  ``min_steps``, the actuator ``positions``, the per-part physics rows ``P`` (the simulator's
  constants with that part's mass and friction factor, drawn per episode, see
  :mod:`..core.randomisation`), the execution ``noise``, the contact-table arrays ``tu, tq, tqu``
  and ``rec`` (the env records no trajectories);
* :class:`Outputs`: what a step reports per part (reward, outcome code, success, the firing as
  fired, the observation row, and the kernel's output row, whose columns are the kernel's
  ``O_*``);
* :class:`~..core.actions.ActionConstants` and :class:`~.task.TaskConstants` (scalars), passed on
  their own: numba's parallel loop cannot take a NamedTuple of scalars nested inside another one.

The types live here and in :mod:`..rail.step`, :mod:`..core.actions` / :mod:`.task`, compiled modules: an edit of any
compiled module discards the cached machine code of every other (:mod:`microconveyor_env.jit_cache`
finds them by their ``refresh`` call), since a cached function is keyed by a NamedTuple's class
and field types, not its field names. The only index constants the env still uses are the
physics' own (``forces.I_*`` into a row of ``P``, ``dynamics_kernel.O_*`` into a row of
``Outputs.kernel``), defined in :mod:`...physics`.

Execution noise: with ``AC.noise = sigma > 0`` part ``i`` fires ``clip(action + sigma * noise[i,
k])`` at its firing ``k`` (``noise``: standard normals drawn per episode, ``(N, n_actuators,
3)``); with sigma = 0 the action is used as given and ``noise`` is not read (:data:`~..rail.step.NO_NOISE`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ...physics import dynamics_kernel as kernel
from ...jit_cache import refresh as refresh_jit_cache
from ..core.actions import decode
from .task import is_success, observe_part, reward, stop_if_delivered


class Parts(NamedTuple):
    """The state of N parts."""

    x: np.ndarray       # (N,) float64, position [m]
    v: np.ndarray       # (N,) float64, velocity [m/s]
    t: np.ndarray       # (N,) float64, simulated time [s]
    fired: np.ndarray   # (N,) int64, actuators fired so far
    target: np.ndarray  # (N,) float64, target [m]


class Outputs(NamedTuple):
    """What a step reports, per part (an inactive part: reward 0, MOVING, no success, firing 0)."""

    reward: np.ndarray     # (N,) float64
    outcome: np.ndarray    # (N,) int64, dynamics_kernel outcome code
    success: np.ndarray    # (N,) bool
    frequency: np.ndarray  # (N,) float64, as fired (noise included) [Hz]
    stroke: np.ndarray     # (N,) float64 [m]
    delay: np.ndarray      # (N,) float64 [s]
    obs: np.ndarray        # (N, OBS_DIM) float32, observation after the step
    kernel: np.ndarray     # (N, N_OUT) float64, dynamics_kernel.fire's output row (O_* columns)


@njit(cache=True)
def _step_part(i, actions, parts, c, AC, TC, out):
    a0, a1, a2 = actions[i, 0], actions[i, 1], actions[i, 2]
    k = parts.fired[i]
    sigma = AC.noise
    if sigma > 0.0:
        a0 += sigma * c.noise[i, k, 0]
        a1 += sigma * c.noise[i, k, 1]
        a2 += sigma * c.noise[i, k, 2]
    f, h, d = decode(a0, a1, a2, AC)
    last = k == TC.n_actuators - 1
    x0, v0, t0, target = parts.x[i], parts.v[i], parts.t[i], parts.target[i]
    kout = out.kernel[i]
    kernel.reset_out(kout)
    x, v, t, code = kernel.fire(x0, v0, t0, c.positions[k], f, h, d, c.dt, c.min_steps, last,
                                TC.max_time, c.P[i], c.tu, c.tq, c.tqu, c.rec, kout)
    if code == kernel.MOVING and not last:
        x, v, t, code = stop_if_delivered(x, v, t, target, TC, c.P[i], c.tu, c.tq, c.tqu)
    kernel.finish_out(kout, x, v, t, code)
    out.reward[i] = reward(code, x0, x, t0, t, target, TC)
    out.success[i] = is_success(code, x, target, TC)
    out.outcome[i] = code
    out.frequency[i], out.stroke[i], out.delay[i] = f, h, d
    parts.x[i], parts.v[i], parts.t[i] = x, v, t
    parts.fired[i] = k + 1


@njit(cache=True)
def _skip_part(i, out):
    out.reward[i] = 0.0
    out.outcome[i] = kernel.MOVING
    out.success[i] = False
    out.frequency[i], out.stroke[i], out.delay[i] = 0.0, 0.0, 0.0


@njit(cache=True)
def _observe(i, parts, positions, TC, obs):
    observe_part(parts.x[i], parts.v[i], parts.t[i], parts.fired[i], parts.target[i], TC,
                 positions, obs[i])


@njit(cache=True, inline="always")
def _advance(i, actions, active, parts, c, AC, TC, out):
    """Part ``i``'s share of a step: fire (active) or clear its outputs (inactive), then observe.
    Returns 1 if the part left the contact table, else 0."""
    beyond = 0
    if active[i]:
        _step_part(i, actions, parts, c, AC, TC, out)
        if out.outcome[i] == kernel.BEYOND_TABLE:
            beyond = 1
    else:
        _skip_part(i, out)
    _observe(i, parts, c.positions, TC, out.obs)
    return beyond


@njit(cache=True)
def step_serial(actions, active, parts, c, AC, TC, out):
    """Fire the next actuator of every active part (``actions`` (N, 3) float64, ``active`` (N,)
    bool), fill ``out``; observe every part. Returns how many parts left the contact table
    (outcome BEYOND_TABLE)."""
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
def observe_all(parts, positions, TC, obs):
    """The observation rows of every part, into ``obs``."""
    for i in range(parts.x.shape[0]):
        _observe(i, parts, positions, TC, obs)


refresh_jit_cache(globals())
