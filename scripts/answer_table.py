"""Measure the README's answer table: how precisely and how fast a part is placed at 1, 3, 5, 7
and 9 mm on MicroConveyor-v1, by which method, nominally and under execution noise (every
episode's final error, outcome and placement time: the simulated time until the part rests).

Methods: the shipped policy ``MicroConveyor-v1/ppo_refined`` (closed loop), MPC seeded by that
policy's plan (``agents.mpc``, the settings of ``microconveyor compare``) and differential
evolution per target (open loop, ``agents.openloop``, budget 1,000 episodes; its nominal plan is
replayed under noise). Per distance d, ``--per-distance`` targets spread over d ± 0.1 mm; the
noise level (σ in action units) is replayed with ``--noise-seeds`` seeds per target. Writes the JSON
that ``scripts/results_tables.py`` turns into the README's table::

    nice python scripts/answer_table.py --out docs/figures/answer_table.json
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from agents.experiments.compare_settings import MPC_SETTINGS
from agents.experiments.perturb import Level, perturbation_table, plan_rollout, policy_rollout
from agents.mpc.harness import mpc_rollout
from agents.openloop.target import solve_target
from agents.planning import LineRollouts
from agents.rl.artefacts.shipped import require_shipped
from agents.rl.evaluation.evaluate import distance_targets, load_policy
from microconveyor_env.envs import env_config

ENV_ID = "MicroConveyor-v1"
DISTANCES_M = (1e-3, 3e-3, 5e-3, 7e-3, 9e-3)
DE_BUDGET = 1000


def noise_in_si(sigma: float, cfg) -> dict:
    """One standard deviation of execution noise ``sigma`` [action units] as the firing's
    frequency (relative, and at 1 kHz), stroke and delay jitter (docs/randomisation.md)."""
    rel_f = math.exp(sigma / 2 * cfg.log_freq_span) - 1.0
    return {"sigma_action_units": sigma,
            "frequency_relative": rel_f,
            "frequency_at_1khz_hz": 1000.0 * rel_f,
            "stroke_m": sigma / 2 * (cfg.stroke_range[1] - cfg.stroke_range[0]),
            "delay_s": sigma / 2 * (cfg.delay_range[1] - cfg.delay_range[0])}


def _episodes(run, cfg, targets, sigma: float, repeats: int, seed: int) -> list[dict]:
    """One row per episode (``perturbation_table``'s), each with its placement time ``time_s``
    [s]: the simulated time until the part rested (or detached)."""
    times: list[float] = []

    def timed(config, tg, s):
        res = run(config, tg, s)
        times.extend(np.asarray(res["time_s"], float).tolist())
        return res

    rows = perturbation_table(timed, cfg, targets, [Level(action_noise=sigma)], seed=seed,
                              repeats=repeats, tolerance=cfg.tolerance, per_episode=True)
    # perturbation_table writes each rollout's rows right after it, in target order
    return [{**row, "time_s": t} for row, t in zip(rows, times, strict=True)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures/answer_table.json"))
    ap.add_argument("--per-distance", type=int, default=5)
    ap.add_argument("--noise-seeds", type=int, default=10)
    ap.add_argument("--sigma", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mpc-workers", type=int, default=1)
    ap.add_argument("--de-budget", type=int, default=DE_BUDGET,
                    help=f"DE's episodes per target (default {DE_BUDGET})")
    args = ap.parse_args()
    load_before = os.getloadavg()[0]

    cfg = env_config(ENV_ID)
    targets = distance_targets(cfg, DISTANCES_M, args.per_distance).reshape(-1)
    policy_dir = require_shipped(ENV_ID, "ppo_refined")
    policy = load_policy(policy_dir, cfg)
    methods: dict[str, dict] = {}

    def record(name: str, run, compute: dict) -> None:
        nominal = _episodes(run, cfg, targets, 0.0, 1, args.seed)
        noisy = _episodes(run, cfg, targets, args.sigma, args.noise_seeds, args.seed)
        methods[name] = {**compute, "nominal": nominal, "noise": noisy}

    # the policy: one forward pass per firing
    run = policy_rollout(policy)
    run(cfg, targets, args.seed)  # warm-up (compilation)
    t0 = time.perf_counter()
    run(cfg, targets, args.seed)
    record("ppo_refined", run, {"wall_s_per_target": (time.perf_counter() - t0) / len(targets)})

    # DE per target on the nominal model, its plan replayed
    roll = LineRollouts(cfg)
    plans, wall = [], 0.0
    for k, tg in enumerate(targets):
        r = solve_target(float(tg), "de", args.de_budget, args.seed + k, rollouts=roll)
        plans.append(r.plan)
        wall += r.wall_time_s
    record("de", plan_rollout(np.array(plans)),
           {"wall_s_per_target": wall / len(targets), "budget_episodes": args.de_budget})

    # MPC seeded by the policy's plan, re-planning after every firing on the nominal model
    with mpc_rollout(MPC_SETTINGS, workers=args.mpc_workers, prior=str(policy_dir)) as mpc:
        walls: list[float] = []

        def timed(config, tg, s):
            res = mpc(config, tg, s)
            walls.extend(np.asarray(res["wall_time_s"], float).tolist())
            return res

        record("mpc_ppo_refined", timed, {"settings": {
            "first_budget": MPC_SETTINGS.first_budget,
            "replan_budget": MPC_SETTINGS.replan_budget, "method": MPC_SETTINGS.method}})
        methods["mpc_ppo_refined"]["wall_s_per_target"] = float(np.mean(walls))

    out = {"env_id": ENV_ID, "policy": f"{ENV_ID}/ppo_refined", "tolerance_m": cfg.tolerance,
           "distances_m": list(DISTANCES_M), "targets_m": targets.tolist(),
           "targets_per_distance": args.per_distance, "noise_seeds": args.noise_seeds,
           "seed": args.seed, "noise": noise_in_si(args.sigma, cfg), "methods": methods,
           "provenance": {"machine": f"{platform.machine()}, {os.cpu_count()} cores",
                          # 1-min load average before and after: the compute column's context
                          "load_average": [load_before, os.getloadavg()[0]],
                          "python": platform.python_version(),
                          "recorded_utc": datetime.datetime.now(datetime.UTC)
                          .isoformat(timespec="seconds"),
                          "command": "nice python scripts/answer_table.py "
                                     f"--per-distance {args.per_distance} "
                                     f"--noise-seeds {args.noise_seeds} --sigma {args.sigma}"
                                     + (f" --de-budget {args.de_budget}"
                                        if args.de_budget != DE_BUDGET else "")}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
