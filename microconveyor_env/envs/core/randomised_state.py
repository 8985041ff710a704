"""The check of a saved part state's randomisation fields (this episode's factors and noise),
every scene's (:mod:`.randomisation`: the draws it checks against)."""
from __future__ import annotations

from typing import Any

import numpy as np

from .part_state import within
from .randomisation import NOISE_BOUND, NOISE_COMPONENTS, Randomised

__all__ = ["check_saved"]


def check_saved(friction_factor: Any, mass_factor: Any, noise: Any, cfg: Randomised,
                rows: int) -> tuple[float | None, float | None, tuple | None]:
    """A saved state's randomisation fields checked against ``cfg``: factors (None: the env's
    own draw) inside its ranges, noise (None: the env's own) only with ``action_noise`` > 0, of
    shape ``(rows, 3)`` and within :data:`NOISE_BOUND`. One-line ValueErrors name the field."""
    for name, val, (lo, hi) in (("friction_factor", friction_factor, cfg.friction_factor_range),
                                ("mass_factor", mass_factor, cfg.mass_factor_range)):
        if val is not None:
            within(name, val, lo, hi, "", 1.0, f"this env's {name}_range")
    if noise is not None:
        if cfg.action_noise <= 0.0:
            raise ValueError("part state noise is given but the env has no execution noise "
                             "(action_noise = 0)")
        try:
            arr = np.asarray(noise, dtype=float)
        except (TypeError, ValueError):
            arr = np.full(1, np.nan)
        if arr.shape != (rows, NOISE_COMPONENTS):
            raise ValueError(f"part state noise must be ({rows}, {NOISE_COMPONENTS}) numbers, "
                             f"got shape {arr.shape}")
        bad = np.argwhere(~(np.abs(arr) <= NOISE_BOUND))  # NaN too
        if len(bad):
            i, j = bad[0]
            within(f"noise[{i}][{j}]", arr[i, j], -NOISE_BOUND, NOISE_BOUND, "", 1.0,
                   "standard normal draws")
        noise = tuple(map(tuple, arr.tolist()))
    return (None if friction_factor is None else float(friction_factor),
            None if mass_factor is None else float(mass_factor), noise)
