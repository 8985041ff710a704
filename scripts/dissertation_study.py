"""The dissertation's shared-parameter problem on this model (a study script, not a test):
the figures and numbers of docs/agents.md.

    python scripts/dissertation_study.py [--seeds 10] [--long-seeds 4]
        [--out docs/figures/dissertation.json] [--figures docs/figures]

Runs DE (population 50, 50 generations, CR 0.8, F 0.9: 2,550 episodes) and CMA-ES with the
same budget for seeds 0..seeds-1, both again with ten times the budget for ``--long-seeds``
seeds; replays Table 4.3's schedule here; replays it under one-at-a-time model changes and
re-runs the DE under each (:func:`agents.openloop.table43.explain`). Writes the JSON and the charts
``dissertation_cost_history.png``, ``dissertation_trajectory.png`` and ``table43_variants.png``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np


def main() -> None:
    from agents.openloop.dissertation import TABLE_4_3, DissertationProblem, evaluate_parameters, \
        solve_dissertation, trajectory
    from agents.plots.optimize import plot_cost_history
    from agents.plots.trajectories import plot_plan_trajectories
    from agents.openloop.table43 import explain

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--long-seeds", type=int, default=4)
    ap.add_argument("--out", default="docs/figures/dissertation.json")
    ap.add_argument("--figures", default="docs/figures")
    args = ap.parse_args()
    fig = Path(args.figures)
    prob = DissertationProblem()
    solve_dissertation("de", seed=100, budget=100, popsize=50)  # warm-up
    out: dict[str, Any] = {"loadavg_before": os.getloadavg(), "runs": []}
    best: dict[str, Any] = {}
    for method, budget, seeds in (("de", 2550, args.seeds), ("cmaes", 2550, args.seeds),
                                  ("de", 25500, args.long_seeds),
                                  ("cmaes", 25500, args.long_seeds)):
        for seed in range(seeds):
            r = solve_dissertation(method, seed=seed, budget=budget)
            row = {**r.to_dict(), "budget": budget}
            out["runs"].append(row)
            key = f"{method}_{budget}"
            if key not in best or r.cost < best[key].cost:
                best[key] = r
            print(f"{method:6s} {budget:6d} seed {seed}: {r.final_position_m * 1e3:.3f} mm "
                  f"({r.outcome}) in {r.travel_time_s * 1e3:.1f} ms, {r.wall_time_s:.2f} s",
                  file=sys.stderr, flush=True)
    summary = []
    for key in best:
        method, budget = key.split("_")
        rs = [r for r in out["runs"] if r["method"] == method and r["budget"] == int(budget)]
        x = np.array([r["final_position_m"] for r in rs])
        w = np.array([r["wall_time_s"] for r in rs])
        summary.append({"method": method, "budget": int(budget), "runs": len(rs),
                        "median_final_position_m": float(np.median(x)),
                        "min_final_position_m": float(x.min()),
                        "max_final_position_m": float(x.max()),
                        "median_wall_time_s": float(np.median(w)),
                        "best": {k: getattr(best[key], k) for k in
                                 ("seed", "parameters", "final_position_m", "travel_time_s",
                                  "outcome", "cost", "episodes")}})
    out["summary"] = summary
    out["table_4_3"] = {"dissertation": TABLE_4_3,
                        "this_model": evaluate_parameters(TABLE_4_3, prob)}
    out["explain"] = explain(prob, seed=0)
    out["loadavg_after"] = os.getloadavg()
    Path(args.out).write_text(json.dumps(out, indent=1))
    runs0 = {f"{m} seed 0": next((r["history_episodes"], r["history_best_cost"])
                                 for r in out["runs"]
                                 if r["method"] == m and r["seed"] == 0 and r["budget"] == 2550)
             for m in ("de", "cmaes")}
    plot_cost_history(runs0, str(fig / "dissertation_cost_history.png"))
    de0 = next(r for r in out["runs"] if r["method"] == "de" and r["seed"] == 0)
    far = best["de_25500"]

    def label(p: dict[str, float], what: str) -> str:
        return (f"{what} ({p['frequency_hz']:.0f} Hz, {p['spacing_m'] * 1e6:.0f} µm, "
                f"{p['delay_s'] * 1e3:.2f} ms, {p['stroke_m'] * 1e6:.0f} µm)")

    plot_plan_trajectories({label(de0["parameters"], "DE seed 0, 2,550 ep."):
                       trajectory(de0["parameters"], prob),
                       label(far.parameters, "best DE, 25,500 ep."):
                       trajectory(far.parameters, prob),
                       label(TABLE_4_3, "Table 4.3"): trajectory(TABLE_4_3, prob)},
                      str(fig / "dissertation_trajectory.png"), prob.target_m)
    contact = prob.simulator().contact
    variant = prob.replace(config__wavelength=0.95e-3,
                           contact=contact.replace(friction_scale=contact.friction_scale * 0.25))
    plot_plan_trajectories({"this model (WL 0.6 mm, friction as calibrated)":
                       trajectory(TABLE_4_3, prob),
                       "WL 0.95 mm and friction x 0.25": trajectory(TABLE_4_3, variant)},
                      str(fig / "table43_variants.png"), prob.target_m,
                      title="Table 4.3 schedule (719 Hz, 500 µm, 1 ms, 178 µm) in two models")
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
