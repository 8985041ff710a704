"""A one-step model-based expert for MicroPositioner-v0, batched over many parts: for every part,
every reachable actuator x a grid of frequencies x strokes fired on the nominal model from where
the part rests, and the firing whose predicted rest is nearest the target chosen.

The model is the env's own compiled step on a part container of the positioner
(:class:`~microconveyor_env.envs.positioner.state.PositionerParts`) whose state arrays are
written directly (one compiled call fires every candidate of every part), with the nominal
friction and mass: the expert knows nothing of an episode's hidden factors or noise. A candidate
that detaches, or whose neighbour in frequency or stroke does, is refused (a margin from
detachment for the execution noise); with ``heavier`` δ > 0 so is one that detaches on the
model of a part 1 + δ times heavier (the mass alone sets when the surface outruns the part's
pull-off, so an unknown mass is what turns a firing near the edge into a detachment); one that
does not bring the part closer is refused too.
Of the candidates predicted to rest within ``slack`` of the best one, the gentlest fires (the
lowest frequency, then the shortest stroke): it lands as near, accelerates the part least (the
furthest from detachment) and makes the expert's answer change smoothly with the state, which a
network imitating it needs (an argmin over the grid jumps between firings that land equally
near).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from microconveyor_env.envs.line.config import FACTOR_BOUNDS
from microconveyor_env.envs.line.randomisation import apply_factors
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.state import PositionerParts
from microconveyor_env.physics import dynamics_kernel as kernel

AIMS = 3          # the reachable actuators tried per part (the nearest three)
REACH = 0.3e-3    # m: an actuator farther from the part moves it by nothing measurable


class BatchExpert:
    """The expert of ``config``'s scene (its randomisation is the real env's; the model is
    nominal). ``frequencies`` and ``strokes`` [-]: candidates evenly over each action's
    [-1, 1]; ``margin`` [-]: grid cells around a detaching candidate refused too; ``slack``
    [m]: how much farther than the best a gentler candidate may rest; ``heavier`` δ [-]: a
    candidate that detaches on the model with a part 1 + δ times heavier is refused too (module
    docstring)."""

    def __init__(self, config: PositionerConfig, frequencies: int = 41, strokes: int = 6,
                 margin: int = 1, slack: float = 5e-6, heavier: float = 0.0) -> None:
        self.config = dataclasses.replace(config, action_noise=0.0, num_threads=1,
                                          friction_factor_range=FACTOR_BOUNDS,
                                          mass_factor_range=FACTOR_BOUNDS)
        self.fa = np.linspace(-1.0, 1.0, frequencies)
        self.ha = np.linspace(-1.0, 1.0, strokes)
        self.margin = margin
        self.slack = slack
        self.heavier = heavier
        self.per_part = AIMS * frequencies * strokes
        self._parts: dict[int, PositionerParts] = {}
        self._factored: dict[int, bool] = {}   # a container whose rows hold other factors
        self.positions = np.asarray(config.actuator_positions)

    def _container(self, n: int) -> PositionerParts:
        if n not in self._parts:
            self._parts[n] = PositionerParts(self.config, n, num_threads=1)
        return self._parts[n]

    def candidates(self, x: np.ndarray) -> np.ndarray:
        """``(M, AIMS, F, H, 3)`` actions: each of the nearest actuators aimed at exactly."""
        s, reach = self.config.spacing, self.config.pick_reach
        j0 = np.clip(np.floor(x / s + 0.5).astype(int), 1, len(self.positions) - 2)
        js = j0[:, None] + np.arange(-1, AIMS - 1)[None, :]
        aim = np.clip((self.positions[js] - x[:, None]) / reach, -1.0, 1.0)
        m, f, h = len(x), len(self.fa), len(self.ha)
        a = np.empty((m, AIMS, f, h, 3))
        a[..., 0] = aim[:, :, None, None]
        a[..., 1] = self.fa[None, None, :, None]
        a[..., 2] = self.ha[None, None, None, :]
        return a

    def act(self, x: np.ndarray, t: np.ndarray, target: np.ndarray,
            factors: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """For parts resting at ``x`` [m] at time ``t`` [s] with ``target`` [m]: the expert's
        actions ``(M, 3)`` and whether each has one (False: no allowed firing brings the part
        closer). ``factors`` ``(M, 2)``: each part's friction and mass factors [-] for the
        model (a controller that knows them: a reference, never a method); None: nominal."""
        m = len(x)
        acts = self.candidates(np.asarray(x, float))
        flat = acts.reshape(-1, 3)
        c = self._container(len(flat))
        p = c.parts
        rep = self.per_part
        if factors is not None or self._factored.get(len(flat)):
            fac = np.ones((m, 2)) if factors is None else np.asarray(factors, float)
            base = c.sim.params
            for i in range(m):
                rows = c.consts.P[i * rep:(i + 1) * rep]
                apply_factors(base, rows[0], fac[i, 0], fac[i, 1])
                rows[1:] = rows[0]
            self._factored[len(flat)] = factors is not None
        p.x[:] = np.repeat(x, rep)
        p.t[:] = np.repeat(t, rep)
        p.target[:] = np.repeat(target, rep)
        p.fired[:] = 0
        shape = (m, AIMS, len(self.fa), len(self.ha))
        bad = np.zeros(shape, bool)
        if self.heavier > 0.0:   # first the heavier part: its rests are not the prediction
            base = c.consts.P.copy()
            fac = np.ones((m, 2)) if factors is None else np.asarray(factors, float)
            for i in range(m):
                apply_factors(c.sim.params, c.consts.P[i * rep], fac[i, 0],
                              fac[i, 1] * (1.0 + self.heavier))
                c.consts.P[i * rep + 1:(i + 1) * rep] = c.consts.P[i * rep]
            c.step(flat)
            code = c.out.outcome.reshape(shape)
            bad |= ~((code == kernel.MOVING) | (code == kernel.REST))
            c.consts.P[:] = base
            p.x[:] = np.repeat(x, rep)
            p.t[:] = np.repeat(t, rep)
            p.fired[:] = 0
        c.step(flat)
        code = c.out.outcome.reshape(shape)
        bad |= ~((code == kernel.MOVING) | (code == kernel.REST))
        k = self.margin
        grown = bad.copy()
        for d in range(1, k + 1):
            grown[:, :, d:] |= bad[:, :, :-d]
            grown[:, :, :-d] |= bad[:, :, d:]
            grown[:, :, :, d:] |= bad[:, :, :, :-d]
            grown[:, :, :, :-d] |= bad[:, :, :, d:]
        err = np.abs(p.x.reshape(code.shape) - np.asarray(target)[:, None, None, None])
        err = np.where(grown, np.inf, err).reshape(m, -1)
        least = err.min(axis=1, keepdims=True)
        # the gentlest within the slack: candidates are ordered aim, frequency, stroke; rank
        # them by frequency, then stroke, then the aim's order
        near = err <= least + self.slack
        f, h = len(self.fa), len(self.ha)
        rank = (np.arange(f)[None, :, None] * (h * AIMS) + np.arange(h)[None, None, :] * AIMS
                + np.arange(AIMS)[:, None, None]).ravel()
        best = np.argmin(np.where(near, rank[None, :], rank.max() + 1), axis=1)
        now = np.abs(np.asarray(x) - np.asarray(target))
        ok = err[np.arange(m), best] < now - 0.1e-6
        return acts.reshape(m, -1, 3)[np.arange(m), best].astype(np.float32), ok
