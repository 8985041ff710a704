"""Model-predictive control per target, before and after the fast planners, on the same targets
and episodes: MicroConveyor-v1 (MPC seeded by the shipped ``ppo_refined``: DE over the remaining
firings, 300 episodes before the first firing and 100 per re-plan, the answer table's; and the
minimum-norm Gauss-Newton re-plan) and MicroPositioner-v0 (the one-step controller with the
friction identified online, its candidates fired on the full model or ranked on the firing map).

Each method is timed in a subprocess, alternating with the others, on one thread. With
``--compare-with DIR`` (a ``git worktree`` of an earlier revision) the methods that revision has
run from it too, in the same run, so the ratio says what the change did::

    nice python scripts/planner_speed.py [--noise-seeds 3] [--per-distance 5] [--positioner-targets 100] [--compare-with /tmp/old] [--out docs/figures/planner_speed.json]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

V1_DISTANCES_M = (1e-3, 3e-3, 5e-3, 7e-3, 9e-3)
PERTURBED = {"action_noise": 3e-3, "friction_factor_range": (0.95, 1.05),
             "mass_factor_range": (0.95, 1.05)}
METHODS = ("v1_mpc_de", "v1_mpc_newton", "positioner_model", "positioner_map")


def _episodes(method: str, noise_seeds: int, per_distance: int,
              positioner_targets: int) -> dict:
    """One method's episodes (run in a worker process): per level, every episode's |error| [m],
    success, outcome, wall time [s] and model episodes."""
    import dataclasses

    import torch

    torch.set_num_threads(1)
    from agents.mpc import MPC, MPCSettings, OneStepSettings
    from agents.rl.artefacts.shipped import require_shipped
    from agents.rl.evaluation.evaluate import distance_targets, fixed_targets, load_policy
    from microconveyor_env.envs.core.versions import nominal, scene_config

    settings: MPCSettings | OneStepSettings
    if method.startswith("v1"):
        cfg = scene_config("MicroConveyor-v1")
        targets = distance_targets(cfg, V1_DISTANCES_M, per_distance).reshape(-1)
        prior = load_policy(require_shipped("MicroConveyor-v1", "ppo_refined"), cfg)
        try:
            settings = (MPCSettings(first_budget=300, replan_budget=100)
                        if method == "v1_mpc_de"
                        else MPCSettings(method="newton", first_budget=70, replan_budget=70))
        except ValueError:           # a revision without the newton re-plan
            return {"missing": True}
        levels = {"nominal": (cfg, 1),
                  "noise": (dataclasses.replace(cfg, action_noise=3e-3), noise_seeds)}
    else:
        cfg = scene_config("MicroPositioner-v0")
        targets = fixed_targets(cfg, positioner_targets, 0)
        prior = None
        search = "model" if method == "positioner_model" else "map"
        try:
            settings = OneStepSettings(model="identified", search=search)
        except TypeError:            # a revision without the map: it searches the model
            if search == "map":
                return {"missing": True}
            settings = OneStepSettings(model="identified")
        levels = {"nominal": (cfg, 1),
                  "perturbed": (scene_config("MicroPositioner-v0", **PERTURBED), 1)}
    from agents.planning import scene_of

    ctl = MPC(nominal(cfg), settings, prior)
    out: dict = {}
    for level, (real, repeats) in levels.items():
        env = scene_of(real).env()
        ctl.run(env, float(targets[0]), 999_999)            # compiled and loaded first
        eps = [ctl.run(env, float(t), 1000 * r + i, search_seed=1000 * i)
               for r in range(repeats) for i, t in enumerate(targets)]
        out[level] = {"target_m": [e.target_m for e in eps],
                      "abs_error_m": [abs(e.error_m) for e in eps],
                      "success": [bool(e.success) for e in eps],
                      "outcome": [e.outcome for e in eps],
                      "wall_time_s": [e.wall_time_s for e in eps],
                      "model_episodes": [int(e.episodes) for e in eps],
                      "sim_time_s": [e.time_s for e in eps]}
    return out


def _summary(level: dict) -> dict:
    err = np.asarray(level["abs_error_m"])
    wall = np.asarray(level["wall_time_s"])
    return {"episodes": len(err), "success_rate": float(np.mean(level["success"])),
            "median_abs_error_m": float(np.median(err)),
            "detach_rate": float(np.mean([o == "detached" for o in level["outcome"]])),
            "wall_s_per_target_mean": float(wall.mean()),
            "wall_s_per_target_median": float(np.median(wall)),
            "model_episodes_mean": float(np.mean(level["model_episodes"]))}


def _run(code: Path, method: str, args: argparse.Namespace) -> dict:
    env = {**os.environ, "PYTHONPATH": str(code), "OMP_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", method,
           "--noise-seeds", str(args.noise_seeds), "--per-distance", str(args.per_distance),
           "--positioner-targets", str(args.positioner_targets)]
    r = subprocess.run(cmd, cwd=code, env=env, capture_output=True, text=True, check=False)
    if r.returncode != 0:
        raise SystemExit(f"{method} at {code} failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--noise-seeds", type=int, default=3)
    ap.add_argument("--per-distance", type=int, default=5,
                    help="MicroConveyor-v1 targets per distance (1, 3, 5, 7, 9 mm)")
    ap.add_argument("--positioner-targets", type=int, default=100)
    ap.add_argument("--compare-with", type=Path, default=None,
                    help="a checkout of an earlier revision, run in the same session")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/planner_speed.json"))
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(_episodes(args.worker, args.noise_seeds, args.per_distance,
                                   args.positioner_targets)))
        return
    here = Path(__file__).resolve().parents[1]
    codes = {"new": here} | ({"old": args.compare_with.resolve()} if args.compare_with else {})
    results: dict = {}
    loads = [os.getloadavg()]
    t0 = time.perf_counter()
    for method in METHODS:
        for name, code in codes.items():
            res = _run(code, method, args)
            loads.append(os.getloadavg())
            if res.get("missing"):
                continue
            results[f"{name}/{method}"] = {lvl: {**_summary(v), "episodes_detail": v}
                                           for lvl, v in res.items()}
            line = "; ".join(f"{lvl}: {s['success_rate']:.0%} success, median "
                             f"{s['median_abs_error_m'] * 1e6:.1f} µm, "
                             f"{s['wall_s_per_target_mean'] * 1e3:.1f} ms per target"
                             for lvl, s in results[f"{name}/{method}"].items())
            print(f"{name}/{method}: {line}", flush=True)

    def rev(path: Path) -> str:
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=path,
                           capture_output=True, text=True, check=False)
        return r.stdout.strip()

    out = {"date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
           "machine": {"processor": platform.processor(), "cpu_count": os.cpu_count()},
           "revisions": {k: rev(v) for k, v in codes.items()},
           "load_average_1_5_15": loads, "wall_time_s": time.perf_counter() - t0,
           "noise_seeds": args.noise_seeds, "positioner_targets": args.positioner_targets,
           "v1_distances_m": list(V1_DISTANCES_M), "v1_targets_per_distance": args.per_distance,
           "positioner_perturbation": {k: list(v) if isinstance(v, tuple) else v
                                       for k, v in PERTURBED.items()},
           "command": "python scripts/planner_speed.py " + " ".join(sys.argv[1:]),
           "methods": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
