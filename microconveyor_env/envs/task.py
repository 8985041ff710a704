"""The reach-target task of MicroConveyor-v0: start, observation, reward, success.

What the part should do, apart from how it moves (:mod:`..physics`) and how an action fires an
actuator (:mod:`.actions`); :mod:`.step` composes the three into the compiled per-part step, so
a task variant is a configuration (:class:`.config.EnvConfig`) of these few functions. The task's
constants travel as one float array ``TC`` (:func:`constants`).

Success (at rest within ``tolerance`` of the target) is decided here and only here: the compiled
step reports it, and the envs read it from there.

Reward ranking (the task is well posed). An episode's return telescopes to
``Phi(end) - Phi(start) - time_cost * T + success_bonus * [success] - ...`` with the potential
``Phi(x) = -min(|x - target|, H) / progress_scale`` saturating at ``H = progress_horizon``
(validated >= the farthest start-to-target distance, so all progress from the start is paid;
default twice that). Detachment ends the episode in the worst state there is: the detached part
takes the potential of the horizon (it forfeits all progress, ``-H / progress_scale``), pays the
time cost up to ``max_time`` and then ``detach_penalty`` (> 0). Hence, for every configuration
validation accepts:

* any episode that ends at rest returns more than any episode that detaches (its potential is
  >= the horizon's and its time cost <= ``time_cost * max_time``; the penalty is > 0);
* at equal simulated time, resting closer to the target returns more (strictly, within the
  horizon), and resting within tolerance adds ``success_bonus`` on top.

``tests/properties/test_reward_ranking.py`` checks both as hypothesis properties.
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

T_NACT, T_SPACING, T_TMAX, T_PSCALE, T_TCOST, T_BONUS, T_PENALTY, T_TOL, T_HORIZON, T_STOP = \
    range(10)
N_T = 10


def constants(cfg) -> np.ndarray:
    """The task constants of ``cfg`` (an EnvConfig) as one array."""
    TC = np.zeros(N_T)
    TC[T_NACT], TC[T_SPACING], TC[T_TMAX] = cfg.n_actuators, cfg.spacing, cfg.max_time
    TC[T_PSCALE], TC[T_TCOST] = cfg.progress_scale, cfg.time_cost
    TC[T_BONUS], TC[T_PENALTY], TC[T_TOL] = cfg.success_bonus, cfg.detach_penalty, cfg.tolerance
    TC[T_HORIZON] = cfg.progress_horizon
    TC[T_STOP] = 1.0 if cfg.stop_at_target else 0.0
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
    """Phi = -min(|x - target|, progress_horizon) / progress_scale."""
    return -min(abs(x - target), TC[T_HORIZON]) / TC[T_PSCALE]


@njit(cache=True)
def is_success(code, x, target, TC):
    """At rest within the tolerance of the target."""
    return code == kernel.REST and abs(x - target) <= TC[T_TOL]


@njit(cache=True)
def stop_if_delivered(x, v, t, target, TC, P, tu, tq, tqu):
    """After a stroke that left the part moving (not the last): with ``stop_at_target`` on, if the
    part left alone comes to rest within the tolerance of the target before ``max_time``, the
    conveyor fires no more: the part coasts to rest there and the outcome is REST (the episode
    ends in success). Otherwise the state is returned unchanged with outcome MOVING.

    Stopping is what a resting part gets from any later firing that leaves it in place (e.g.
    200 Hz, 100 um), so the option changes when the episode ends, not where a part can rest."""
    if TC[T_STOP] > 0.0:
        xr, _, used, rest, _ = kernel.coast(x, v, max(TC[T_TMAX] - t, 0.0), P, tu, tq, tqu)
        if rest and abs(xr - target) <= TC[T_TOL]:
            return xr, 0.0, t + used, kernel.REST
    return x, v, t, kernel.MOVING


@njit(cache=True)
def reward(code, x_old, x_new, t_old, t_new, target, TC):
    """Potential-based progress, minus the time cost, plus the success bonus; on detachment the
    part takes the horizon's potential, pays the time cost up to ``max_time`` and the detachment
    penalty (see the module docstring for why)."""
    if code == kernel.DETACHED:
        return -TC[T_HORIZON] / TC[T_PSCALE] - potential(x_old, target, TC) \
            - TC[T_TCOST] * (max(TC[T_TMAX], t_new) - t_old) - TC[T_PENALTY]
    r = potential(x_new, target, TC) - potential(x_old, target, TC) \
        - TC[T_TCOST] * (t_new - t_old)
    if is_success(code, x_new, target, TC):
        r += TC[T_BONUS]
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
