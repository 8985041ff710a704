"""Minimum-norm Gauss-Newton on a whole plan: the smallest change of a plan's actions that
brings the part to rest on the target, on the scene's model.

From a plan ``(K, 3)`` (every firing's action in [-1, 1]), each iteration plays the plan and one
copy per action component moved by a forward-difference ``probe`` (one batch of ``3K + 1``
episodes on the scene's batched env, from the episode's start or from a saved part state), takes
the gradient of the final position, and moves the plan by the minimum-norm step that zeroes the
final error to first order (no longer than ``max_step`` action units), kept only if the part then
rests nearer the target. Components whose probe does not end at rest do not move.

The minimum-norm step changes the plan as little as any step that corrects the landing, so plans
found for neighbouring targets or states from one reference stay neighbours (a plan table over
the target, :mod:`.continuation`; a re-plan from where the part really is, :mod:`agents.mpc`).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..planning import Rollouts


def newton_plan(roll: Rollouts, plan: np.ndarray, target: float, iterations: int = 6,
                probe: float = 1e-3, max_step: float = 0.3, accept_m: float = 1e-6,
                start: Any = None) -> tuple[np.ndarray, int]:
    """``plan`` moved towards ``target`` [m] (module docstring) on ``roll``'s model, from the
    episode's start (seed 0) or from the saved part state ``start`` (its own target is used);
    ``iterations`` [-] at most, ``probe`` and ``max_step`` [action units], stopping once the
    part rests within ``accept_m`` [m]. Returns the plan (float32 values, as played) and the
    episodes played."""
    shape = np.shape(plan)
    a = np.asarray(plan, float).ravel().astype(np.float32).astype(float)
    dim = a.size
    idx = np.arange(dim)
    used = 0
    for _ in range(iterations):
        h = np.where(a + probe <= 1.0, probe, -probe)
        probes = np.repeat(a[None], dim + 1, axis=0)
        probes[1:][idx, idx] += h
        probes = probes.astype(np.float32).astype(float)
        r = roll.run(probes.reshape(-1, *shape), target, seed=0, start=start)
        used += dim + 1
        e0 = float(r.error_m[0])
        if not r.rest[0] or abs(e0) <= accept_m:
            break
        g = np.where(r.rest[1:], (r.error_m[1:] - e0) / (probes[1:][idx, idx] - a), 0.0)
        gg = float((g ** 2).sum())
        if gg == 0.0:
            break
        step = -e0 * g / gg
        norm = float(np.linalg.norm(step))
        if norm > max_step:
            step *= max_step / norm
        moved = np.clip(a + step, -1.0, 1.0).astype(np.float32).astype(float)
        rm = roll.run(moved.reshape(1, *shape), target, seed=0, start=start)
        used += 1
        if not (rm.rest[0] and abs(rm.error_m[0]) < abs(e0)):
            break
        a = moved
    return a.reshape(shape), used
