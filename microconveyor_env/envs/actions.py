"""The action of MicroConveyor-v0: one firing of the next actuator, ``(frequency, stroke, delay)``.

Each component lives in [-1, 1] (clipped): frequency maps log-uniformly onto ``freq_range`` [Hz],
stroke linearly onto ``stroke_range`` [m], delay linearly onto ``delay_range`` [s]. The mapping's
constants travel as one float array ``AC`` (:func:`constants`) into the compiled :func:`decode`,
with the execution noise ``action_noise`` [action units] (``AC[A_NOISE]``): when it is > 0 the env
fires ``clip(action + action_noise * z)``, ``z`` standard normal per component and firing
(docs/randomisation.md).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .config import EnvConfig

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from ..physics.jit_cache import refresh as refresh_jit_cache

ACTION_DIM = 3
A_F0, A_LOGSPAN, A_H0, A_HSPAN, A_D0, A_DSPAN, A_NOISE = range(7)
N_A = 7


def constants(cfg: EnvConfig) -> np.ndarray:
    """The action mapping of ``cfg`` (an EnvConfig) as one array."""
    AC = np.zeros(N_A)
    AC[A_F0], AC[A_LOGSPAN] = cfg.freq_range[0], cfg.log_freq_span
    AC[A_H0], AC[A_HSPAN] = cfg.stroke_range[0], cfg.stroke_range[1] - cfg.stroke_range[0]
    AC[A_D0], AC[A_DSPAN] = cfg.delay_range[0], cfg.delay_range[1] - cfg.delay_range[0]
    AC[A_NOISE] = cfg.action_noise
    return AC


@njit(cache=True)
def decode(a0: float, a1: float, a2: float, AC: np.ndarray) -> tuple[float, float, float]:
    """Action components in [-1, 1] (clipped) -> (f [Hz], h [m], delay [s])."""
    u0 = (min(max(a0, -1.0), 1.0) + 1.0) * 0.5
    u1 = (min(max(a1, -1.0), 1.0) + 1.0) * 0.5
    u2 = (min(max(a2, -1.0), 1.0) + 1.0) * 0.5
    return (AC[A_F0] * math.exp(u0 * AC[A_LOGSPAN]), AC[A_H0] + u1 * AC[A_HSPAN],
            AC[A_D0] + u2 * AC[A_DSPAN])


def encode_actions(f: npt.ArrayLike, h: npt.ArrayLike, delay: npt.ArrayLike,
                   cfg: EnvConfig) -> np.ndarray:
    """Inverse of :func:`decode`: SI values (f [Hz], h [m], delay [s], arrays or scalars) ->
    actions in [-1, 1]^3 (float32)."""
    def lin(val: npt.ArrayLike, lo: float, hi: float) -> np.ndarray:
        val = np.asarray(val, float)
        return np.zeros_like(val) if hi == lo else 2 * (val - lo) / (hi - lo) - 1

    uf = 2 * np.log(np.asarray(f, float) / cfg.freq_range[0]) / cfg.log_freq_span - 1
    return np.stack([uf, lin(h, *cfg.stroke_range), lin(delay, *cfg.delay_range)],
                    -1).astype(np.float32)


def check_actions(actions: npt.ArrayLike, n: int | None) -> np.ndarray:
    """float64 ``(n, 3)`` copy of the actions, checked.

    ``n = None`` is the single env: exactly shape ``(3,)``; otherwise exactly ``(n, 3)``. A wrong
    shape, a non-numeric dtype (bool, complex, str, object) or NaN/inf raise ``ValueError``.
    """
    expected = (3,) if n is None else (n, 3)
    what = ("one action of 3 components (frequency, stroke, delay)" if n is None else
            f"{n} actions of 3 components (frequency, stroke, delay)")
    try:
        raw = np.asarray(actions)
    except (TypeError, ValueError) as exc:  # ragged nested sequences
        raise ValueError(f"expected {what}, shape {expected}; got {type(actions).__name__} "
                         f"that is not an array ({exc})") from None
    if raw.shape != expected:
        raise ValueError(f"expected {what}, shape {expected}; got shape {raw.shape}")
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"expected {what} as real numbers; got dtype {raw.dtype}")
    a = raw.astype(np.float64).reshape(-1, 3)
    if not np.isfinite(a).all():
        raise ValueError(f"action contains NaN or inf: {a.tolist()}")
    return a



refresh_jit_cache(globals())
