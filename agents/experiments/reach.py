"""Reach study: how far, how precisely and how robustly can an open-loop schedule move the part?

Per target, differential evolution (:func:`.open_loop.solve_target`) searches the whole schedule
(one action of 3 numbers per actuator: 15 numbers for 5 actuators) for the smallest final
|x - target| at rest, each generation evaluated as one batch on ``MicroConveyorVectorEnv``. The
best schedule is
then replayed ``n_noisy`` times with Gaussian action noise ``sigma`` (in [-1, 1] units): its
success rate says whether the answer is robust or fragile.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig

from ..openloop.search import de_minimize
from ..openloop.target import solve_target
from ..planning import MISS, LineRollouts, robust_cost


def best_schedule(roll: LineRollouts, target: float, budget: int, seed: int) -> Any:
    """Differential evolution over the schedule for the smallest nominal |error|
    (:func:`.open_loop.solve_target`): (best error [m], schedule (n, 3), episodes)."""
    res = solve_target(target, "de", budget, seed, rollouts=roll)
    err = res.abs_error_m if res.outcome == "rest" else MISS + min(res.abs_error_m, MISS)
    return err, res.plan, res.episodes


def robust_schedule(roll: LineRollouts, target: float, budget: int, seed: int, sigma: float,
                    k: int = 8, x0: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Differential evolution for the schedule whose ``k`` noisy copies (noise ``sigma``) end
    closest on average, started from ``x0``: (schedule (n, 3), episodes).

    A copy costs :func:`agents.planning.robust_cost`: its error capped at 10 tolerances plus a
    tie-break of 0.1 tolerance ln(1 + error / tolerance); a copy not at rest counts as an error
    of 10^4 tolerances."""
    n, tol = roll.config.n_actuators, roll.config.tolerance
    rng = np.random.default_rng(seed)
    start = roll.episodes

    def cost(x: np.ndarray) -> np.ndarray:
        s = x.reshape(-1, n, 3)
        noisy = np.clip(s[:, None] + rng.normal(0.0, sigma, (s.shape[0], k, n, 3)), -1, 1)
        r = roll.run(noisy.reshape(-1, n, 3), target)
        return robust_cost(r.abs_error_m, r.rest, tol, miss=1e4 * tol).reshape(-1, k).mean(1)

    res = de_minimize(cost, [(-1.0, 1.0)] * (3 * n), max(5, budget // k), seed,
                      x0=None if x0 is None else np.asarray(x0, float).ravel())
    return res.x.reshape(n, 3), roll.episodes - start


def noisy_success(roll: LineRollouts, schedule: np.ndarray, target: float, sigma: float,
                  n_noisy: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    noisy = np.clip(schedule[None] + rng.normal(0.0, sigma, (n_noisy, *schedule.shape)), -1, 1)
    return float(roll.run(noisy, target, seed=seed, same_episode=False).success.mean())


def reach_study(targets: Sequence[float], budget: int = 3000, sigma: float = 1e-3, n_noisy: int = 200,
                seed: int = 0, robust_rate: float = 0.9, robust_budget: int = 0,
                config: EnvConfig | None = None,
                progress: Callable[[dict], None] | None = None) -> dict:
    """The study over ``targets`` [m]; rows per target and the widest robust target range.

    Per target: DE for the best nominal error (``budget`` episodes), that answer's success
    under noise; then, if ``robust_budget`` > 0 and the target is reachable, a second DE started
    from it that minimises the noisy error (``robust_budget`` episodes), its success measured
    on fresh noise (run for unreachable targets too: it may find what the first stage missed).
    A target is reachable when an answer lands within tolerance (nominally, or in some noisy
    replays), robust when one of the two answers keeps ``robust_rate``."""
    cfg = config or EnvConfig.from_yaml(target_range=(1e-4, 0.1))
    roll = LineRollouts(cfg)
    rows = []
    for i, target in enumerate(targets):
        t0 = time.perf_counter()
        err, sched, episodes = best_schedule(roll, float(target), budget, seed + i)
        ok = err <= cfg.tolerance
        rate = noisy_success(roll, sched, float(target), sigma, n_noisy, seed + 1000 + i) \
            if ok else 0.0
        row = {"target_m": float(target), "best_abs_error_m": err, "reachable": bool(ok),
               "noisy_success_rate": rate, "episodes": int(episodes), "schedule": sched.tolist()}
        best_rate = rate
        if robust_budget > 0 and rate < 1.0:
            rsched, rep = robust_schedule(roll, float(target), robust_budget, seed + i, sigma,
                                          x0=sched)
            rrate = noisy_success(roll, rsched, float(target), sigma, n_noisy, seed + 2000 + i)
            row.update(robust_noisy_success_rate=rrate, robust_episodes=int(rep),
                       robust_schedule=rsched.tolist())
            best_rate = max(rate, rrate)
        row.update(best_noisy_success_rate=best_rate, reachable=bool(ok or best_rate > 0),
                   robust=bool(best_rate >= robust_rate),
                   wall_time_s=time.perf_counter() - t0)
        rows.append(row)
        if progress:
            progress(row)
    return {"sigma": sigma, "n_noisy": n_noisy, "budget_episodes": budget,
            "robust_budget_episodes": robust_budget, "seed": seed,
            "tolerance_m": cfg.tolerance, "robust_rate": robust_rate, "rows": rows,
            "robust_target_range_m": widest_robust_range(rows)}


def widest_robust_range(rows: Sequence[dict]) -> list | None:
    """[low, high] of the longest run of consecutive robust grid targets (None: none robust)."""
    best: list | None = None
    cur: list = []
    for r in sorted(rows, key=lambda r: r["target_m"]):
        cur = cur + [r["target_m"]] if r["robust"] else []
        if cur and (best is None or cur[-1] - cur[0] > best[1] - best[0]):
            best = [cur[0], cur[-1]]
    return best
