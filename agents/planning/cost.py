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
"""
from __future__ import annotations

import numpy as np

MISS = 1.0        # m: base cost of an episode that does not end at rest (detached, max_time, ...)
CAP = 10.0        # tolerances: where the robust cost's error term stops growing
TIE_BREAK = 0.1   # the weight of the robust cost's smooth term beyond the cap


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
