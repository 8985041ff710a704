"""The experts DAgger imitates (:mod:`agents.imitation.dagger`), one per scene it serves, each
labelling many part states at once: :func:`expert_for` picks it.

* :class:`BatchExpert`, MicroPositioner-v0's: the one-step search of
  :class:`~.control.OneStepPlanner` batched over many parts, its candidates ranked on the
  scene's firing map and the few it would choose fired on the full model, which has the last
  word.
* :class:`SeededExpert`, the conveyor line's (MicroConveyor-v1): model-predictive control with
  a horizon of one firing, seeded by a policy: fire what the policy fires, and where that firing
  is the policy's last, re-aim it on the model so that the part comes to rest on the target.

On MicroConveyor-v1 the last firing sets where the part rests: an error of 10^-3 in its action
moves a far target's landing by tens of µm, and nothing fires after it to correct that. A policy
gets the firings before it right (they carry the part along, the same for a band of targets)
and leaves its error in the last one. So, for many part states at once:

1. the policy's firing is fired on the nominal model from each state (the env's own compiled
   step on a part container whose state arrays are written directly, as :class:`BatchExpert`
   does); it is the last when the part comes to rest after it (or when it is the last
   actuator's);
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
import math
from typing import Any

import numpy as np

from microconveyor_env.envs.core.randomisation import FACTOR_BOUNDS, apply_factors
from microconveyor_env.envs.line.config import EnvConfig
from microconveyor_env.envs.line.state import Conveyor
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.state import PositionerParts
from microconveyor_env.physics import dynamics_kernel as kernel
from microconveyor_env.physics.forces import I_MASS

from ..planning import PositionerScene, scene_of
from ..planning.plane import LABEL_SETTINGS, PlaneController, labeller
from ..planning.rest_expert import MIN_GAIN, RestRanking, check_integers
from ..planning.scene import MapModel
from ..rl.refinement.corrections import NOOP
from .control import dilate

__all__ = ["BatchExpert", "SeededExpert", "expert_for"]


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

    def label(self, obs: np.ndarray, venv: Any,
              live: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """DAgger's labels for the batched env ``venv`` observed as ``obs``, its rows ``live``
        only: the actions, which have one (all), which were re-aimed."""
        acts, fixed = self.act(obs, venv.conveyor.parts, rows=live)
        return acts, np.ones(len(acts), bool), fixed


AIMS = 3          # the reachable actuators tried per part (the nearest three)
CHECKED = 24      # candidates per part fired again on the heavier model, in the order tried
SEARCHES = ("map", "model")   # where BatchExpert ranks its candidates
CONFIRM = 8       # per part, twice this many candidates confirmed on the full model (map search)


class BatchExpert:
    """The one-step search of :class:`~.control.OneStepPlanner` batched over many parts (DAgger's expert
    and the sizing study play hundreds of episodes at once): for every part, each of the
    ``AIMS`` nearest actuators x ``frequencies`` x ``strokes`` from where the part rests. The
    model is nominal (or, with ``factors``, each part's friction and mass: a reference that
    knows them, never a method); it never sees an episode's noise. Full-model firings run the
    env's own step on a part container
    (:class:`~microconveyor_env.envs.positioner.state.PositionerParts`) whose state arrays are
    written directly, not through resets.

    ``search`` says where the candidates are ranked:

    * ``"map"`` (nominal model): on the scene's firing map
      (:meth:`agents.planning.PositionerScene.map_model`, under a microsecond a candidate); a
      candidate in a cell the map does not trust (it touches a detachment, or lies off the map)
      or that would run past the episode's time limit counts as one that detaches. The ``confirm``
      first of the ranking below and the ``confirm`` nearest not among them are then fired on
      the full model, and the rule below is applied again to the full model's answers alone:
      the label's predicted landing is always the full model's (bit for bit the env's, for the
      float32 action the label is);
    * ``"model"``: every candidate fired on the full model (``factors`` given: always this).

    A candidate that detaches, or whose neighbour within ``margin`` [-] grid cells in frequency
    or stroke does, is refused; with ``heavier`` δ [-] > 0 so is one that detaches on the model
    of a part 1 + δ times heavier (the mass alone sets when the surface outruns the part's
    pull-off, so an unknown mass is what turns a firing near the edge into a detachment); so is
    one that does not bring the part closer. Of the rest, among those predicted to come to rest
    within ``slack`` [m] of the nearest, the gentlest fires (the lowest frequency, then the
    shortest stroke): the rest scenes' rule (:mod:`agents.planning.rest_expert`). The heavier
    model checks the first ``CHECKED`` in that order (then by predicted error), and the first
    one it does not detach fires.
    ``frequencies`` and ``strokes`` [-]: candidates evenly over each action's [-1, 1];
    ``config``'s randomisation is the real env's, unused."""

    def __init__(self, config: PositionerConfig, frequencies: int = 41, strokes: int = 6,
                 margin: int = 1, slack: float = 5e-6, heavier: float = 0.0,
                 search: str = "map", confirm: int = CONFIRM) -> None:
        if search not in SEARCHES:
            raise ValueError(f"search = {search!r} is invalid: must be one of {SEARCHES}")
        self.confirm = confirm
        check_integers(self, [("confirm", 1)])
        self.config = dataclasses.replace(config, action_noise=0.0, num_threads=1,
                                          friction_factor_range=FACTOR_BOUNDS,
                                          mass_factor_range=FACTOR_BOUNDS)
        self.fa = np.linspace(-1.0, 1.0, frequencies)
        self.ha = np.linspace(-1.0, 1.0, strokes)
        self.margin = margin
        self.slack = slack
        self.heavier = heavier
        self.search = search
        self.per_part = AIMS * frequencies * strokes
        self._parts: dict[int, PositionerParts] = {}
        self._factored: dict[int, bool] = {}   # a container whose rows hold other factors
        self.positions = np.asarray(config.actuator_positions)
        # candidates are ordered aim, frequency, stroke; gentleness ranks them by frequency,
        # then stroke, then aim
        self.ranking = RestRanking(AIMS, frequencies, strokes, slack, confirm)
        self._rank = self.ranking.rank
        self.map = MapModel(self.config) if search == "map" else None
        self.full_firings = 0   # full-model firings so far (map queries are not firings)

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
        model (a controller that knows them: a reference, never a method; searched on the full
        model); None: nominal."""
        acts, ok, _ = self.choose(x, t, target, factors)
        return acts, ok

    def choose(self, x: np.ndarray, t: np.ndarray, target: np.ndarray,
               factors: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`act`'s actions and flags, and where the full model puts each part after its
        action [m] (inf where no candidate comes to rest)."""
        x, t, target = (np.asarray(a, float) for a in (x, t, target))
        if self.map is None or factors is not None:
            return self._act_model(x, t, target, factors)
        return self._act_map(x, t, target)

    def fire(self, x: np.ndarray, t: np.ndarray, target: np.ndarray, actions: np.ndarray,
             mass_factor: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """One firing of ``actions`` ``(B, 3)`` on the full model (nominal friction, the mass
        times ``mass_factor``) from parts resting at ``x`` [m] at ``t`` [s] with ``target``
        [m] (arrays of B): where each comes to rest [m] and whether it does (no detachment, no
        time limit)."""
        b = len(actions)
        cap = 1 << max(b - 1, 0).bit_length()   # containers by powers of two, the rest idle
        c = self._container(cap)
        P = c.consts.P
        P[:] = c.sim.params
        P[:, I_MASS] = c.sim.params[I_MASS] * mass_factor
        self._factored[cap] = mass_factor != 1.0
        p = c.parts
        for arr, val in ((p.x, x), (p.t, t), (p.target, target)):
            arr[:b] = val
            arr[b:] = 0.0
        p.fired[:] = 0
        a = np.zeros((cap, 3))
        a[:b] = actions
        active = np.zeros(cap, bool)
        active[:b] = True
        out = c.step(a, active)
        self.full_firings += b
        code = out.outcome[:b]
        return p.x[:b].copy(), (code == kernel.MOVING) | (code == kernel.REST)

    def _act_map(self, x: np.ndarray, t: np.ndarray,
                 target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`act` ranked on the map and confirmed on the full model (class docstring)."""
        assert self.map is not None
        m, per = len(x), self.per_part
        rows = np.arange(m)
        shape = (m, AIMS, len(self.fa), len(self.ha))
        acts = self.candidates(x).astype(np.float32).reshape(m, per, 3)   # as the label fires
        xr, tr, trusted = self.map.rests(np.repeat(x, per), acts.reshape(-1, 3))
        late = np.repeat(t, per) + np.nan_to_num(tr, nan=np.inf) > self.config.max_time
        bad = (~trusted | late).reshape(shape)
        err = np.where(dilate(bad, self.margin), np.inf,
                       np.abs(xr.reshape(shape) - target[:, None, None, None])).reshape(m, per)
        # the confirm first in the expert's order and the confirm nearest not among them
        pick = self.ranking.shortlist(err)
        mapped = np.isfinite(np.take_along_axis(err, pick, axis=1))
        sel = acts[rows[:, None], pick]                             # (m, 2k, 3)
        c = pick.shape[1]
        sel64 = sel.reshape(-1, 3).astype(np.float64)
        xf, ok = self.fire(np.repeat(x, c), np.repeat(t, c), np.repeat(target, c), sel64)
        full = np.where(mapped & ok.reshape(m, c), np.abs(xf.reshape(m, c) - target[:, None]),
                        np.inf)
        order = self.ranking.ordered(full, self._rank[pick])
        best = order[:, 0]
        if self.heavier > 0.0:   # the first in that order that a heavier part survives
            def survives(top: np.ndarray) -> np.ndarray:
                kk = top.shape[1]
                _, hok = self.fire(np.repeat(x, kk), np.repeat(t, kk), np.repeat(target, kk),
                                   sel64.reshape(m, c, 3)[rows[:, None], top].reshape(-1, 3),
                                   1.0 + self.heavier)
                return hok.reshape(m, kk)
            best = self.ranking.first_surviving(order, full, CHECKED, survives)
        ok_best = full[rows, best] < np.abs(x - target) - MIN_GAIN
        rest = np.where(np.isfinite(full[rows, best]),
                        xf.reshape(m, c)[rows, best], np.inf)
        return sel[rows, best], ok_best, rest

    def _act_model(self, x: np.ndarray, t: np.ndarray, target: np.ndarray,
                   factors: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`act` with every candidate fired on the full model (class docstring)."""
        m = len(x)
        acts = self.candidates(x).astype(np.float32).astype(np.float64)   # as the label fires
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
        c.step(flat)
        self.full_firings += len(flat)
        code = c.out.outcome.reshape(shape)
        grown = dilate(~((code == kernel.MOVING) | (code == kernel.REST)), self.margin)
        err = np.abs(p.x.reshape(code.shape) - np.asarray(target)[:, None, None, None])
        err = np.where(grown, np.inf, err).reshape(m, -1)
        order = self.ranking.ordered(err, self._rank[None, :])
        best = order[:, 0]
        if self.heavier > 0.0:   # the first of the CHECKED in that order that a heavier part survives
            def survives(top: np.ndarray) -> np.ndarray:
                k = top.shape[1]
                fac = np.ones((m, 2)) if factors is None else np.asarray(factors, float)
                hc = self._container(m * k)
                self._factored[m * k] = True
                for i in range(m):
                    apply_factors(hc.sim.params, hc.consts.P[i * k], fac[i, 0],
                                  fac[i, 1] * (1.0 + self.heavier))
                    hc.consts.P[i * k + 1:(i + 1) * k] = hc.consts.P[i * k]
                hp = hc.parts
                hp.x[:], hp.t[:] = np.repeat(x, k), np.repeat(t, k)
                hp.target[:], hp.fired[:] = np.repeat(target, k), 0
                hc.step(acts.reshape(m, -1, 3)[np.arange(m)[:, None], top].reshape(-1, 3))
                self.full_firings += m * k
                hcode = hc.out.outcome.reshape(m, k)
                return (hcode == kernel.MOVING) | (hcode == kernel.REST)
            best = self.ranking.first_surviving(order, err, CHECKED, survives)
        now = np.abs(np.asarray(x) - np.asarray(target))
        ok = err[np.arange(m), best] < now - MIN_GAIN
        rest = np.where(np.isfinite(err[np.arange(m), best]),
                        p.x.reshape(m, -1)[np.arange(m), best], np.inf)
        return acts.reshape(m, -1, 3)[np.arange(m), best].astype(np.float32), ok, rest

    def label(self, obs: np.ndarray, venv: Any,
              live: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """DAgger's labels for the parts of the batched env ``venv``, its rows ``live`` only
        (the others get the weakest firing of a far actuator and no label): the actions, which
        have one (:meth:`act`), and no re-aim flags."""
        live = np.asarray(live, bool)
        acts = np.tile(np.array([1.0, -1.0, -1.0], np.float32), (len(live), 1))
        ok = np.zeros(len(live), bool)
        if live.any():
            acts[live], ok[live] = self.act(venv.x[live], venv.t[live], venv.target[live])
        return acts, ok, None


def expert_for(config: Any, settings: Any,
               seed: Any = None) -> BatchExpert | SeededExpert | PlaneController:
    """The expert of ``config``'s scene (:func:`agents.planning.scene_of`) with DAgger's
    ``settings`` (:class:`agents.imitation.dagger.DaggerSettings`): on the positioner the batched
    one-step search; on the plane its one-step controller (:func:`agents.planning.plane.
    labeller`); on the line the seeded expert of the policy ``seed`` (its ``act``; the line's
    expert with no seed: :class:`.staged.StagedExpert`)."""
    if isinstance(config, PlaneEnvConfig):
        return labeller(config, dataclasses.replace(
            LABEL_SETTINGS, frequencies=settings.frequencies, strokes=settings.strokes,
            margin=settings.margin, slack_m=settings.slack_m, heavier=settings.heavier,
            lookahead=settings.lookahead,
            lookahead_within_m=(math.inf if settings.lookahead_within_m is None
                                else settings.lookahead_within_m)))
    if isinstance(scene_of(config), PositionerScene):
        return BatchExpert(config, settings.frequencies, settings.strokes, settings.margin,
                           settings.slack_m, settings.heavier, settings.search)
    return SeededExpert(config, seed, settings.newton_iterations, accept_m=settings.accept_m)
