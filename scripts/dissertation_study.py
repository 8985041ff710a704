"""The dissertation's shared-parameter problem on this model (a study script, not a test):
the figures and numbers of docs/agents.md §1.

    python scripts/dissertation_study.py [--preset conveyor] [--seeds 10] [--long-seeds 10]
        [--out docs/figures/dissertation_conveyor.json] [--figures docs/figures]
        [--budgets 2550,25500] [--explain-seeds 10]

On the chapter-4 surface (preset ``conveyor``, the default; ``feasibility`` gives the chapter-3
record of ``dissertation.json``): DE with the dissertation's settings (population 50, 50
generations, CR 0.8, F 0.9: 2,550 episodes) and CMA-ES with the same budget for seeds
0..seeds-1, both again with ten times the budget for ``--long-seeds`` seeds; Table 4.3's
schedule replayed here; the one-at-a-time explanation (:func:`agents.openloop.table43.explain`,
10 seeds per change) at the dissertation's budget and at ten times it. Writes the JSON and the
charts ``dissertation_<preset>_cost_history.png`` and ``dissertation_<preset>_trajectory.png``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np


def _summary(rows: list[dict[str, Any]], target_m: float) -> dict[str, Any]:
    x = np.array([r["final_position_m"] for r in rows])
    t = np.array([r["travel_time_s"] for r in rows])
    rest = np.array([r["outcome"] == "rest" for r in rows])
    within = rest & (np.abs(x - target_m) <= 50e-6)
    return {"runs": len(rows), "median_final_position_m": float(np.median(x)),
            "min_final_position_m": float(x.min()), "max_final_position_m": float(x.max()),
            "median_travel_time_s": float(np.median(t)),
            "min_travel_time_s": float(t.min()), "max_travel_time_s": float(t.max()),
            "within_50um": int(within.sum()), "within_50um_in_50ms": int((within & (t <= 0.05)).sum()),
            "median_wall_time_s": float(np.median([r["wall_time_s"] for r in rows]))}


def main() -> None:
    from agents.openloop.dissertation import TABLE_4_3, DissertationProblem, evaluate_parameters, \
        solve_dissertation, trajectory
    from agents.openloop.table43 import explain
    from agents.plots.optimize import plot_cost_history
    from agents.plots.trajectories import plot_plan_trajectories
    from microconveyor_env.envs import EnvConfig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="conveyor")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--long-seeds", type=int, default=10)
    ap.add_argument("--out", default=None)
    ap.add_argument("--figures", default="docs/figures")
    ap.add_argument("--budgets", default="2550,25500",
                    help="episodes of the short and the long runs (default 2550,25500)")
    ap.add_argument("--explain-seeds", type=int, default=10,
                    help="seeds per variant of Table 4.3's explanation (default 10)")
    args = ap.parse_args()
    short, long = (int(b) for b in args.budgets.split(","))
    fig = Path(args.figures)
    out_path = Path(args.out or fig / f"dissertation_{args.preset}.json")
    prob = DissertationProblem(config=EnvConfig.from_yaml(preset=args.preset))
    solve_dissertation("de", seed=100, budget=100, popsize=50, problem=prob)  # warm-up
    out: dict[str, Any] = {"preset": args.preset, "loadavg_before": os.getloadavg(), "runs": []}
    for method, budget, seeds in (("de", short, args.seeds), ("cmaes", short, args.seeds),
                                  ("de", long, args.long_seeds),
                                  ("cmaes", long, args.long_seeds)):
        for seed in range(seeds):
            r = solve_dissertation(method, seed=seed, budget=budget, problem=prob)
            row = {**r.to_dict(), "budget": budget}
            if budget == long:  # the long runs' cost history thinned to every 10th generation
                for k in ("history_episodes", "history_best_cost"):
                    row[k] = row[k][::10] + row[k][-1:]
            out["runs"].append(row)
            print(f"{method:6s} {budget:6d} seed {seed}: {r.final_position_m * 1e3:.3f} mm "
                  f"({r.outcome}) in {r.travel_time_s * 1e3:.1f} ms, {r.wall_time_s:.2f} s",
                  file=sys.stderr, flush=True)
    out["summary"] = [{"method": m, "budget": b, **_summary(
        [r for r in out["runs"] if r["method"] == m and r["budget"] == b], prob.target_m)}
        for m, b in (("de", short), ("cmaes", short), ("de", long), ("cmaes", long))]
    out["table_4_3"] = {"dissertation": TABLE_4_3,
                        "this_model": evaluate_parameters(TABLE_4_3, prob)}

    def progress(row: dict[str, Any]) -> None:
        print(f"{row['variant'][:60]:60s} DE median {row['de_median_final_position_m'] * 1e3:.3f}"
              f" mm, {row['de_median_travel_time_s'] * 1e3:.1f} ms, goal {row['de_goal_hits']}/"
              f"{len(row['de_seeds'])}", file=sys.stderr, flush=True)

    for budget in (short, long):
        t0 = time.perf_counter()
        out[f"explain_{budget}"] = explain(prob, seeds=range(args.explain_seeds), budget=budget,
                                           progress=progress)
        print(f"explain at {budget}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    out["loadavg_after"] = os.getloadavg()
    out_path.write_text(json.dumps(out, indent=1))
    runs0 = {f"{m} seed 0": next((r["history_episodes"], r["history_best_cost"])
                                 for r in out["runs"]
                                 if r["method"] == m and r["seed"] == 0 and r["budget"] == short)
             for m in ("de", "cmaes")}
    plot_cost_history(runs0, str(fig / f"dissertation_{args.preset}_cost_history.png"))
    de = sorted((r for r in out["runs"] if r["method"] == "de" and r["budget"] == short),
                key=lambda r: r["final_position_m"])
    med = de[len(de) // 2]
    far = min((r for r in out["runs"] if r["budget"] == long), key=lambda r: r["cost"])

    def label(p: dict[str, float], what: str) -> str:
        return (f"{what} ({p['frequency_hz']:.0f} Hz, {p['spacing_m'] * 1e6:.0f} µm, "
                f"{p['delay_s'] * 1e3:.2f} ms, {p['stroke_m'] * 1e6:.0f} µm)")

    plot_plan_trajectories(
        {label(med["parameters"], f"DE median seed ({med['seed']}), {short:,} ep."):
         trajectory(med["parameters"], prob),
         label(far["parameters"], f"best of {long:,} ep. ({far['method']} seed {far['seed']})"):
         trajectory(far["parameters"], prob),
         label(TABLE_4_3, "Table 4.3"): trajectory(TABLE_4_3, prob)},
        str(fig / f"dissertation_{args.preset}_trajectory.png"), prob.target_m,
        title=f"The dissertation's problem on preset {args.preset}")
    print(json.dumps(out["summary"], indent=1))


if __name__ == "__main__":
    main()
