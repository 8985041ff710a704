"""Identification of an episode's model factors from the firings seen so far.

The real part may have other friction and mass than the nominal model (the env's per-episode
randomisation). After each firing the controller knows the observed state before it, the action it
commanded and the observed state after it (a :data:`Transition`); :class:`Identifier` finds the
(friction, mass) factors under which the model best reproduces those transitions: least squares
of the position and velocity residuals after each firing, over a grid of the prior range, refined
once around its best. The controller (:mod:`.control`) then plans on the model with those factors.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, PartState

Transition = tuple[PartState, np.ndarray, PartState]  # observed before, commanded, observed after
ID_GRID = 9          # candidates per factor and pass
ID_PASSES = 2        # a coarse grid over the prior range, then a finer one around its best
ID_SCALES = (10e-6, 1e-3)  # m, m/s: position and velocity residuals are counted in these units


class Identifier:
    """Fits (friction, mass) factors [-] within [1 − ``factor_range``, 1 + ``factor_range``] on
    ``model`` (an :class:`EnvConfig` whose factor ranges admit that interval; execution noise is
    switched off for the fit). The batched env of the grid is made on the first fit and kept."""

    def __init__(self, model: EnvConfig, factor_range: float) -> None:
        self.model = dataclasses.replace(model, action_noise=0.0)
        self.factor_range = float(factor_range)
        self._env: Any = None

    def fit(self, history: list[Transition]) -> tuple[float, float]:
        """The (friction, mass) factors [-] under which the model best reproduces the observed
        firings of ``history``: least squares of the position and velocity residuals after each
        firing (in units of :data:`ID_SCALES`) over a grid of the prior range, refined once."""
        from microconveyor_env.envs import MicroConveyorVectorEnv

        r = self.factor_range
        g = ID_GRID
        if self._env is None:
            self._env = MicroConveyorVectorEnv(g * g, config=self.model)
        env = self._env
        lo_f = lo_m = 1.0 - r
        span = 2.0 * r
        best = (1.0, 1.0)
        for _ in range(ID_PASSES):
            ff, mf = (np.array(m).ravel() for m in np.meshgrid(
                np.linspace(lo_f, lo_f + span, g), np.linspace(lo_m, lo_m + span, g),
                indexing="ij"))
            cost = np.zeros(g * g)
            for before, action, after in history:
                starts = [dataclasses.replace(before, friction_factor=float(a),
                                              mass_factor=float(b))
                          for a, b in zip(ff, mf, strict=True)]
                env.reset(seed=0, options={"state": starts})
                env.step(np.repeat(action[None].astype(np.float32), g * g, axis=0))
                cost += ((env.x - after.position_m) / ID_SCALES[0]) ** 2
                cost += ((env.v - after.velocity_m_s) / ID_SCALES[1]) ** 2
            i = int(np.argmin(cost))
            best = (float(ff[i]), float(mf[i]))
            step = span / (g - 1)
            span = 2.0 * step  # the next pass: +-1 cell around the best, finer
            lo_f = min(max(best[0] - step, 1.0 - r), 1.0 + r - span)
            lo_m = min(max(best[1] - step, 1.0 - r), 1.0 + r - span)
        return best
