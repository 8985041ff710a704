"""The reach-target task of the line (MicroConveyor-v0, -v1): observation, reward, success
(the start and target of an episode are every rail's: :func:`..rail.parts.initial_state`).

What the part should do, apart from how it moves (:mod:`...physics`) and how an action fires an
actuator (:mod:`..core.actions`); :mod:`.step` composes the three into the compiled per-part step, so
a task variant is a configuration (:class:`.config.EnvConfig`) of these few functions. The task's
constants travel as one :class:`TaskConstants` ``TC`` (:func:`constants`; a NamedTuple read by
field name in compiled code).

Success (at rest within ``tolerance`` of the target) is decided here and only here: the compiled
step reports it, and the envs read it from there. The reward's arithmetic, in distances to the
target, is the one every scene shares (:mod:`..core.reward`).

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

from typing import NamedTuple

from numba import njit

from ...jit_cache import refresh as refresh_jit_cache
from ...physics import dynamics_kernel as kernel
from ..core import reward as scored
from ..core.reward import reward_constants
from ..rail.step import LENGTH_SCALE, OBS_BOUND

OBS_DIM = 6
# observations are clipped to [-OBS_BOUND, OBS_BOUND]; position error and target are divided by
# LENGTH_SCALE [m] (every rail's: ..rail.step)
VELOCITY_SCALE = 0.5      # m/s


class TaskConstants(NamedTuple):
    """The task's constants (compiled code reads the fields by name)."""

    n_actuators: int
    spacing: float           # m
    max_time: float          # s
    progress_scale: float    # m
    time_cost: float         # 1/s
    success_bonus: float     # -
    detach_penalty: float    # -
    tolerance: float         # m
    progress_horizon: float  # m
    stop_at_target: bool


def constants(cfg) -> TaskConstants:
    """The task constants of ``cfg`` (an EnvConfig)."""
    return TaskConstants(n_actuators=int(cfg.n_actuators), spacing=float(cfg.spacing),
                         **reward_constants(cfg))


@njit(cache=True)
def potential(x, target, TC):
    """Phi = -min(|x - target|, progress_horizon) / progress_scale."""
    return scored.potential(abs(x - target), TC)


@njit(cache=True)
def is_success(code, x, target, TC):
    """At rest within the tolerance of the target."""
    return scored.is_success(code, abs(x - target), TC)


@njit(cache=True)
def stop_if_delivered(x, v, t, target, TC, P, tu, tq, tqu):
    """After a stroke that left the part moving (not the last): with ``stop_at_target`` on, if the
    part left alone comes to rest within the tolerance of the target before ``max_time``, the
    conveyor fires no more: the part coasts to rest there and the outcome is REST (the episode
    ends in success). Otherwise the state is returned unchanged with outcome MOVING.

    Stopping is what a resting part gets from any later firing that leaves it in place (e.g.
    200 Hz, 100 um), so the option changes when the episode ends, not where a part can rest."""
    if TC.stop_at_target:
        xr, _, used, rest, _ = kernel.coast(x, v, max(TC.max_time - t, 0.0), P, tu, tq, tqu)
        if rest and abs(xr - target) <= TC.tolerance:
            return xr, 0.0, t + used, kernel.REST
    return x, v, t, kernel.MOVING


@njit(cache=True)
def reward(code, x_old, x_new, t_old, t_new, target, TC):
    """Potential-based progress, minus the time cost, plus the success bonus; on detachment the
    part takes the horizon's potential, pays the time cost up to ``max_time`` and the detachment
    penalty (see the module docstring for why)."""
    return scored.reward(code, abs(x_old - target), abs(x_new - target), t_old, t_new, TC)


@njit(cache=True)
def observe_part(x, v, t, fired, target, TC, positions, row):
    """The observation row of one part (see the env's docstring table)."""
    n = TC.n_actuators
    nxt = positions[fired] - x if fired < n else 0.0
    vals = ((x - target) / LENGTH_SCALE, v / VELOCITY_SCALE, nxt / TC.spacing,
            t / TC.max_time, fired / n, target / LENGTH_SCALE)
    for j in range(OBS_DIM):
        row[j] = min(max(vals[j], -OBS_BOUND), OBS_BOUND)


refresh_jit_cache(globals())
