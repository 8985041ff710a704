"""An expert for the conveyor line (MicroConveyor-v1) built from the simulator alone: no trained
policy seeds it, so DAgger can learn the line from nothing.

The plan it teaches is one smooth family over the target. Each of the first firings has its
stroke and delay fixed and its frequency free along a *stage*: a range of the frequency action
over which the part's rest position (that firing the last, the rest no-ops) rises steadily with
the frequency, below the frequencies that detach the part. From any part state, for the firing
about to be fired (the state's stage):

1. every frequency of a grid over the stage's range is fired on the nominal model from that
   state (the part then left alone), giving the stage's rest position as a curve of frequency;
2. a target that curve reaches is *aimed at*: the lowest frequency at which the curve crosses
   the target (linear between grid points), then polished by Newton's method on the frequency
   alone (the model's slope by a forward difference) so that the part rests on the target: the
   answer stays on the family, a smooth function of the state;
3. a target beyond the curve's reach is *carried towards*: the stage's strongest frequency,
   whose part then rests where the next stage's curve starts. At the frontier between aiming
   and carrying the two answers are the same firing, so the expert's answer is continuous in
   the target, which is what a network imitating it needs;
4. after the last stage (every target within the stages' reach is met by then) the part is left
   alone (:data:`~agents.rl.refinement.corrections.NOOP`).

A state from which the stage's firing cannot move the part's rest (it rests, or coasts, out of
the actuator's reach: a firing before it missed), a state whose target the stage before was
meant to reach (it missed), and every state after the last stage get no label
(:meth:`StagedExpert.label`): nothing fired there brings the part onto its target, and such
labels, which jump with the target, would only cost the network's fit elsewhere. A later
stage's state whose target lies less than ``overlap_m`` (0.2 mm) short of the farthest the
stage before aims at is labelled all the same: it aims at the target, correcting a small miss of
the firing before.

The default stages (:data:`STAGES`) were found by sweeping the nominal MicroConveyor-v1 scene:
the first firing (actuator at 0 mm, fired at once: a delay from rest is only waiting) lands the
part from about 0 to 0.54 mm; after it, the second (0.5 mm, fired 5 ms after the first stroke
ends, when the carried part has coasted into its bump) from about 0.6 to 7.0 mm; after those two
at their strongest, the third (1.0 mm, fired without delay on the moving part) from about 7.0 to
11.4 mm; together they cover v1's targets of 0.5-10 mm. A shorter second delay fires before the
part arrives: at 4.5, 4 and 3.5 ms the second firing's rise ends at about 5.3, 3.0 and 2.0 mm,
beyond which it detaches the part. On the nominal model the expert places every target of
0.5-10 mm within 10 µm of ~99 % of them, in about 13 ms at 0.5 mm to 55 ms at 10 mm (median
41 ms over the range). The model is nominal; the episode's noise and factors are unknown to it.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from microconveyor_env.envs.line.config import EnvConfig
from microconveyor_env.physics import dynamics_kernel as kernel

from .experts import SeededExpert
from ..rl.refinement.corrections import NOOP

__all__ = ["STAGES", "LineStage", "StagedExpert"]

PROBE = 1e-3      # [action units] Newton's forward-difference step on the frequency
MAX_STEP = 0.1    # [action units] its longest step


class LineStage(NamedTuple):
    """One firing of the family: ``stroke`` and ``delay`` [action units] fixed, the frequency
    action free over ``[f_low, f_high]`` (``f_high`` below the part's detachment)."""

    stroke: float
    delay: float
    f_low: float
    f_high: float


# MicroConveyor-v1's nominal scene (module docstring): firings 1, 2 and 3
STAGES: tuple[LineStage, ...] = (LineStage(0.64, -1.0, -0.76, -0.385),
                                 LineStage(1.0, -0.9, -1.0, -0.45),
                                 LineStage(-1.0, -1.0, -0.52, -0.34))


class StagedExpert:
    """The staged expert (module docstring) for the conveyor scene ``config`` (its randomisation
    ignored: the model is nominal). ``stages``: one :class:`LineStage` per firing from the
    first; ``grid`` [-] frequencies tried per stage; ``iterations`` [-] Newton steps of the
    aimed firing's frequency, stopped once the part then rests within ``accept_m`` [m] of the
    target. No label for a state whose stage moves the part's rest by less than ``moves_m`` [m]
    over its frequencies, nor for a state of a later stage whose target lies more than
    ``overlap_m`` [m] short of where the stage before carries the part at its strongest
    (:attr:`reach_m`, on the nominal plan): the stage before was meant to put the part there."""

    def __init__(self, config: EnvConfig, stages: tuple[LineStage, ...] = STAGES, grid: int = 41,
                 iterations: int = 6, accept_m: float = 2e-6, moves_m: float = 10e-6,
                 overlap_m: float = 0.2e-3) -> None:
        if not stages or len(stages) > config.n_actuators:
            raise ValueError(f"stages: 1 to {config.n_actuators} (one per actuator), "
                             f"not {len(stages)}")
        for s in stages:
            if not (-1.0 <= s.f_low < s.f_high <= 1.0 and abs(s.stroke) <= 1.0
                    and abs(s.delay) <= 1.0):
                raise ValueError(f"stage {s}: actions in [-1, 1] and f_low < f_high")
        if isinstance(grid, bool) or not isinstance(grid, int) or grid < 2:
            raise ValueError(f"grid = {grid!r} is invalid: an integer >= 2")
        self.model = SeededExpert(config, seed=None)   # its rest_after: the nominal model
        self.iterations = iterations
        self.stages = stages
        self.grid = grid
        self.accept_m = accept_m
        self.moves_m = moves_m
        self.overlap_m = overlap_m
        self.reach_m = self._reaches(config)

    def _reaches(self, config: EnvConfig) -> np.ndarray:
        """[m] where the part rests after each stage's strongest firing, the stages before it
        at theirs (the nominal plan of the farthest target, stage by stage)."""
        c = self.model._container(1)
        state: tuple[np.ndarray, ...] = (np.array([-config.start_offset]), np.zeros(1),
                                         np.zeros(1), np.zeros(1),
                                         np.array([config.target_range[1]]))
        out = []
        for st in self.stages:
            strongest = np.array([[st.f_high, st.stroke, st.delay]])
            out.append(float(self.model.rest_after(state, strongest)[0][0]))
            p = c.parts
            p.x[:], p.v[:], p.t[:], p.fired[:], p.target[:] = state
            c.step(strongest)
            state = tuple(np.array(getattr(p, k), float) for k in ("x", "v", "t", "fired",
                                                                     "target"))
        return np.array(out)

    def _stage(self, k: int, state: tuple[np.ndarray, ...]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stage ``k``'s answers for parts in ``state`` (x, v, t, fired, target): the actions,
        whether each aims at its target (False: it carries the part on) and whether the stage
        can move the part's rest at all (``moves_m``)."""
        st = self.stages[k]
        m, g = len(state[0]), self.grid
        f = np.linspace(st.f_low, st.f_high, g)
        cand = np.column_stack([f, np.full(g, st.stroke), np.full(g, st.delay)])
        many = tuple(np.repeat(s, g) for s in state)
        x, code, _ = self.model.rest_after(many, np.tile(cand, (m, 1)))
        land = np.where(code == kernel.REST, x, np.nan).reshape(m, g)
        span = np.nanmax(land, axis=1, initial=-np.inf) - np.nanmin(land, axis=1, initial=np.inf)
        target = state[4]
        moves = span >= self.moves_m
        if k:
            moves &= target > self.reach_m[k - 1] - self.overlap_m
        # the first grid interval, from the lowest frequency, where the curve reaches the target
        lo, hi = land[:, :-1], land[:, 1:]
        cross = (lo <= target[:, None]) & (hi >= target[:, None])
        below = land[:, 0] >= target          # the weakest firing already lands at or past it
        reach = cross.any(1) | below
        i = np.argmax(cross, axis=1)
        rows = np.arange(m)
        l0, l1 = lo[rows, i], hi[rows, i]
        w = np.clip((target - l0) / np.where(l1 > l0, l1 - l0, 1.0), 0.0, 1.0)
        fa = np.where(below, f[0], f[i] + w * (f[1] - f[0]))
        a = np.repeat(cand[-1:], m, 0)        # carry: the strongest firing of the stage
        a[reach, 0] = fa[reach]
        aim = np.flatnonzero(reach)
        if len(aim):
            a[aim, 0] = self._newton(tuple(s[aim] for s in state), a[aim])
        return a, reach, moves

    def _newton(self, state: tuple[np.ndarray, ...], a: np.ndarray) -> np.ndarray:
        """Newton's method on the frequency action alone (stroke and delay stay the stage's,
        so the answers lie on the family): the slope by a forward difference, each step kept
        only if the part then rests nearer the target. Returns the frequency actions."""
        target = state[4]
        a = a.copy()
        x, code, _ = self.model.rest_after(state, a)
        err = np.where(code == kernel.REST, x - target, np.inf)
        for _ in range(self.iterations):
            todo = np.isfinite(err) & (np.abs(err) > self.accept_m)
            if not todo.any():
                break
            h = np.where(a[:, 0] + PROBE <= 1.0, PROBE, -PROBE)
            probe = a.copy()
            probe[:, 0] += h
            xp, cp, _ = self.model.rest_after(state, probe)
            slope = (xp - x) / h
            todo &= (cp == kernel.REST) & (np.abs(slope) > 0.0)
            step = np.clip(-err / np.where(todo, slope, 1.0), -MAX_STEP, MAX_STEP)
            moved = a.copy()
            moved[:, 0] = np.clip(a[:, 0] + np.where(todo, step, 0.0), -1.0, 1.0)
            xm, cm, _ = self.model.rest_after(state, moved)
            em = np.where(cm == kernel.REST, xm - target, np.inf)
            better = todo & (np.abs(em) < np.abs(err))
            a[better], x[better], err[better] = moved[better], xm[better], em[better]
        return a[:, 0]

    def act(self, parts: Any, rows: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The expert's actions ``(M, 3)`` (float32) for parts in the states ``parts`` (arrays
        ``x``, ``v``, ``t``, ``fired``, ``target``: a batched env's ``conveyor.parts``), only
        the ``rows`` given (bool ``(M,)``; the others get the no-op); which of them aim at the
        target; and which are worth a label (the stage can move the part's rest)."""
        state = tuple(np.array(getattr(parts, k), float) for k in ("x", "v", "t", "fired",
                                                                     "target"))
        m = len(state[0])
        a = np.repeat(NOOP[None].astype(np.float64), m, 0)
        aims = np.zeros(m, bool)
        useful = np.zeros(m, bool)
        todo = np.ones(m, bool) if rows is None else np.asarray(rows, bool).copy()
        fired = state[3].astype(int)
        for k in range(len(self.stages)):
            idx = np.flatnonzero(todo & (fired == k))
            if len(idx):
                a[idx], aims[idx], useful[idx] = self._stage(k, tuple(s[idx] for s in state))
        return a.astype(np.float32), aims, useful

    def label(self, obs: np.ndarray, venv: Any,
              live: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """DAgger's labels (:data:`agents.imitation.dagger.Labeller`) for the batched env
        ``venv``, its rows ``live``: the actions, which have one (the states whose stage can
        still move the part's rest), which aim."""
        acts, aims, useful = self.act(venv.conveyor.parts, rows=live)
        return acts, useful, aims
