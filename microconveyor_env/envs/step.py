"""The env's compiled per-part step: decode the action (:mod:`.actions`), fire the next actuator
(:func:`..physics.dynamics_kernel.fire`), score and observe (:mod:`.task`).

The single env (N = 1) and the batched env run the very same per-part function
(:func:`_step_part`), serially or in numba's parallel loop, so their rollouts are bit-identical.

Per-part physics: ``P`` has one row per part (the simulator's constants with that part's mass and
friction factor, drawn per episode, see :mod:`.randomisation`). Execution noise: with
``AC[A_NOISE] = sigma > 0`` part ``i`` fires ``clip(action + sigma * noise[i, k])`` at its firing
``k`` (``noise``: standard normals drawn per episode, ``(N, n_actuators, 3)``); with sigma = 0 the
action is used as given and ``noise`` is not read (pass :data:`NO_NOISE`).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..physics import dynamics_kernel as kernel
from ..physics.jit_cache import refresh as refresh_jit_cache
from .actions import A_NOISE, decode
from .task import T_NACT, T_TMAX, is_success, observe_part, reward, stop_if_delivered

NO_RECORD = np.zeros((0, kernel.N_REC))  # the env never records trajectories
NO_NOISE = np.zeros((0, 0, 3))  # no execution noise (action_noise = 0)
# per-part outputs of a step
(S_REWARD, S_OUTCOME, S_SUCCESS, S_F, S_H, S_D) = range(6)
N_S = 6


@njit(cache=True)
def _step_part(i, actions, noise, x, v, t, fired, target, AC, TC, dt, min_steps, positions, P,
               tu, tq, tqu, rec, kout, res):
    a0, a1, a2 = actions[i, 0], actions[i, 1], actions[i, 2]
    sigma = AC[A_NOISE]
    if sigma > 0.0:
        k = fired[i]
        a0 += sigma * noise[i, k, 0]
        a1 += sigma * noise[i, k, 1]
        a2 += sigma * noise[i, k, 2]
    f, h, d = decode(a0, a1, a2, AC)
    last = fired[i] == int(TC[T_NACT]) - 1
    out = kout[i]
    kernel.reset_out(out)
    x_new, v_new, t_new, code = kernel.fire(x[i], v[i], t[i], positions[fired[i]], f, h, d, dt,
                                       min_steps, last, TC[T_TMAX], P[i], tu, tq, tqu, rec, out)
    if code == kernel.MOVING and not last:
        x_new, v_new, t_new, code = stop_if_delivered(x_new, v_new, t_new, target[i], TC, P[i],
                                                      tu, tq, tqu)
    kernel.finish_out(out, x_new, v_new, t_new, code)
    res[i, S_REWARD] = reward(code, x[i], x_new, t[i], t_new, target[i], TC)
    res[i, S_SUCCESS] = 1.0 if is_success(code, x_new, target[i], TC) else 0.0
    res[i, S_OUTCOME] = code
    res[i, S_F], res[i, S_H], res[i, S_D] = f, h, d
    x[i], v[i], t[i] = x_new, v_new, t_new
    fired[i] += 1


@njit(cache=True)
def step_serial(actions, noise, x, v, t, fired, target, active, AC, TC, dt, min_steps, positions,
                P, tu, tq, tqu, rec, kout, res, obs):
    for i in range(x.shape[0]):
        if active[i]:
            _step_part(i, actions, noise, x, v, t, fired, target, AC, TC, dt, min_steps,
                       positions, P, tu, tq, tqu, rec, kout, res)
        observe_part(x[i], v[i], t[i], fired[i], target[i], TC, positions, obs[i])


@njit(cache=True, parallel=True)
def step_parallel(actions, noise, x, v, t, fired, target, active, AC, TC, dt, min_steps,
                  positions, P, tu, tq, tqu, rec, kout, res, obs):
    for i in prange(x.shape[0]):
        if active[i]:
            _step_part(i, actions, noise, x, v, t, fired, target, AC, TC, dt, min_steps,
                       positions, P, tu, tq, tqu, rec, kout, res)
        observe_part(x[i], v[i], t[i], fired[i], target[i], TC, positions, obs[i])


@njit(cache=True)
def observe_all(x, v, t, fired, target, TC, positions, obs):
    for i in range(x.shape[0]):
        observe_part(x[i], v[i], t[i], fired[i], target[i], TC, positions, obs[i])


refresh_jit_cache(globals())
