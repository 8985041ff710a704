"""The comparison of closed loop against open loop on the same fixed targets, on any scene the
planners serve (the conveyor line, the positioner: :func:`agents.planning.scene_of`); what one
run does is a :class:`.compare_settings.CompareSettings`.

On the line: PPO, the PPO trained under randomisation and model-predictive control against DE
and CMA-ES plans, a random policy and a fixed schedule. On the positioner: its policy (the
shipped ``dagger``) and the one-step model-based controller with an identified or the nominal
model against DE and CMA-ES plans of a few firings, searched on the nominal model and replayed
unchanged, with the controller that knows each episode's hidden friction and mass as a
reference row (:data:`REFERENCE`); everything there runs in this process (one core).

For every method (and budget), per target: the final error, success within the tolerance, the
travel (simulated) time, and the compute it took — wall time [s] and simulated episodes. PPO pays
its training once (``metadata.json`` of the policy: wall time and steps) and then one batched
rollout per target; it is shown both at deployment cost and amortised over ``N`` targets, with
the crossover ``N`` above which training once costs less than searching every target. MPC
(:mod:`agents.mpc`) searches on the nominal model before every firing: its compute per target
is the sum of its searches. Then: success against tolerance (a performance profile), the ECDF of
the episodes an optimiser needs to reach the tolerance (as COCO compares black-box optimisers),
and success against perturbation (the env's per-episode randomisation, :mod:`.perturb`): an
execution-noise axis, a model-error axis, their combinations on a diagonal (and with
``full_grid`` every combination), with 95 % Wilson intervals; open-loop plans are made on the
nominal model. With several training seeds of PPO (``policy_seeds``), their IQM and its
bootstrap interval.

The policy's row is named after its folder (the shipped ``ppo_refined``, a run folder's name;
:func:`.compare_rows.policy_row_name`) and carries its path (``policy``); the MPC seeded by a
policy's plan is ``mpc_<its folder's name>`` (``mpc_ppo_refined``).
"""
from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.env_ids import REGISTRY
from microconveyor_env.envs import EnvConfig, env_config
from microconveyor_env.envs.core.actions import encode_actions
from microconveyor_env.envs.core.versions import nominal, scene_config

from ..mpc import OneStepSettings, mpc_rollout
from ..openloop.target import plans_rollout, solve_target
from ..planning import Rollouts, scene_of
from ..rl.evaluation.evaluate import fixed_targets, load_policy, rollout
from ..rl.evaluation.seeds import iqm_interval
from .compare_rows import (TOLERANCES, closed_loop_row, episodes_to, policy_row_name, result_row,
                           reusing, seeded_mpc_name)
from .compare_settings import CompareSettings
from .perturb import (Level, axes_table, perturbation_levels, plan_rollout, policy_rollout,
                      unique_levels)

# the positioner's row that knows what no controller can: a reference, never a method
REFERENCE = {"mpc_oracle": "reference (knows the hidden factors)"}
# the fixed schedule: every actuator at the single-firing optimum of the reference scene
FIXED_SCHEDULE = {"frequency_hz": 950.0, "stroke_m": 200e-6, "delay_s": 0.0}


class _RandomPolicy:
    """Uniform random actions in the box (seeded)."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, (len(obs), 3)).astype(np.float32)


def _open_loop(method: str, budget: int, targets: np.ndarray, cfg: Any, seed: int,
               roll: Rollouts, progress: Callable[[], None] | None = None,
               firings: int | None = None) -> tuple[dict, np.ndarray]:
    """The row of ``method``'s plans at ``budget``, searched on ``roll`` (plans of ``firings``
    where the scene takes any number), and the plans."""
    plans, err, outcome, t, wall, eps, reach = [], [], [], [], 0.0, 0, []
    for k, tg in enumerate(targets):
        r = solve_target(float(tg), method, budget, seed + k, rollouts=roll, firings=firings)
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
    shape = {} if firings is None else {"plan_firings": firings}
    row = result_row(method, res, targets, cfg.tolerance, budget=int(budget), **shape,
                     wall_s_per_target=wall / len(targets),
                     episodes_per_target=eps / len(targets), episodes_to_tolerance=reach)
    return row, np.array(plans)


def seed_summary(values: Sequence[float], seed: int = 0) -> dict:
    """Per-seed scores summed up as rliable does for one task: their IQM and its 95 %
    percentile-bootstrap interval over seeds, 2,000 resamples drawn with ``seed``
    (:func:`agents.rl.evaluation.seeds.iqm_interval`)."""
    return iqm_interval(values, 2000, seed)

def crossover(train_wall_s: float, ppo_wall_s: float, other_wall_s: float) -> float | None:
    """Targets N above which training once (``train_wall_s``) plus ``N`` deployments
    (``ppo_wall_s`` each) costs less wall time than ``N`` searches (``other_wall_s`` each);
    None when the search is no dearer per target than deploying the policy."""
    gain = other_wall_s - ppo_wall_s
    return None if gain <= 0 else float(train_wall_s / gain)


def compare(settings: CompareSettings | None = None) -> dict:
    """Run the comparison ``settings`` describe (default: :class:`CompareSettings`'s defaults)
    on its scene. Returns a JSON-able dict (``rows``, ``tolerance``, ``perturbation``,
    ``seeds``, ...; SI units); on the positioner the reference row carries ``reference``."""
    from ..rl.artefacts.shipped import require_shipped, shipped_path

    s = settings or CompareSettings()   # the policy row: s.policy, else the id's default shipped
    if REGISTRY[s.env_id].geometry == "positioner":
        return _compare_positioner(s)
    cfg = s.config or env_config(s.env_id)
    targets = fixed_targets(cfg, s.n_targets, s.seed)
    ppo = load_policy(s.policy or require_shipped(s.env_id), cfg)   # the id's default
    rand_path: Path | None = None
    if s.randomised_policy is None:
        cand = shipped_path("ppo_randomised", s.env_id)
        rand_path = cand if (cand / "model.zip").is_file() else None
    elif s.randomised_policy != "":
        rand_path = Path(s.randomised_policy)
    seeds = [load_policy(p, cfg) for p in s.policy_seeds]
    with contextlib.ExitStack() as stack:  # the MPC's worker processes
        return _compare(stack, s, cfg, targets, ppo, rand_path, seeds)


def _compare(stack: contextlib.ExitStack, s: CompareSettings, cfg: EnvConfig,
             targets: np.ndarray, ppo: Any, rand_path: Path | None, seeds: list) -> dict:
    from tqdm import tqdm

    seed = s.seed
    meta = ppo.metadata
    train_wall, train_steps = float(meta.get("wall_time_s", np.nan)), int(meta.get("steps", 0))
    # warm-up (compilation, caches, torch): nothing below times a first call
    rollout(ppo, targets[:1], cfg, seed=seed)
    for method in s.methods:
        solve_target(float(targets[0]), method, 40, seed, config=cfg)
    name = policy_row_name(meta, ppo.path)   # its folder's: ppo, ppo_refined, a run's name
    rows = [closed_loop_row(name, ppo, targets, cfg, seed, train_wall_s=train_wall,
                            train_steps=train_steps, policy=str(ppo.path))]
    robust = None
    if rand_path is not None:
        robust = load_policy(rand_path, cfg)
        rows.append(closed_loop_row("ppo_randomised", robust, targets, cfg, seed,
                                 train_wall_s=float(robust.metadata.get("wall_time_s", np.nan)),
                                 train_steps=int(robust.metadata.get("steps", 0)),
                                 policy=str(robust.path)))
    runners: dict[str, Callable] = {name: policy_rollout(ppo)}
    if robust is not None:
        runners["ppo_randomised"] = policy_rollout(robust)
    mpc_runs = _mpc_rows(stack, s, cfg, targets, rows, runners)
    rows.append(closed_loop_row("random", _RandomPolicy(seed), targets, cfg, seed))
    fixed = encode_actions(FIXED_SCHEDULE["frequency_hz"], FIXED_SCHEDULE["stroke_m"],
                           FIXED_SCHEDULE["delay_s"], cfg)
    fixed_plan = np.broadcast_to(fixed, (cfg.n_actuators, 3)).copy()
    t0 = time.perf_counter()
    res = plan_rollout(fixed_plan)(cfg, targets, seed)
    rows.append(result_row("fixed_schedule", res, targets, cfg.tolerance,
                           episodes_per_target=1,
                           wall_s_per_target=(time.perf_counter() - t0) / len(targets),
                           schedule=FIXED_SCHEDULE))
    plans: dict[str, np.ndarray] = {}
    bar = tqdm(total=len(s.methods) * len(s.budgets) * len(targets), desc="open-loop searches",
               unit="target", disable=not s.progress)
    roll = scene_of(cfg).rollouts()
    for method in s.methods:
        for b in s.budgets:
            row, p = _open_loop(method, int(b), targets, cfg, seed, roll, bar.update)
            rows.append(row)
            plans[f"{method}_{int(b)}"] = p
    bar.close()
    ppo_row = rows[0]
    for row in rows:
        if "budget" in row:
            row["crossover_targets"] = crossover(train_wall, ppo_row["wall_s_per_target"],
                                                 row["wall_s_per_target"])
    amortised = train_wall / s.amortise_over + ppo_row["wall_s_per_target"]

    tol = {row["method"] + (f"_{row['budget']}" if "budget" in row else ""):
           [float(np.mean(np.asarray(row["rest"]) & (np.asarray(row["abs_error_m"]) <= t)))
            for t in TOLERANCES] for row in rows}

    # perturbation: every method, the open-loop plans of the largest budget (made nominally)
    runners["random"] = policy_rollout(_RandomPolicy(seed).act)
    runners["fixed_schedule"] = plan_rollout(fixed_plan)
    for method in s.methods:
        key = f"{method}_{int(max(s.budgets))}"
        runners[f"{key}_plan"] = plan_rollout(plans[key])
    axes = perturbation_levels(s.noise_ladder, s.spread_ladder, s.diagonal, s.full_grid)
    pert = _perturbation(runners, s, cfg, targets, axes)
    return {"env_id": s.env_id, "targets_m": targets.tolist(), "seed": seed,
            "tolerance_m": cfg.tolerance, "rows": rows,
            "ppo_amortised": {"over_targets": s.amortise_over, "wall_s_per_target": amortised},
            "tolerance": {"tolerances_m": list(TOLERANCES), "success_rate": tol},
            "perturbation": pert, "seeds": _seed_stats(seeds, s, cfg, targets, axes),
            "policy": str(ppo.path),
            "randomised_policy": None if rand_path is None else str(rand_path),
            # pools an MPC worker's death broke (its episodes ran again; twice: failed)
            "mpc_worker_deaths": sum(r.worker_deaths for r in mpc_runs)}


def _mpc_rows(stack: contextlib.ExitStack, s: CompareSettings, cfg: EnvConfig,
              targets: np.ndarray, rows: list[dict], runners: dict[str, Callable]) -> list[Any]:
    """The MPCs' rows (appended to ``rows``) and perturbation runners (added to ``runners``);
    their rollouts (worker pools closed with ``stack``)."""
    prior = None if s.mpc_prior is None else str(s.mpc_prior)
    mpc_runs: list[Any] = []
    seeded_name = None if prior is None else seeded_mpc_name(prior, ("mpc", "mpc_robust"))
    for name, settings, seeded in (("mpc", s.mpc, None),
                                   (seeded_name, s.mpc if prior else None, prior),
                                   ("mpc_robust", s.robust_mpc, prior)):
        if settings is None or name is None:
            continue
        run_mpc = stack.enter_context(mpc_rollout(settings, workers=s.mpc_workers,
                                                  prior=seeded))
        mpc_runs.append(run_mpc)
        if s.progress:
            print(f"{name}: {len(targets)} targets on {s.mpc_workers} workers ...",
                  file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        res = run_mpc(cfg, targets, s.seed)
        rows.append(result_row(name, res, targets, cfg.tolerance,
                               wall_s_per_target=(time.perf_counter() - t0) / len(targets),
                               episodes_per_target=float(np.mean(res["episodes"])),
                               planning_wall_s_per_target=float(np.mean(res["wall_time_s"])),
                               workers=s.mpc_workers, settings=dataclasses.asdict(settings),
                               prior=seeded))
        runners[name] = reusing(run_mpc, cfg, targets, s.seed, res)
    return mpc_runs


def _seed_stats(seeds: list, s: CompareSettings, cfg: EnvConfig, targets: np.ndarray,
                axes: dict[str, list[Level]]) -> dict | None:
    """The PPO seeds' success along every perturbation axis: IQM and interval per level."""
    if not seeds:
        return None
    per_seed = [axes_table(policy_rollout(p), cfg, targets, axes, s.seed, s.perturb_repeats)
                for p in seeds]
    seed_pert = {axis: [{"action_noise": lv.action_noise, "spread": lv.spread,
                         **seed_summary([ps[axis][j]["success_rate"] for ps in per_seed],
                                        s.seed)}
                        for j, lv in enumerate(levels)] for axis, levels in axes.items()}
    return {"policies": [str(p.path) for p in seeds], "perturbation": seed_pert,
            "nominal": seed_pert["action_noise"][0]}


def _perturbation(runners: dict[str, Callable], s: CompareSettings, cfg: Any,
                  targets: np.ndarray, axes: dict[str, list[Level]]) -> dict[str, dict]:
    """Every runner's success along every perturbation axis (:func:`.perturb.axes_table`)."""
    from tqdm import tqdm

    pert: dict[str, dict] = {}
    bar = tqdm(total=len(runners) * len(unique_levels(axes)), desc="perturbation",
               unit="level", disable=not s.progress)
    for name, run in runners.items():
        bar.set_postfix_str(name)
        pert[name] = axes_table(run, cfg, targets, axes, s.seed, s.perturb_repeats, bar.update)
    bar.close()
    return pert


def _one_step_row(name: str, model: str, cfg: Any, targets: np.ndarray, seed: int,
             runners: dict[str, Callable], progress: bool) -> dict:
    settings = OneStepSettings(model=model)
    run = mpc_rollout(settings)
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
                     settings=dataclasses.asdict(settings), **extra)
    runners[name] = reusing(run, cfg, targets, seed, res)
    return row


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


def _compare_positioner(settings: CompareSettings) -> dict:
    """The comparison on a positioner id (module docstring), of the line's comparison's form."""
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
        rows.append(_one_step_row(f"mpc_{model}", model, cfg, targets, seed, runners, s.progress))
    plans: dict[str, np.ndarray] = {}
    roll = scene_of(cfg).rollouts(nominal(cfg))
    bar = tqdm(total=len(s.methods) * len(s.budgets) * len(targets), desc="open-loop plans",
               unit="target", disable=not s.progress)
    for method in s.methods:
        for b in s.budgets:
            row, p = _open_loop(method, int(b), targets, cfg, seed, roll, bar.update,
                                s.plan_firings)
            rows.append(row)
            plans[f"{method}_{int(b)}"] = p
    bar.close()
    for method in s.methods:   # under perturbation: the plans of the largest budget
        key = f"{method}_{int(max(s.budgets))}"
        runners[f"{key}_plan"] = plans_rollout(plans[key])
    for model in (m for m in s.mpc_models if f"mpc_{m}" in REFERENCE):   # the reference, last
        rows.append(_one_step_row(f"mpc_{model}", model, cfg, targets, seed, runners, s.progress))

    tol = {row["method"] + (f"_{row['budget']}" if "budget" in row else ""):
           [float(np.mean(np.asarray(row["rest"]) & (np.asarray(row["abs_error_m"]) <= t)))
            for t in TOLERANCES] for row in rows}
    axes = perturbation_levels(s.noise_ladder, s.spread_ladder, s.diagonal, s.full_grid)
    pert = _perturbation(runners, s, cfg, targets, axes)
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
