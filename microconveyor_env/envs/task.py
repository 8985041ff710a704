"""The conveyor task's arithmetic, compiled: action decoding, one firing per part, observation,
potential-based reward. The single env (N = 1) and the batched env run the very same compiled
per-part function (:func:`_step_part`), so their rollouts are bit-identical.

Task constants travel as one float array ``C`` (see :func:`constants`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..physics import dynamics_kernel as K
from ..physics.jit_cache import refresh as refresh_jit_cache

OBS_DIM = 6
OBS_BOUND = 10.0          # observations are clipped to [-OBS_BOUND, OBS_BOUND]
LENGTH_SCALE = 10e-3      # m: position error and target are divided by this
VELOCITY_SCALE = 0.5      # m/s
NO_RECORD = np.zeros((0, K.N_REC))  # the env never records trajectories
OBS_NAMES = ("error", "velocity", "to_next_actuator", "elapsed_time", "fired_fraction", "target")

(C_F0, C_LOGSPAN, C_H0, C_HSPAN, C_D0, C_DSPAN, C_NACT, C_SPACING, C_TMAX, C_PSCALE, C_TCOST,
 C_BONUS, C_PENALTY, C_TOL, C_DT, C_MINSTEPS) = range(16)
N_C = 16
# per-part outputs of a step
(S_REWARD, S_OUTCOME, S_SUCCESS, S_F, S_H, S_D) = range(6)
N_S = 6


def constants(cfg, dt: float = 0.0, min_steps: int = 0) -> np.ndarray:
    """The task constants of ``cfg`` and the integrator's step settings as one array."""
    C = np.zeros(N_C)
    C[C_F0], C[C_LOGSPAN] = cfg.freq_range[0], cfg.log_freq_span
    C[C_H0], C[C_HSPAN] = cfg.stroke_range[0], cfg.stroke_range[1] - cfg.stroke_range[0]
    C[C_D0], C[C_DSPAN] = cfg.delay_range[0], cfg.delay_range[1] - cfg.delay_range[0]
    C[C_NACT], C[C_SPACING], C[C_TMAX] = cfg.n_actuators, cfg.spacing, cfg.max_time
    C[C_PSCALE], C[C_TCOST] = cfg.progress_scale, cfg.time_cost
    C[C_BONUS], C[C_PENALTY], C[C_TOL] = cfg.success_bonus, cfg.detach_penalty, cfg.tolerance
    C[C_DT], C[C_MINSTEPS] = dt, min_steps
    return C


@njit(cache=True)
def decode(a0, a1, a2, C):
    """Action components in [-1, 1] (clipped) -> (f [Hz], h [m], delay [s])."""
    u0 = (min(max(a0, -1.0), 1.0) + 1.0) * 0.5
    u1 = (min(max(a1, -1.0), 1.0) + 1.0) * 0.5
    u2 = (min(max(a2, -1.0), 1.0) + 1.0) * 0.5
    return (C[C_F0] * math.exp(u0 * C[C_LOGSPAN]), C[C_H0] + u1 * C[C_HSPAN],
            C[C_D0] + u2 * C[C_DSPAN])


@njit(cache=True)
def potential(x, target, C):
    """Phi = -|x - target| / progress_scale."""
    return -abs(x - target) / C[C_PSCALE]


@njit(cache=True)
def observe_part(x, v, t, fired, target, C, positions, row):
    n = int(C[C_NACT])
    nxt = positions[fired] - x if fired < n else 0.0
    vals = ((x - target) / LENGTH_SCALE, v / VELOCITY_SCALE, nxt / C[C_SPACING], t / C[C_TMAX],
            fired / n, target / LENGTH_SCALE)
    for j in range(OBS_DIM):
        row[j] = min(max(vals[j], -OBS_BOUND), OBS_BOUND)


@njit(cache=True)
def _step_part(i, actions, x, v, t, fired, target, C, positions, P, tu, tq, tqu, rec, kout, res):
    f, h, d = decode(actions[i, 0], actions[i, 1], actions[i, 2], C)
    last = fired[i] == int(C[C_NACT]) - 1
    out = kout[i]
    K.reset_out(out)
    x_new, v_new, t_new, code = K.fire(x[i], v[i], t[i], positions[fired[i]], f, h, d, C[C_DT],
                                       int(C[C_MINSTEPS]), last, C[C_TMAX], P, tu, tq, tqu, rec,
                                       out)
    K.finish_out(out, x_new, v_new, t_new, code)
    success = code == K.REST and abs(x_new - target[i]) <= C[C_TOL]
    r = potential(x_new, target[i], C) - potential(x[i], target[i], C) - C[C_TCOST] * (t_new - t[i])
    if success:
        r += C[C_BONUS]
    if code == K.DETACHED:
        r -= C[C_PENALTY]
    x[i], v[i], t[i] = x_new, v_new, t_new
    fired[i] += 1
    res[i, S_REWARD], res[i, S_OUTCOME], res[i, S_SUCCESS] = r, code, 1.0 if success else 0.0
    res[i, S_F], res[i, S_H], res[i, S_D] = f, h, d


@njit(cache=True)
def step_serial(actions, x, v, t, fired, target, active, C, positions, P, tu, tq, tqu, rec, kout,
                res, obs):
    for i in range(x.shape[0]):
        if active[i]:
            _step_part(i, actions, x, v, t, fired, target, C, positions, P, tu, tq, tqu, rec, kout,
                       res)
        observe_part(x[i], v[i], t[i], fired[i], target[i], C, positions, obs[i])


@njit(cache=True, parallel=True)
def step_parallel(actions, x, v, t, fired, target, active, C, positions, P, tu, tq, tqu, rec,
                  kout, res, obs):
    for i in prange(x.shape[0]):
        if active[i]:
            _step_part(i, actions, x, v, t, fired, target, C, positions, P, tu, tq, tqu, rec, kout,
                       res)
        observe_part(x[i], v[i], t[i], fired[i], target[i], C, positions, obs[i])


@njit(cache=True)
def observe_all(x, v, t, fired, target, C, positions, obs):
    for i in range(x.shape[0]):
        observe_part(x[i], v[i], t[i], fired[i], target[i], C, positions, obs[i])


def check_actions(actions, n: int) -> np.ndarray:
    """float64 (n, 3) copy of the actions; NaN/inf or a wrong shape raise ValueError."""
    a = np.asarray(actions, dtype=np.float64)
    if a.size != 3 * n:
        raise ValueError(f"expected {n} action(s) of 3 components (frequency, stroke, delay), got "
                         f"shape {np.shape(actions)}")
    a = a.reshape(n, 3)
    if not np.isfinite(a).all():
        raise ValueError(f"action contains NaN or inf: {a.tolist()}")
    return a


def decode_actions(actions, cfg):
    """Python-side decoding (arrays over parts) -> (f [Hz], h [m], delay [s])."""
    a = np.atleast_2d(np.asarray(actions, dtype=np.float64))
    C = constants(cfg)
    out = np.array([decode(r[0], r[1], r[2], C) for r in a])
    return out[:, 0], out[:, 1], out[:, 2]


def encode_actions(f, h, delay, cfg):
    """Inverse of :func:`decode_actions`: SI values -> actions in [-1, 1]^3 (float32)."""
    def lin(val, lo, hi):
        val = np.asarray(val, float)
        return np.zeros_like(val) if hi == lo else 2 * (val - lo) / (hi - lo) - 1

    uf = 2 * np.log(np.asarray(f, float) / cfg.freq_range[0]) / cfg.log_freq_span - 1
    return np.stack([uf, lin(h, *cfg.stroke_range), lin(delay, *cfg.delay_range)],
                    -1).astype(np.float32)


refresh_jit_cache(globals())
