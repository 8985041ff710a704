"""The reach-target task of MicroConveyor-v0: start, observation, reward, success.

What the part should do, apart from how it moves (:mod:`..physics`) and how an action fires an
actuator (:mod:`.actions`); :mod:`.step` composes the three into the compiled per-part step, so
a task variant is a configuration (:class:`.config.EnvConfig`) of these few functions. The task's
constants travel as one float array ``TC`` (:func:`constants`).

Success (at rest within ``tolerance`` of the target) is decided here and only here: the compiled
step reports it, and the envs read it from there.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..physics import dynamics_kernel as kernel
from ..physics.jit_cache import refresh as refresh_jit_cache

OBS_DIM = 6
OBS_BOUND = 10.0          # observations are clipped to [-OBS_BOUND, OBS_BOUND]
LENGTH_SCALE = 10e-3      # m: position error and target are divided by this
VELOCITY_SCALE = 0.5      # m/s

T_NACT, T_SPACING, T_TMAX, T_PSCALE, T_TCOST, T_BONUS, T_PENALTY, T_TOL = range(8)
N_T = 8


def constants(cfg) -> np.ndarray:
    """The task constants of ``cfg`` (an EnvConfig) as one array."""
    TC = np.zeros(N_T)
    TC[T_NACT], TC[T_SPACING], TC[T_TMAX] = cfg.n_actuators, cfg.spacing, cfg.max_time
    TC[T_PSCALE], TC[T_TCOST] = cfg.progress_scale, cfg.time_cost
    TC[T_BONUS], TC[T_PENALTY], TC[T_TOL] = cfg.success_bonus, cfg.detach_penalty, cfg.tolerance
    return TC


def initial_state(cfg, rng: np.random.Generator, target: float | None = None) -> tuple:
    """(start position [m], target [m]) of a new episode: the part ``start_offset`` upstream of
    actuator 1 (jittered by up to ``start_jitter``), the target drawn uniformly from
    ``target_range`` unless given (already checked)."""
    jitter = rng.uniform(-1.0, 1.0) * cfg.start_jitter if cfg.start_jitter else 0.0
    drawn = rng.uniform(*cfg.target_range)
    return -cfg.start_offset + jitter, drawn if target is None else target


@njit(cache=True)
def potential(x, target, TC):
    """Phi = -|x - target| / progress_scale."""
    return -abs(x - target) / TC[T_PSCALE]


@njit(cache=True)
def is_success(code, x, target, TC):
    """At rest within the tolerance of the target."""
    return code == kernel.REST and abs(x - target) <= TC[T_TOL]


@njit(cache=True)
def reward(code, x_old, x_new, t_old, t_new, target, TC):
    """Potential-based progress, minus the time cost, plus the success bonus, minus the
    detachment penalty."""
    r = potential(x_new, target, TC) - potential(x_old, target, TC) \
        - TC[T_TCOST] * (t_new - t_old)
    if is_success(code, x_new, target, TC):
        r += TC[T_BONUS]
    if code == kernel.DETACHED:
        r -= TC[T_PENALTY]
    return r


@njit(cache=True)
def observe_part(x, v, t, fired, target, TC, positions, row):
    """The observation row of one part (see the env's docstring table)."""
    n = int(TC[T_NACT])
    nxt = positions[fired] - x if fired < n else 0.0
    vals = ((x - target) / LENGTH_SCALE, v / VELOCITY_SCALE, nxt / TC[T_SPACING],
            t / TC[T_TMAX], fired / n, target / LENGTH_SCALE)
    for j in range(OBS_DIM):
        row[j] = min(max(vals[j], -OBS_BOUND), OBS_BOUND)


refresh_jit_cache(globals())
