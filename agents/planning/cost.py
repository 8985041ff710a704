"""The costs a search scores rollouts with, in metres, written once.

* :func:`plan_cost`: the |final error| of a part at rest, ``MISS + min(|error|, MISS)``
  otherwise (detached, out of time): any part at rest beats any part that is not.
* :func:`robust_cost`: the error capped at ``CAP`` tolerances plus a tie-break of
  ``TIE_BREAK`` · tolerance · ln(1 + error / tolerance), a part not at rest counting ``miss``
  [m]. Averaged over noisy copies of a plan, the capped term is a proxy of the success rate;
  the tie-break keeps a slope where every copy misses, which is where far targets start: with
  the cap alone a whole population costs the same, and a search sees a flat landscape and stops
  at once (at 8 mm on MicroConveyor-v1 this took the noisy success of the answer from 0 to
  0.68).
* :func:`time_weighted_cost`: the dissertation's cost of placement time against precision
  (docs/physics.md §7), ``A T_f + |e / T_d|^C`` for a part at rest after ``T_f`` [s] with error
  ``e`` [m], ``P + |e_0 / T_d|^C`` otherwise (``e_0``: the error of a part that never moved,
  so every run that rests nearer the target than its start beats every run that does not
  rest). ``A`` [1/s] weighs time, ``T_d`` [m] is the tolerance asked for: inside it the
  position term is below 1 and time decides; at twice it the position term is ``2^C`` = 1024.
"""
from __future__ import annotations

from typing import Any

import numpy as np

MISS = 1.0        # m: base cost of an episode that does not end at rest (detached, max_time, ...)
CAP = 10.0        # tolerances: where the robust cost's error term stops growing
TIE_BREAK = 0.1   # the weight of the robust cost's smooth term beyond the cap
# the time-weighted cost's constants (the dissertation's: its A ~ 1e3, "a large C", P = 1e5)
TIME_WEIGHT = 1e3   # 1/s: A, the cost of one second of placement time
EXPONENT = 10.0     # C: the position term's power
PENALTY = 1e5       # P: added to the cost of a run that does not end at rest


def plan_cost(abs_error_m: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """|error| [m] at rest, ``MISS + min(|error|, MISS)`` otherwise (NaN error: ``2 MISS``)."""
    return np.where(rest, abs_error_m,
                    MISS + np.minimum(np.nan_to_num(abs_error_m, nan=MISS), MISS))


def robust_cost(abs_error_m: np.ndarray, rest: np.ndarray, tolerance: float,
                miss: float = MISS) -> np.ndarray:
    """Per rollout [m]: ``min(e, CAP tol) + TIE_BREAK tol ln(1 + e / tol)`` with ``e`` the
    |error| of a part at rest, ``miss`` [m] otherwise (and for a NaN error)."""
    e = np.where(rest, np.nan_to_num(abs_error_m, nan=miss), miss)
    tol = tolerance
    return np.minimum(e, CAP * tol) + TIE_BREAK * tol * np.log1p(e / tol)


def time_weighted_cost(error_m: Any, time_s: Any, rest: Any, time_weight: float,
                       scale_m: float, start_error_m: float, exponent: float = EXPONENT,
                       penalty: float = PENALTY) -> np.ndarray:
    """Per run: ``time_weight · time_s + |error_m / scale_m|^exponent`` where ``rest``, else
    ``penalty + |start_error_m / scale_m|^exponent``. ``error_m`` [m]: final position minus
    target (signed or not); ``time_s`` [s]: the time until the part rests; ``rest`` [bool]:
    the part came to rest; ``time_weight`` A [1/s]; ``scale_m`` T_d [m]: the tolerance asked
    for; ``start_error_m`` [m]: the error of the part where it started. Arrays or scalars;
    returns an array."""
    e = np.asarray(error_m, dtype=float)
    t = np.asarray(time_s, dtype=float)
    miss = np.abs(e / scale_m) ** exponent
    failed = penalty + abs(start_error_m / scale_m) ** exponent
    return np.where(np.asarray(rest, dtype=bool), time_weight * t + miss, failed)
