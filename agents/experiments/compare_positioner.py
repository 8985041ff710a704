"""The comparison on MicroPositioner-v0: closed loop (PPO, the one-step model-based controller
with an identified or the nominal model) against open loop (DE and CMA-ES plans of a few
firings, searched on the nominal model and replayed unchanged), with the controller that knows
each episode's hidden friction and mass as a reference row; what one run does is a
:class:`.compare_settings.CompareSettings`.

The same fixed targets, rows, perturbation axes, tables and charts as the line's comparison
(:mod:`.compare`, :mod:`.perturb`, :mod:`agents.plots.compare`); what is the positioner's own is
the runner of each method: :class:`agents.mpc.positioner.PositionerMPCRollout` for the
controller, :func:`agents.openloop.positioner.solve_plan` and
:func:`~agents.openloop.positioner.plans_rollout` for the plans, the batched rollout of
:mod:`agents.rl.evaluation.evaluate` for PPO. Everything runs in this process (one core).

Per method and target: the final error, success within the tolerance, detachment, the compute
(wall time [s] and model episodes: for the controller, every candidate firing it simulated; for
a plan, every episode of its search). Under perturbation, every level replays the same targets
with the same seeds (:mod:`.perturb`).
"""
from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import numpy as np

from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.versions import scene_config

from ..mpc.positioner import PositionerMPCRollout, PositionerMPCSettings
from ..openloop.positioner import PlanRollouts, nominal_rollouts, plans_rollout, solve_plan
from ..rl.evaluation.evaluate import fixed_targets, load_policy, rollout
from .compare_rows import (TOLERANCES, closed_loop_row, episodes_to, policy_row_name, result_row,
                           reusing)
from .compare_settings import CompareSettings
from .perturb import axes_table, perturbation_levels, policy_rollout, unique_levels

# the row that knows what no controller can: a reference, never a method
REFERENCE = {"mpc_oracle": "reference (knows the hidden factors)"}


def _mpc_row(name: str, model: str, cfg: Any, targets: np.ndarray, seed: int,
             runners: dict[str, Callable], progress: bool) -> dict:
    run = PositionerMPCRollout(PositionerMPCSettings(model=model))
    if progress:
        print(f"{name}: {len(targets)} targets ...", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    res = run(cfg, targets, seed)
    extra: dict[str, Any] = {}
    if name in REFERENCE:
        extra["reference"] = REFERENCE[name]
    row = result_row(name, res, targets, cfg.tolerance,
                     wall_s_per_target=(time.perf_counter() - t0) / len(targets),
                     episodes_per_target=float(np.mean(res["episodes"])),
                     planning_wall_s_per_target=float(np.mean(res["wall_time_s"])),
                     mean_firings=float(np.mean(res["firings"])),
                     settings=dataclasses.asdict(run.settings), **extra)
    runners[name] = reusing(run, cfg, targets, seed, res)
    return row


def _plan_row(method: str, budget: int, cfg: Any, targets: np.ndarray, seed: int,
              firings: int, roll: PlanRollouts,
              progress: Callable[[], None] | None) -> tuple[dict, np.ndarray]:
    plans, err, outcome, t, wall, eps, reach = [], [], [], [], 0.0, 0, []
    for k, tg in enumerate(targets):
        r = solve_plan(float(tg), method, budget, seed + k, roll, firings)
        plans.append(r.plan)
        err.append(r.error_m)
        outcome.append(r.outcome)
        t.append(r.sim_time_s)
        wall += r.wall_time_s
        eps += r.episodes
        reach.append(episodes_to(r.history_episodes, r.history_best_abs_error_m, cfg.tolerance))
        if progress:
            progress()
    res = {"error_m": err, "outcome": outcome, "time_s": t}
    row = result_row(method, res, targets, cfg.tolerance, budget=int(budget),
                     plan_firings=firings, wall_s_per_target=wall / len(targets),
                     episodes_per_target=eps / len(targets), episodes_to_tolerance=reach)
    return row, np.array(plans)


def _policy(s: CompareSettings) -> Path | None:
    """The policy folder: the one given, else the env's default shipped policy if there is one
    (None: no policy row)."""
    from ..rl.artefacts.shipped import default_policy_name, shipped_path

    if s.policy == "":
        return None
    if s.policy is not None:
        return Path(s.policy)
    cand = shipped_path(default_policy_name(s.env_id), s.env_id)
    return cand if (cand / "model.zip").is_file() else None


def compare_positioner(settings: CompareSettings) -> dict:
    """Run the comparison ``settings`` describe on a positioner id. Returns a JSON-able dict
    (``rows``, ``tolerance``, ``perturbation``, ...; SI units) of the line's comparison's form;
    the reference row carries ``reference``."""
    from tqdm import tqdm

    s = settings
    cfg = s.config or scene_config(s.env_id)
    seed = s.seed
    targets = fixed_targets(cfg, s.n_targets, seed)
    rows: list[dict] = []
    runners: dict[str, Callable] = {}
    path = _policy(s)
    ppo = None
    if path is not None:
        ppo = load_policy(path, cfg)
        rollout(ppo, targets[:1], cfg, seed=seed)   # warm-up: nothing below times a first call
        meta = ppo.metadata
        name = policy_row_name(meta, path)   # its folder's: the shipped dagger, a run's name
        rows.append(closed_loop_row(name, ppo, targets, cfg, seed,
                                    train_wall_s=float(meta.get("wall_time_s", np.nan)),
                                    train_steps=int(meta.get("steps", 0)), policy=str(path)))
        runners[name] = policy_rollout(ppo)
    for model in (m for m in s.mpc_models if f"mpc_{m}" not in REFERENCE):
        rows.append(_mpc_row(f"mpc_{model}", model, cfg, targets, seed, runners, s.progress))
    plans: dict[str, np.ndarray] = {}
    roll = nominal_rollouts(cast(PositionerConfig, cfg))
    bar = tqdm(total=len(s.methods) * len(s.budgets) * len(targets), desc="open-loop plans",
               unit="target", disable=not s.progress)
    for method in s.methods:
        for b in s.budgets:
            row, p = _plan_row(method, int(b), cfg, targets, seed, s.plan_firings, roll,
                               bar.update)
            rows.append(row)
            plans[f"{method}_{int(b)}"] = p
    bar.close()
    for method in s.methods:   # under perturbation: the plans of the largest budget
        key = f"{method}_{int(max(s.budgets))}"
        runners[f"{key}_plan"] = plans_rollout(plans[key])
    for model in (m for m in s.mpc_models if f"mpc_{m}" in REFERENCE):   # the reference, last
        rows.append(_mpc_row(f"mpc_{model}", model, cfg, targets, seed, runners, s.progress))

    tol = {row["method"] + (f"_{row['budget']}" if "budget" in row else ""):
           [float(np.mean(np.asarray(row["rest"]) & (np.asarray(row["abs_error_m"]) <= t)))
            for t in TOLERANCES] for row in rows}
    axes = perturbation_levels(s.noise_ladder, s.spread_ladder, s.diagonal, s.full_grid)
    pert: dict[str, dict] = {}
    bar = tqdm(total=len(runners) * len(unique_levels(axes)), desc="perturbation",
               unit="level", disable=not s.progress)
    for name, run in runners.items():
        bar.set_postfix_str(name)
        pert[name] = axes_table(run, cfg, targets, axes, seed, s.perturb_repeats, bar.update)
    bar.close()
    out: dict[str, Any] = {
        "env_id": s.env_id, "targets_m": targets.tolist(), "seed": seed,
        "tolerance_m": cfg.tolerance, "rows": rows,
        "tolerance": {"tolerances_m": list(TOLERANCES), "success_rate": tol},
        "perturbation": pert, "seeds": None, "plan_firings": s.plan_firings,
        "reference_methods": {k: v for k, v in REFERENCE.items() if k in pert},
        "policy": None if path is None else str(path), "randomised_policy": None,
        "mpc_worker_deaths": 0}
    if ppo is not None:
        train = rows[0]["train_wall_s"]
        out["ppo_amortised"] = {"over_targets": s.amortise_over,
                                "wall_s_per_target": train / s.amortise_over
                                + rows[0]["wall_s_per_target"]}
    return out
