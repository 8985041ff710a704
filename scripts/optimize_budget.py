"""Budget versus accuracy of the per-target open-loop search, DE against CMA-ES (a study
script, not a test).

    python scripts/optimize_budget.py [--targets 10] [--budgets 100,300,1000,2000,5000,20000]
        [--out docs/figures/optimize_budget.json] [--plot docs/figures/optimize_budget.png]

Targets evenly over 0.5-3 mm (the env's default range); target i is solved with seed i by both
methods at every budget (:func:`agents.openloop.target.solve_target`). Per (method, budget): the median
best |error| [m] (a part not at rest counts as infinitely far), the success rate (at rest within
±50 µm), the mean episodes used and wall time. Writes the JSON (with every run) and a chart.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def main() -> None:
    from agents.openloop.target import solve_target
    from agents.planning import LineRollouts
    from agents.plots.optimize import plot_budget_errors

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=10)
    ap.add_argument("--budgets", default="100,300,1000,2000,5000,20000")
    ap.add_argument("--methods", default="de,cmaes")
    ap.add_argument("--out", default="docs/figures/optimize_budget.json")
    ap.add_argument("--plot", default="docs/figures/optimize_budget.png")
    args = ap.parse_args()
    targets = np.linspace(0.5e-3, 3e-3, args.targets)
    budgets = [int(b) for b in args.budgets.split(",")]
    roll = LineRollouts()
    solve_target(1e-3, "de", 30, 0, rollouts=roll)  # warm-up
    runs, summary = [], []
    load_before = os.getloadavg()
    for method in args.methods.split(","):
        for budget in budgets:
            errs, succ, eps, walls = [], [], [], []
            for i, target in enumerate(targets):
                t0 = time.perf_counter()
                r = solve_target(float(target), method, budget, seed=i, rollouts=roll)
                walls.append(time.perf_counter() - t0)
                errs.append(r.abs_error_m if r.outcome == "rest" else np.inf)
                succ.append(r.success)
                eps.append(r.episodes)
                runs.append({"method": method, "budget": budget, "target_m": float(target),
                             "seed": i, "abs_error_m": r.abs_error_m, "outcome": r.outcome,
                             "success": r.success, "episodes": r.episodes,
                             "wall_time_s": walls[-1]})
            row = {"method": method, "budget": budget,
                   "median_abs_error_m": float(np.median(errs)),
                   "max_abs_error_m": float(np.max(errs)),
                   "success_rate": float(np.mean(succ)), "mean_episodes": float(np.mean(eps)),
                   "mean_wall_time_s": float(np.mean(walls))}
            summary.append(row)
            print(f"{method:6s} {budget:6d}: median {row['median_abs_error_m'] * 1e6:9.3f} µm, "
                  f"success {row['success_rate']:.2f}, {row['mean_wall_time_s']:.2f} s/target",
                  file=sys.stderr, flush=True)
    out = {"targets_m": targets.tolist(), "tolerance_m": roll.config.tolerance,
           "loadavg_before": load_before, "loadavg_after": os.getloadavg(),
           "summary": summary, "runs": runs}
    with open(args.out, "w") as fh:
        json.dump(out, fh, indent=1)
    plot_budget_errors(summary, args.plot, roll.config.tolerance)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
