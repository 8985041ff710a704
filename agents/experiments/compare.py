"""The comparison of issue 12: closed loop (PPO) against open loop (DE, CMA-ES), a random policy
and a fixed schedule, on the same fixed targets of MicroConveyor-v0.

For every method and budget, per target: the final error, success within the tolerance, the
travel (simulated) time, and the compute it took — wall time [s] and simulated episodes. PPO pays
its training once (``metadata.json`` of the policy: wall time and steps) and then one batched
rollout per target; it is shown both at deployment cost and amortised over ``N`` targets, with
the crossover ``N`` above which training once costs less than searching every target. Then:
success against tolerance, and success against perturbation (the env's per-episode
randomisation, :mod:`.perturb`) for the closed-loop policies and the open-loop plans (made on the
nominal model).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, env_config
from microconveyor_env.envs.actions import encode_actions

from ..rl.evaluate import fixed_targets, load_policy, rollout
from ..openloop.target import Rollouts, solve_target
from .perturb import Level, perturbation_table, plan_rollout, policy_rollout

# the fixed schedule: every actuator at the single-firing optimum of the reference scene
FIXED_SCHEDULE = {"frequency_hz": 950.0, "stroke_m": 200e-6, "delay_s": 0.0}
# success against tolerance is read off the final errors at these tolerances [m]
TOLERANCES = tuple(float(t) for t in np.geomspace(1e-8, 1e-3, 51))
# perturbation ladders: execution noise alone [action units], model error alone (friction and
# mass factors uniform in [1 - r, 1 + r])
NOISE_LADDER = (0.0, 1e-3, 3e-3, 1e-2, 3e-2, 0.1)
SPREAD_LADDER = (0.0, 0.005, 0.01, 0.02, 0.05, 0.1)


class _RandomPolicy:
    """Uniform random actions in the box (seeded)."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, (len(obs), 3)).astype(np.float32)


def _rows(name: str, res: dict, targets: np.ndarray, tol: float, **extra: Any) -> dict:
    err = np.asarray(res["error_m"], float)
    rest = np.asarray(res["outcome"]) == "rest"
    ok = rest & (np.abs(err) <= tol)
    t = np.asarray(res["time_s"], float)
    return {"method": name, "n_targets": int(len(targets)), "success_rate": float(ok.mean()),
            "median_abs_error_m": float(np.median(np.abs(err))),
            "detach_rate": float(np.mean(np.asarray(res["outcome"]) == "detached")),
            "median_travel_time_s": float(np.median(t[rest])) if rest.any() else None,
            "abs_error_m": np.abs(err).tolist(), "rest": rest.tolist(), **extra}


def _closed_loop(name: str, policy: Any, targets: np.ndarray, cfg: EnvConfig, seed: int,
                 **extra: Any) -> dict:
    t0 = time.perf_counter()
    res = rollout(policy, targets, cfg, seed=seed)
    wall = time.perf_counter() - t0
    return _rows(name, res, targets, cfg.tolerance, wall_s_per_target=wall / len(targets),
                 episodes_per_target=1, **extra)


def _open_loop(method: str, budget: int, targets: np.ndarray, cfg: EnvConfig, seed: int,
               progress: Callable[[], None] | None = None) -> tuple[dict, np.ndarray]:
    roll = Rollouts(cfg)
    plans, err, outcome, t, wall, eps = [], [], [], [], 0.0, 0
    for k, tg in enumerate(targets):
        r = solve_target(float(tg), method, budget, seed + k, rollouts=roll)
        plans.append(r.plan)
        err.append(r.error_m)
        outcome.append(r.outcome)
        t.append(r.sim_time_s)
        wall += r.wall_time_s
        eps += r.episodes
        if progress:
            progress()
    res = {"error_m": err, "outcome": outcome, "time_s": t}
    row = _rows(method, res, targets, cfg.tolerance, budget=int(budget),
                wall_s_per_target=wall / len(targets), episodes_per_target=eps / len(targets))
    return row, np.array(plans)


def crossover(train_wall_s: float, ppo_wall_s: float, other_wall_s: float) -> float | None:
    """Targets N above which training once (``train_wall_s``) plus ``N`` deployments
    (``ppo_wall_s`` each) costs less wall time than ``N`` searches (``other_wall_s`` each);
    None when the search is no dearer per target than deploying the policy."""
    gain = other_wall_s - ppo_wall_s
    return None if gain <= 0 else float(train_wall_s / gain)


def compare(n_targets: int = 20, seed: int = 0, budgets: Sequence[int] = (100, 300, 1000, 2000,
            5000), methods: Sequence[str] = ("de", "cmaes"), policy: str | Path | None = None,
            randomised_policy: str | Path | None = None, amortise_over: int = 100,
            noise_ladder: Sequence[float] = NOISE_LADDER,
            spread_ladder: Sequence[float] = SPREAD_LADDER, perturb_repeats: int = 5,
            config: EnvConfig | None = None, progress: bool = True,
            env_id: str = "MicroConveyor-v0") -> dict:
    """Run the comparison on ``n_targets`` fixed targets (drawn with ``seed`` from the target
    range of ``config``, default ``env_id``'s defaults; the policies must have been trained on
    its scene); ``budgets``: episodes per target for each open-loop ``method``; ``policy``: the PPO
    policy (default: the one shipped for ``env_id``), ``randomised_policy``: the PPO trained
    under randomisation (default: ``env_id``'s shipped ``ppo_randomised`` if present; ``""`` to
    skip);
    ``amortise_over``: N targets for the amortised PPO point; the ladders: execution noise σ
    [action units] and factor spread r [-] of the perturbation charts, each replayed
    ``perturb_repeats`` times per target. Returns a JSON-able dict (``rows``, ``tolerance``,
    ``perturbation``, ``crossover``)."""
    from tqdm import tqdm

    from ..rl.shipped import require_shipped, shipped_path

    cfg = config or env_config(env_id)
    targets = fixed_targets(cfg, n_targets, seed)
    ppo = load_policy(policy or require_shipped(env_id), cfg)
    meta = ppo.metadata
    train_wall, train_steps = float(meta.get("wall_time_s", np.nan)), int(meta.get("steps", 0))
    rand_path: Path | None = None
    if randomised_policy is None:
        cand = shipped_path("ppo_randomised", env_id)
        rand_path = cand if (cand / "model.zip").is_file() else None
    elif randomised_policy != "":
        rand_path = Path(randomised_policy)
    # warm-up (compilation, caches, torch): nothing below times a first call
    rollout(ppo, targets[:1], cfg, seed=seed)
    for method in methods:
        solve_target(float(targets[0]), method, 40, seed, rollouts=Rollouts(cfg))
    rows = [_closed_loop("ppo", ppo, targets, cfg, seed, train_wall_s=train_wall,
                         train_steps=train_steps)]
    robust = None
    if rand_path is not None:
        robust = load_policy(rand_path, cfg)
        rows.append(_closed_loop("ppo_randomised", robust, targets, cfg, seed,
                                 train_wall_s=float(robust.metadata.get("wall_time_s", np.nan)),
                                 train_steps=int(robust.metadata.get("steps", 0))))
    rows.append(_closed_loop("random", _RandomPolicy(seed), targets, cfg, seed))
    fixed = encode_actions(FIXED_SCHEDULE["frequency_hz"], FIXED_SCHEDULE["stroke_m"],
                           FIXED_SCHEDULE["delay_s"], cfg)
    fixed_plan = np.broadcast_to(fixed, (cfg.n_actuators, 3)).copy()
    t0 = time.perf_counter()
    res = plan_rollout(fixed_plan)(cfg, targets, seed)
    rows.append(_rows("fixed_schedule", res, targets, cfg.tolerance, episodes_per_target=1,
                      wall_s_per_target=(time.perf_counter() - t0) / len(targets),
                      schedule=FIXED_SCHEDULE))
    plans: dict[str, np.ndarray] = {}
    bar = tqdm(total=len(methods) * len(budgets) * n_targets, desc="open-loop searches",
               unit="target", disable=not progress)
    for method in methods:
        for b in budgets:
            row, p = _open_loop(method, int(b), targets, cfg, seed, bar.update)
            rows.append(row)
            plans[f"{method}_{int(b)}"] = p
    bar.close()
    ppo_row = rows[0]
    for row in rows:
        if "budget" in row:
            row["crossover_targets"] = crossover(train_wall, ppo_row["wall_s_per_target"],
                                                 row["wall_s_per_target"])
    amortised = train_wall / amortise_over + ppo_row["wall_s_per_target"]

    tol = {row["method"] + (f"_{row['budget']}" if "budget" in row else ""):
           [float(np.mean(np.asarray(row["rest"]) & (np.asarray(row["abs_error_m"]) <= t)))
            for t in TOLERANCES] for row in rows}

    # perturbation: closed loop (PPO, PPO randomised) vs the open-loop plans of the largest budget
    runners: dict[str, Callable] = {"ppo": policy_rollout(ppo)}
    if robust is not None:
        runners["ppo_randomised"] = policy_rollout(robust)
    for method in methods:
        key = f"{method}_{int(max(budgets))}"
        runners[f"{method}_{int(max(budgets))}_plan"] = plan_rollout(plans[key])
    pert: dict[str, dict] = {}
    ladders = {"action_noise": [Level(action_noise=s) for s in noise_ladder],
               "spread": [Level(spread=r) for r in spread_ladder]}
    for name, run in tqdm(runners.items(), desc="perturbation", disable=not progress):
        pert[name] = {axis: perturbation_table(run, cfg, targets, levels, seed=seed,
                                               repeats=perturb_repeats)
                      for axis, levels in ladders.items()}
    return {"targets_m": targets.tolist(), "seed": seed, "tolerance_m": cfg.tolerance,
            "rows": rows, "ppo_amortised": {"over_targets": amortise_over,
                                            "wall_s_per_target": amortised},
            "tolerance": {"tolerances_m": list(TOLERANCES), "success_rate": tol},
            "perturbation": pert, "policy": str(ppo.path),
            "randomised_policy": None if rand_path is None else str(rand_path)}


def summary_table(result: dict) -> str:
    """The comparison as a plain-text table (one line per method and budget)."""
    head = (f"{'method':<16}{'budget':>7}{'success':>9}{'median |err|':>14}{'travel':>9}"
            f"{'wall/target':>13}{'episodes':>10}{'crossover N':>13}")
    lines = [head, "-" * len(head)]
    for r in result["rows"]:
        tt = r.get("median_travel_time_s")
        cross = r.get("crossover_targets")
        lines.append(
            f"{r['method']:<16}{r.get('budget', ''):>7}{100 * r['success_rate']:>8.0f}%"
            f"{1e6 * r['median_abs_error_m']:>11.1f} µm"
            f"{'' if tt is None else f'{1e3 * tt:.0f} ms':>9}"
            f"{1e3 * r['wall_s_per_target']:>10.2f} ms{r['episodes_per_target']:>10.0f}"
            f"{'' if cross is None else f'{cross:.0f}':>13}")
    ppo = result["rows"][0]
    lines.append(f"PPO training: {ppo['train_wall_s']:.0f} s, {ppo['train_steps']:,} env steps "
                 "(firings); "
                 f"amortised over {result['ppo_amortised']['over_targets']} targets: "
                 f"{result['ppo_amortised']['wall_s_per_target']:.2f} s per target")
    return "\n".join(lines)
