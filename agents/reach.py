"""Reach study: how far, how precisely and how robustly can an open-loop schedule move the part?

Per target, scipy's ``differential_evolution`` searches the whole schedule (one action of 3
numbers per actuator: 15 numbers for 5 actuators) for the smallest final |x - target| at rest,
each generation evaluated as one batch on :class:`MicroConveyorVectorEnv`. The best schedule is
then replayed ``n_noisy`` times with Gaussian action noise ``sigma`` (in [-1, 1] units): its
success rate says whether the answer is robust or fragile.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorVectorEnv

MISS = 1.0  # m: cost of an episode that does not end at rest (detached, max_time, ...)


@dataclass
class Rollouts:
    """Batched open-loop rollouts of whole schedules on one config (envs cached by batch size)."""
    config: EnvConfig

    def __post_init__(self):
        self._envs: dict[int, MicroConveyorVectorEnv] = {}
        self.episodes = 0

    def run(self, schedules: np.ndarray, target: float):
        """schedules (B, n_actuators, 3) -> (final error [m], at rest, success) per schedule."""
        b = schedules.shape[0]
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = MicroConveyorVectorEnv(b, config=self.config,
                                                         autoreset_mode="SameStep")
        env.reset(seed=0, options={"target": target})
        done = np.zeros(b, bool)
        err, rest, succ = np.full(b, np.inf), np.zeros(b, bool), np.zeros(b, bool)
        for k in range(schedules.shape[1]):
            _, _, term, trunc, info = env.step(schedules[:, k, :].astype(np.float32))
            src = info.get("final_info", info)
            new = (term | trunc) & ~done
            err[new] = np.abs(src["position_error_m"][new])
            rest[new] = src["outcome"][new] == "rest"
            succ[new] = src["is_success"][new]
            done |= term | trunc
            if done.all():
                break
        self.episodes += b
        return err, rest, succ


def _de(cost, dim: int, budget: int, seed: int, x0=None):
    from scipy.optimize import differential_evolution

    pop = max(5, int(round(np.sqrt(budget) / dim)))  # popsize multiplier: pop * dim per generation
    res = differential_evolution(cost, [(-1.0, 1.0)] * dim, popsize=pop,
                                 maxiter=max(1, budget // (pop * dim) - 1), seed=seed, tol=0.0,
                                 atol=0.0, polish=False, vectorized=True, updating="deferred",
                                 x0=x0)
    return res


def best_schedule(roll: Rollouts, target: float, budget: int, seed: int):
    """Differential evolution over the schedule for the smallest nominal |error|:
    (best error [m], schedule (n, 3), episodes)."""
    n = roll.config.n_actuators
    start = roll.episodes

    def cost(x):  # x: (dim, S) with vectorized=True
        err, rest, _ = roll.run(x.T.reshape(-1, n, 3), target)
        return np.where(rest, err, MISS + np.minimum(err, MISS))

    res = _de(cost, 3 * n, budget, seed)
    return float(res.fun), res.x.reshape(n, 3), roll.episodes - start


def robust_schedule(roll: Rollouts, target: float, budget: int, seed: int, sigma: float,
                    k: int = 8, x0=None):
    """Differential evolution for the schedule whose ``k`` noisy copies (noise ``sigma``) end
    closest on average (error in tolerances, capped at 10; not at rest: 10), started from
    ``x0``: (schedule (n, 3), episodes)."""
    n, tol = roll.config.n_actuators, roll.config.tolerance
    rng = np.random.default_rng(seed)
    start = roll.episodes

    def cost(x):
        s = x.T.reshape(-1, n, 3)
        noisy = np.clip(s[:, None] + rng.normal(0.0, sigma, (s.shape[0], k, n, 3)), -1, 1)
        err, rest, _ = roll.run(noisy.reshape(-1, n, 3), target)
        c = np.where(rest, np.minimum(err / tol, 10.0), 10.0)
        return c.reshape(-1, k).mean(1)

    res = _de(cost, 3 * n, max(1, budget // k), seed, x0=None if x0 is None else x0.ravel())
    return res.x.reshape(n, 3), roll.episodes - start


def noisy_success(roll: Rollouts, schedule: np.ndarray, target: float, sigma: float,
                  n_noisy: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    noisy = np.clip(schedule[None] + rng.normal(0.0, sigma, (n_noisy, *schedule.shape)), -1, 1)
    _, _, succ = roll.run(noisy, target)
    return float(succ.mean())


def reach_study(targets, budget: int = 3000, sigma: float = 1e-3, n_noisy: int = 200,
                seed: int = 0, robust_rate: float = 0.9, robust_budget: int = 0,
                config: EnvConfig | None = None, progress=None) -> dict:
    """The study over ``targets`` [m]; rows per target and the widest robust target range.

    Per target: DE for the best nominal error (``budget`` episodes), that answer's success
    under noise; then, if ``robust_budget`` > 0 and the target is reachable, a second DE started
    from it that minimises the noisy error (``robust_budget`` episodes), its success measured
    on fresh noise. A target is robust when one of the two answers keeps ``robust_rate``."""
    cfg = config or EnvConfig.from_yaml(target_range=(1e-4, 0.1))
    roll = Rollouts(cfg)
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
        if ok and robust_budget > 0 and rate < 1.0:
            rsched, rep = robust_schedule(roll, float(target), robust_budget, seed + i, sigma,
                                          x0=sched)
            rrate = noisy_success(roll, rsched, float(target), sigma, n_noisy, seed + 2000 + i)
            row.update(robust_noisy_success_rate=rrate, robust_episodes=int(rep),
                       robust_schedule=rsched.tolist())
            best_rate = max(rate, rrate)
        row.update(best_noisy_success_rate=best_rate,
                   robust=bool(ok and best_rate >= robust_rate),
                   wall_time_s=time.perf_counter() - t0)
        rows.append(row)
        if progress:
            progress(row)
    return {"sigma": sigma, "n_noisy": n_noisy, "budget_episodes": budget,
            "robust_budget_episodes": robust_budget, "seed": seed,
            "tolerance_m": cfg.tolerance, "robust_rate": robust_rate, "rows": rows,
            "robust_target_range_m": widest_robust_range(rows)}


def widest_robust_range(rows) -> list | None:
    """[low, high] of the longest run of consecutive robust grid targets (None: none robust)."""
    best, cur = None, []
    for r in sorted(rows, key=lambda r: r["target_m"]):
        cur = cur + [r["target_m"]] if r["robust"] else []
        if cur and (best is None or cur[-1] - cur[0] > best[1] - best[0]):
            best = [cur[0], cur[-1]]
    return best


def plot_reach(study: dict, path: str) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = study["rows"]
    t = np.array([r["target_m"] for r in rows]) * 1e3
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    a1.semilogy(t, [max(r["best_abs_error_m"], 1e-9) * 1e6 for r in rows], "o-")
    a1.axhline(study["tolerance_m"] * 1e6, color="k", ls="--", lw=0.8, label="tolerance")
    a1.set_ylabel("best open-loop |error| [µm]")
    a1.legend()
    a2.plot(t, [100 * r["noisy_success_rate"] for r in rows], "s-", label="best-error answer")
    a2.plot(t, [100 * r["best_noisy_success_rate"] for r in rows], "o-",
            label="best of it and the noise-robust answer")
    a2.legend(fontsize=8)
    a2.axhline(100 * study["robust_rate"], color="k", ls="--", lw=0.8)
    a2.set_ylabel(f"success under noise σ={study['sigma']:g} [%]")
    a2.set_xlabel("target [mm]")
    rr = study["robust_target_range_m"]
    if rr:
        for ax in (a1, a2):
            ax.axvspan(rr[0] * 1e3, rr[1] * 1e3, color="g", alpha=0.1)
    fig.suptitle(f"Reach of open-loop schedules (DE, {study['budget_episodes']} episodes/target)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
