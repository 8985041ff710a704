"""The conveyor's model-predictive controller with a horizon of one firing, seeded by a policy:
fire what the policy fires, and where that firing is the policy's last, re-aim it on the model
so that the part comes to rest on the target (:class:`SeededExpert`; DAgger's expert on
MicroConveyor-v1, :mod:`agents.imitation.dagger`).

On MicroConveyor-v1 the last firing sets where the part rests: an error of 10^-3 in its action
moves a far target's landing by tens of µm, and nothing fires after it to correct that. A policy
gets the firings before it right (they carry the part along, the same for a band of targets)
and leaves its error in the last one. So, for many part states at once:

1. the policy's firing is fired on the nominal model from each state (the env's own compiled
   step on a part container whose state arrays are written directly, as
   :class:`~.positioner.BatchExpert` does); it is the last when the part comes to rest after it
   (or when it is the last actuator's);
2. for the last ones, Gauss-Newton on its three actions: the derivatives of the rest position by
   forward differences, the minimal-norm step that zeroes the error (capped at ``max_step``),
   each step kept only if it brings the rest closer, ``iterations`` times; kept when the part
   then rests within ``accept_m`` of the target. Later firings, should the part not rest
   within the env's tolerance, are the no-op of :data:`~agents.rl.refinement.corrections.NOOP`
   (200 Hz, 100 µm after 0.1 s: a part stays put), so the model's rest is where the part rests.

The same correction as ``refine``'s (:mod:`agents.rl.refinement.corrections`), made from any
state the policy being trained reaches rather than from the seed's own episodes. The model is
nominal; per-episode randomisation is not modelled (v1's criterion is on the nominal env).
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from microconveyor_env.envs.line.config import EnvConfig
from microconveyor_env.envs.line.state import Conveyor
from microconveyor_env.physics import dynamics_kernel as kernel

from ..rl.refinement.corrections import NOOP

__all__ = ["SeededExpert"]


class SeededExpert:
    """A policy's firings with its last one re-aimed on the nominal model (module docstring).

    ``config``: the conveyor scene (its randomisation is ignored: the model is nominal);
    ``seed``: any callable mapping raw observations ``(M, obs)`` to actions ``(M, 3)`` (a
    loaded policy's mean action); ``iterations`` [-] Gauss-Newton steps; ``step`` [action
    units] forward-difference step; ``max_step`` [action units] longest Gauss-Newton step;
    ``accept_m`` [m] a re-aimed firing is kept when the part then rests this close."""

    def __init__(self, config: EnvConfig, seed: Any, iterations: int = 6, step: float = 1e-3,
                 max_step: float = 0.2, accept_m: float = 2e-6) -> None:
        if type(config) is not EnvConfig:   # the positioner's config is a subclass
            raise ValueError("the seeded expert re-aims the firings of a conveyor "
                             f"(MicroConveyor-v0/-v1), not of {type(config).__name__}")
        self.config = dataclasses.replace(config, action_noise=0.0, num_threads=1,
                                          friction_factor_range=(1.0, 1.0),
                                          mass_factor_range=(1.0, 1.0), observe_history=0)
        self.seed = seed
        self.iterations, self.step, self.max_step, self.accept_m = (iterations, step, max_step,
                                                                    accept_m)
        self._parts: dict[int, Conveyor] = {}

    def _container(self, n: int) -> Conveyor:
        if n not in self._parts:
            self._parts[n] = Conveyor(self.config, n, num_threads=1)
        return self._parts[n]

    def rest_after(self, state: tuple[np.ndarray, ...],
                   actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fire ``actions`` ``(M, 3)`` on the model from ``state`` (x [m], v [m/s], t [s],
        fired [-], target [m], arrays of M), then no-ops until the episode ends. Returns where
        each part ends [m], the outcome code of that end and of the firing itself
        (:mod:`~microconveyor_env.physics.dynamics_kernel` codes)."""
        c = self._container(len(actions))
        p = c.parts
        p.x[:], p.v[:], p.t[:], p.fired[:], p.target[:] = state
        first = c.step(np.asarray(actions, np.float64)).outcome.copy()
        code = first.copy()
        noop = np.repeat(NOOP[None].astype(np.float64), len(actions), 0)
        while True:
            live = (code == kernel.MOVING) & (p.fired < self.config.n_actuators)
            if not live.any():
                break
            code = np.where(live, c.step(noop, live).outcome, code)
        return p.x.copy(), code, first

    def _reaim(self, state: tuple[np.ndarray, ...],
               a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton on each row's firing (module docstring, step 2): the actions and the
        final signed error [m] (inf: not at rest)."""
        a = a.copy()
        target = state[4]
        x, code, _ = self.rest_after(state, a)
        err = np.where(code == kernel.REST, x - target, np.inf)
        m = len(a)
        three = tuple(np.repeat(s, 3) for s in state)
        for _ in range(self.iterations):
            h = np.where(a + self.step <= 1.0, self.step, -self.step)   # inside the box
            probes = np.repeat(a[:, None], 3, 1)
            probes[:, [0, 1, 2], [0, 1, 2]] += h
            xp, cp, _ = self.rest_after(three, probes.reshape(-1, 3))
            grad = (xp.reshape(m, 3) - x[:, None]) / h
            usable = (np.isfinite(err) & (np.abs(err) > 0.1 * self.accept_m)
                      & (cp.reshape(m, 3) == kernel.REST).all(1) & ((grad ** 2).sum(1) > 0))
            if not usable.any():
                break
            delta = np.zeros((m, 3))
            delta[usable] = (-err[usable, None] * grad[usable]
                             / (grad[usable] ** 2).sum(1, keepdims=True))
            norm = np.linalg.norm(delta, axis=1, keepdims=True)
            delta *= np.minimum(1.0, self.max_step / np.maximum(norm, 1e-300))
            moved = np.clip(a + delta, -1.0, 1.0)
            xm, cm, _ = self.rest_after(state, moved)
            em = np.where(cm == kernel.REST, xm - target, np.inf)
            better = usable & (np.abs(em) < np.abs(err))
            a[better], x[better], err[better] = moved[better], xm[better], em[better]
        return a, err

    def act(self, obs: np.ndarray, parts: Any,
            rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The expert's actions ``(M, 3)`` (float32, in the box) for parts in the states
        ``parts`` (arrays ``x``, ``v``, ``t``, ``fired``, ``target``: a batched env's
        ``conveyor.parts``) observed as ``obs``; and which of them were re-aimed (the rest are
        the seed's own). ``rows`` (bool ``(M,)``): label only these (the others, e.g. finished
        episodes, get the seed's action untouched); parts that have fired every actuator are
        never fired again."""
        a = np.clip(np.asarray(self.seed(obs), np.float64), -1.0, 1.0)
        state = tuple(np.array(getattr(parts, k)) for k in ("x", "v", "t", "fired", "target"))
        fixed = np.zeros(len(a), bool)
        todo = state[3] < self.config.n_actuators
        if rows is not None:
            todo &= np.asarray(rows, bool)
        idx = np.flatnonzero(todo)
        if len(idx):
            sub = tuple(s[idx] for s in state)
            _, _, first = self.rest_after(sub, a[idx])
            last = idx[(first == kernel.REST) | (sub[3] == self.config.n_actuators - 1)]
            if len(last):
                ra, err = self._reaim(tuple(s[last] for s in state), a[last])
                keep = (np.abs(err) <= self.accept_m) & np.any(ra != a[last], axis=1)
                a[last[keep]] = ra[keep]
                fixed[last[keep]] = True
        return a.astype(np.float32), fixed
