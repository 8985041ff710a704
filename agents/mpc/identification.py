"""Identification of an episode's model factors from the firings seen so far.

The real part may have other friction and mass than the nominal model (the env's per-episode
randomisation). After each firing the controller knows the observed state before it, the action it
commanded and the observed state after it (a :data:`Transition`). An identifier counts each
(:meth:`add`) and says the (friction, mass) factors [-] the model should plan with now
(:meth:`factors`); the controller (:mod:`.control`) then plans on the model with those factors.

* :class:`Identifier` (the line's): the (friction, mass) factors under which the model best
  reproduces the transitions: least squares of the position and velocity residuals after each
  firing, over a grid of the prior range, refined once around its best.
* :class:`FrictionFit` (the positioner's): the effective friction factor alone. A firing there
  runs the part to rest, and its rest depends on the friction and mass factors through their
  ratio (a part ``k`` times heavier on ``k`` times the friction rests where the nominal part
  does, within 0.2 % of the displacement over ±10 %), so the rests cannot tell them apart; the
  fitted *effective* friction factor (mass held nominal) is the one number that carries the
  difference. Each past firing's observed rest against the model's rest from the observed state
  before it and the **commanded** action (the env does not say what noise it added), least
  squares over a grid of friction factors with a weak prior at 1, refined by a parabola through
  the best three.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig

# one observed firing: the state before it (as observed), the action commanded, the state after
Transition = tuple[Any, np.ndarray, Any]
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
        self.history: list[Transition] = []

    def reset(self) -> None:
        """Forget every firing (a new episode)."""
        self.history = []

    def add(self, transition: Transition) -> None:
        """Count one observed firing."""
        self.history.append(transition)

    def factors(self) -> tuple[float, float]:
        """The (friction, mass) factors [-] fitted from the firings counted (:meth:`fit`)."""
        return self.fit(self.history)

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


class FrictionFit:
    """The effective friction factor [-] fitted from observed firings (module docstring) on
    ``model`` (a :class:`agents.planning.scene.FiringModel`) with ``settings`` (an
    :class:`~.control.OneStepSettings`): on a grid of ``settings.factor_points`` factors over [1 − R, 1 + R], the cost of each is the sum
    of the squared rest residuals (in units of ``residual_m``) plus ``((factor − 1) /
    prior_width)²``; each firing adds its residuals once (:meth:`add`), and :meth:`estimate`
    refines the grid's best by a parabola through it and its neighbours."""

    def __init__(self, model: Any, settings: Any) -> None:
        self.model = model
        self.settings = s = settings
        self.grid = np.linspace(1.0 - s.factor_range, 1.0 + s.factor_range, s.factor_points)
        self.prior = ((self.grid - 1.0) / s.prior_width) ** 2
        self.reset()

    def reset(self) -> None:
        """Forget every firing (a new episode)."""
        self.cost = self.prior.copy()
        self.firings = 0

    def add(self, transition: Transition) -> None:
        """Count one observed firing: the model's rest at every grid factor against the
        observed one. A factor under which the model part detaches costs as if it rested
        1 mm off."""
        before, action, after = transition
        states = [dataclasses.replace(before, friction_factor=float(f), mass_factor=1.0)
                  for f in self.grid]
        x, ok = self.model.rests(states, np.repeat(np.asarray(action, float)[None],
                                                   len(self.grid), axis=0))
        r = np.where(ok, x - after.position_m, 1e-3) / self.settings.residual_m
        self.cost += r ** 2
        self.firings += 1

    def estimate(self) -> float:
        """The fitted factor [-] (1 before any firing)."""
        if not self.firings:
            return 1.0
        i = int(np.argmin(self.cost))
        if 0 < i < len(self.grid) - 1:
            c0, c1, c2 = self.cost[i - 1:i + 2]
            den = c0 - 2.0 * c1 + c2
            if den > 0:
                step = self.grid[1] - self.grid[0]
                return float(self.grid[i] + 0.5 * step * (c0 - c2) / den)
        return float(self.grid[i])

    def factors(self) -> tuple[float, float]:
        """The fitted friction factor and the nominal mass factor [-]."""
        return (self.estimate(), 1.0)
