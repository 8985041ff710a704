"""Success against perturbation: a closed-loop policy or open-loop plans on fixed targets, across a
ladder of perturbation levels of the env's per-episode randomisation (docs/randomisation.md).

A level is an execution-noise sigma [action units] plus a symmetric spread r [-] of the friction
and mass factors (both drawn uniformly in [1 - r, 1 + r] per episode)::

    from agents.rl.evaluation.evaluate import fixed_targets
    from agents.experiments.perturb import Level, perturbation_table, plan_rollout, policy_rollout

    cfg = EnvConfig.from_yaml()
    targets = fixed_targets(cfg, 100, seed=0)
    rows = perturbation_table(policy_rollout(policy), cfg, targets)      # PPO (policy.act)
    rows = perturbation_table(plan_rollout(plans), cfg, targets)         # DE plans (100, 5, 3)

The comparison's axes (:func:`perturbation_levels`: noise alone, model error alone, both on a
diagonal, optionally the full grid) are tabulated by :func:`axes_table`.

Every level replays the same targets with the same seeds; the env derives its draws from the seed
so that a level's factors and noise are the same random numbers scaled (common random numbers):
differences between levels are the perturbation's, not sampling noise.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig

from ..rl.evaluation.evaluate import rollout

# (config, targets [m], seed) -> {"error_m", "outcome", and with randomisation on
# "friction_factor", "mass_factor"}: one episode per target, sub-env i seeded seed + i
RolloutFn = Callable[[EnvConfig, np.ndarray, int], dict]


@dataclasses.dataclass(frozen=True)
class Level:
    """One perturbation level: ``action_noise`` sigma [action units] and ``spread`` r [-] (friction
    and mass factors uniform in [1 - r, 1 + r]; r <= 0.9, the factors' floor being 0.1)."""

    action_noise: float = 0.0
    spread: float = 0.0

    def config(self, base: EnvConfig) -> EnvConfig:
        """``base`` with this level's randomisation (validated by EnvConfig)."""
        r = self.spread
        return dataclasses.replace(base, action_noise=self.action_noise,
                                   friction_factor_range=(1.0 - r, 1.0 + r),
                                   mass_factor_range=(1.0 - r, 1.0 + r))


def ladder(action_noise: Sequence[float], spread: Sequence[float]) -> list[Level]:
    """Levels pairing ``action_noise[k]`` with ``spread[k]``."""
    if len(action_noise) != len(spread):
        raise ValueError(f"{len(action_noise)} noise levels for {len(spread)} spreads")
    return [Level(float(s), float(r)) for s, r in zip(action_noise, spread, strict=True)]


DEFAULT_LADDER = tuple(ladder((0.0, 0.01, 0.02, 0.05, 0.1, 0.2),
                              (0.0, 0.02, 0.05, 0.1, 0.2, 0.3)))


class _Act:
    def __init__(self, act: Callable[[np.ndarray], np.ndarray]) -> None:
        self.act = act


def policy_rollout(policy: Any) -> RolloutFn:
    """Closed loop: ``policy`` is ``act(obs) -> actions`` ((N, 6) -> (N, 3)) or has such an
    ``act`` method (e.g. :class:`agents.rl.evaluation.evaluate.Policy`)."""
    act = getattr(policy, "act", policy)
    if not callable(act):
        raise TypeError(f"policy must be callable or have an act method, got {type(policy)}")

    def run(config: EnvConfig, targets: np.ndarray, seed: int) -> dict:
        return rollout(_Act(act), targets, config, seed=seed)

    return run


def plan_rollout(plans: np.ndarray) -> RolloutFn:
    """Open loop: ``plans`` (n_targets, n_actuators, 3) in action units, one plan per target
    (firing k of episode i fires ``plans[i, k]``), or one plan (n_actuators, 3) for all."""
    plans = np.asarray(plans, dtype=np.float64)

    def run(config: EnvConfig, targets: np.ndarray, seed: int) -> dict:
        n, n_act = len(targets), config.n_actuators
        p = np.broadcast_to(plans, (n, *plans.shape)) if plans.ndim == 2 else plans
        if p.shape != (n, n_act, 3):
            raise ValueError(f"plans of shape {plans.shape} do not fit {n} targets with "
                             f"{n_act} actuators: expected ({n}, {n_act}, 3) or ({n_act}, 3)")
        rows = np.arange(n)

        def act(obs: np.ndarray) -> np.ndarray:  # obs[:, 4] = fired / n_actuators
            k = np.minimum(np.rint(obs[:, 4].astype(np.float64) * n_act).astype(int), n_act - 1)
            return p[rows, k].astype(np.float32)

        return rollout(_Act(act), targets, config, seed=seed)

    return run


def wilson(k: int, n: int) -> list[float]:
    """95 % Wilson score interval of a success rate k / n (statsmodels' ``proportion_confint``)."""
    if n == 0:
        return [math.nan, math.nan]
    from statsmodels.stats.proportion import proportion_confint

    lo, hi = proportion_confint(k, n, alpha=0.05, method="wilson")
    return [float(lo), float(hi)]


def perturbation_table(run: RolloutFn, config: EnvConfig, targets: Sequence[float] | np.ndarray,
                       levels: Sequence[Level] = DEFAULT_LADDER, seed: int = 0,
                       repeats: int = 1, tolerance: float = 50e-6,
                       per_episode: bool = False) -> list[dict]:
    """Success within ``tolerance`` [m] (at rest, ``|x - target| <= tolerance``) of ``run`` on
    ``targets`` [m] under each perturbation level applied to ``config``.

    Each level runs ``repeats`` rollouts of all targets, repeat ``j`` seeded
    ``seed + j * len(targets)`` (sub-env i: ``+ i``), the same at every level. Returns one row per
    level (``per_episode=False``: ``level``, ``action_noise``, ``spread``,
    ``friction_factor_range``, ``mass_factor_range``, ``n_episodes``, ``tolerance_m``,
    ``success_rate`` and its 95 % Wilson ``success_ci95``, ``median_abs_error_m``, ``rest_rate``,
    ``detach_rate``) or one row per episode (``level``, ``action_noise``, ``spread``, ``repeat``,
    ``target_m``, ``error_m``, ``outcome``, ``success``, ``friction_factor``, ``mass_factor``).
    """
    tg = np.asarray(targets, dtype=np.float64)
    if tg.ndim != 1 or tg.size == 0:
        raise ValueError(f"targets must be a non-empty 1-d sequence, got shape {tg.shape}")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats = {repeats!r} is invalid: must be an integer >= 1")
    rows: list[dict] = []
    for li, level in enumerate(levels):
        cfg = level.config(config)
        errs, outs, ffs, mfs = [], [], [], []
        for j in range(repeats):
            res = run(cfg, tg, seed + j * tg.size)
            err = np.asarray(res["error_m"], dtype=np.float64)
            errs.append(err)
            outs.append(np.asarray(res["outcome"], dtype=object))
            ffs.append(np.asarray(res.get("friction_factor", np.ones(tg.size)), dtype=np.float64))
            mfs.append(np.asarray(res.get("mass_factor", np.ones(tg.size)), dtype=np.float64))
            if per_episode:
                for i in range(tg.size):
                    rest = outs[-1][i] == "rest"
                    rows.append({"level": li, "action_noise": level.action_noise,
                                 "spread": level.spread, "repeat": j, "target_m": float(tg[i]),
                                 "error_m": float(err[i]), "outcome": str(outs[-1][i]),
                                 "success": bool(rest and abs(err[i]) <= tolerance),
                                 "friction_factor": float(ffs[-1][i]),
                                 "mass_factor": float(mfs[-1][i])})
        if per_episode:
            continue
        err, out = np.concatenate(errs), np.concatenate(outs)
        rest = out == "rest"
        ok = int(np.sum(rest & (np.abs(err) <= tolerance)))
        rows.append({"level": li, "action_noise": level.action_noise, "spread": level.spread,
                     "friction_factor_range": list(cfg.friction_factor_range),
                     "mass_factor_range": list(cfg.mass_factor_range),
                     "n_episodes": int(err.size), "tolerance_m": tolerance,
                     "success_rate": ok / err.size, "success_ci95": wilson(ok, err.size),
                     "median_abs_error_m": float(np.median(np.abs(err))),
                     "rest_rate": float(np.mean(rest)),
                     "detach_rate": float(np.mean(out == "detached"))})
    return rows


# the comparison's perturbation axes (agents.experiments.compare): execution noise alone
# [action units], model error alone (friction and mass factors uniform in [1 - r, 1 + r]), and
# both together on a diagonal ((sigma, r) pairs; (3e-3, 5 %) is the goal level)
NOISE_LADDER = (0.0, 1e-3, 3e-3, 1e-2)
SPREAD_LADDER = (0.0, 0.01, 0.02, 0.05, 0.1)
DIAGONAL = ((1e-3, 0.01), (3e-3, 0.05), (1e-2, 0.1))


def perturbation_levels(noise: Sequence[float] = NOISE_LADDER,
                        spread: Sequence[float] = SPREAD_LADDER,
                        diagonal: Sequence[tuple[float, float]] = DIAGONAL,
                        full: bool = False) -> dict[str, list[Level]]:
    """The perturbation axes, each starting at the unperturbed level: ``action_noise`` (σ
    [action units], r = 0), ``spread`` (r [-], σ = 0), ``combined`` (the ``diagonal`` (σ, r)
    pairs) and, with ``full``, ``grid``: every (σ, r) of the two ladders."""
    zero = Level()
    axes = {"action_noise": [zero] + [Level(action_noise=float(x)) for x in noise if x > 0],
            "spread": [zero] + [Level(spread=float(r)) for r in spread if r > 0],
            "combined": [zero] + [Level(float(x), float(r)) for x, r in diagonal]}
    if full:
        axes["grid"] = [Level(float(x), float(r)) for x in sorted({0.0, *noise})
                        for r in sorted({0.0, *spread})]
    return axes


def unique_levels(axes: dict[str, list[Level]]) -> list[Level]:
    """The distinct levels of ``axes``, in order."""
    return list(dict.fromkeys(lv for levels in axes.values() for lv in levels))


def axes_table(run: RolloutFn, config: EnvConfig, targets: np.ndarray,
               axes: dict[str, list[Level]], seed: int = 0, repeats: int = 1,
               progress: Callable[[], None] | None = None) -> dict[str, list[dict]]:
    """:func:`perturbation_table` of ``run`` along ``axes`` (:func:`perturbation_levels`) at
    ``config``'s tolerance: every distinct level run once (``progress`` called after each), its
    row placed on each axis that has it (``level``: its number among the distinct levels)."""
    unique = unique_levels(axes)
    rows: list[dict] = []
    for lv in unique:
        row = perturbation_table(run, config, targets, [lv], seed=seed, repeats=repeats,
                                 tolerance=config.tolerance)[0]
        rows.append({**row, "level": len(rows)})
        if progress:
            progress()
    by_level = dict(zip(unique, rows, strict=True))
    return {axis: [by_level[lv] for lv in levels] for axis, levels in axes.items()}
