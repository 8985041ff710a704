"""The firing every scene's action decodes to, ``(frequency, stroke, delay)``: the line's whole
action (the next actuator fires), the plane's last three components (after the aim that picks
the actuator).

Each component lives in [-1, 1] (clipped): frequency maps log-uniformly onto ``freq_range`` [Hz],
stroke linearly onto ``stroke_range`` [m], delay linearly onto ``delay_range`` [s]. The mapping's
constants travel as one :class:`ActionConstants` (:func:`constants`, a NamedTuple of floats read by
field name in compiled code) into the compiled :func:`decode`, with the execution noise
``action_noise`` [action units]: when it is > 0 the env fires ``clip(action + action_noise * z)``,
``z`` standard normal per component and firing (docs/randomisation.md).
"""
from __future__ import annotations

import math
from typing import NamedTuple, Protocol

import numpy as np
import numpy.typing as npt
from numba import njit

from ...jit_cache import refresh as refresh_jit_cache

ACTION_DIM = 3


class ActionConstants(NamedTuple):
    """The action mapping (all float64; compiled code reads the fields by name)."""

    f0: float        # Hz, lowest frequency (freq_range[0])
    log_span: float  # -, ln(freq_range[1] / freq_range[0])
    h0: float        # m, lowest stroke
    h_span: float    # m, stroke_range[1] - stroke_range[0]
    d0: float        # s, shortest delay
    d_span: float    # s, delay_range[1] - delay_range[0]
    noise: float     # action units, execution noise sigma (0: off)


class FiringRanges(Protocol):
    """What the decoding reads of a scene's config (:class:`~.config.SceneConfig` has it)."""

    @property
    def freq_range(self) -> tuple: ...
    @property
    def stroke_range(self) -> tuple: ...
    @property
    def delay_range(self) -> tuple: ...
    @property
    def log_freq_span(self) -> float: ...


def constants(cfg: FiringRanges, noise: float = 0.0) -> ActionConstants:
    """The action mapping of ``cfg`` (a scene's config) with execution noise ``noise`` [action
    units] (the line's ``action_noise``; 0: off)."""
    return ActionConstants(
        f0=float(cfg.freq_range[0]), log_span=float(cfg.log_freq_span),
        h0=float(cfg.stroke_range[0]), h_span=float(cfg.stroke_range[1] - cfg.stroke_range[0]),
        d0=float(cfg.delay_range[0]), d_span=float(cfg.delay_range[1] - cfg.delay_range[0]),
        noise=float(noise))


@njit(cache=True)
def decode(a0: float, a1: float, a2: float, AC: ActionConstants) -> tuple[float, float, float]:
    """Action components in [-1, 1] (clipped) -> (f [Hz], h [m], delay [s])."""
    u0 = (min(max(a0, -1.0), 1.0) + 1.0) * 0.5
    u1 = (min(max(a1, -1.0), 1.0) + 1.0) * 0.5
    u2 = (min(max(a2, -1.0), 1.0) + 1.0) * 0.5
    return (AC.f0 * math.exp(u0 * AC.log_span), AC.h0 + u1 * AC.h_span,
            AC.d0 + u2 * AC.d_span)


def encode_actions(f: npt.ArrayLike, h: npt.ArrayLike, delay: npt.ArrayLike,
                   cfg: FiringRanges) -> np.ndarray:
    """Inverse of :func:`decode`: SI values (f [Hz], h [m], delay [s], arrays or scalars) ->
    actions in [-1, 1]^3 (float32)."""
    def lin(val: npt.ArrayLike, lo: float, hi: float) -> np.ndarray:
        val = np.asarray(val, float)
        return np.zeros_like(val) if hi == lo else 2 * (val - lo) / (hi - lo) - 1

    uf = 2 * np.log(np.asarray(f, float) / cfg.freq_range[0]) / cfg.log_freq_span - 1
    return np.stack([uf, lin(h, *cfg.stroke_range), lin(delay, *cfg.delay_range)],
                    -1).astype(np.float32)


refresh_jit_cache(globals())
