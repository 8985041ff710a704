"""How much of MicroConveyor-v1's target range can ANY controller hold under execution noise?

A controller that knows the part's state exactly before its last firing, and the model exactly,
still fires that last firing with noise, and the part then coasts to rest with nothing left to
correct it. For each target: the best nominal plan (DE, 5,000 episodes, best of 3 seeds) is played
until the firing after which the part comes to rest (the *launch*); from the exact state before
it, the launch's three action numbers are searched for the firing that holds best under noise σ
(a 25 × 25 × 9 grid scan and DE refinements from the four best cells and from the nominal launch,
each candidate scored over 16 noisy copies with common random numbers, the robust cost of
agents.planning.robust_cost); the best is measured on 500 fresh noisy launches. The success found
is what a controller with perfect state and model gets from that state (a better earlier firing
could set up an easier launch, so it bounds the launch, not every strategy).

    python scripts/launch_noise_bound.py --sigma 3e-3 --targets 2,4,6,8,10 --out docs/figures/launch_noise_bound_v1.json
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from agents.openloop.search import de_minimize
from agents.openloop.target import solve_target
from agents.planning import LineRollouts, robust_cost
from microconveyor_env.envs import MicroConveyorEnv, env_config

COPIES, REPLAYS = 16, 500
# the searches' sizes: the nominal plan's DE budget, the grid's points per axis (frequency and
# stroke; delay), each refinement's DE budget, the fresh noisy launches measured; --quick: a
# check that the script runs (its numbers mean nothing)
SIZES = {"plan_budget": 5000, "grid": 25, "grid_delay": 9, "refine_budget": 1500,
         "replays": REPLAYS}
QUICK = {"plan_budget": 60, "grid": 3, "grid_delay": 2, "refine_budget": 60, "replays": 8}


def launch_bound(target: float, sigma: float, cfg, roll: LineRollouts,
                 sizes: dict[str, int] = SIZES) -> dict:
    t0 = time.perf_counter()
    tol = cfg.tolerance
    best = min((solve_target(target, "de", sizes["plan_budget"], sd, rollouts=roll)
                for sd in range(3)), key=lambda r: r.abs_error_m)
    env = MicroConveyorEnv(config=cfg)
    env.reset(seed=0, options={"target": target})
    for k in range(cfg.n_actuators):
        state = env.get_state()
        _, _, term, trunc, _ = env.step(best.plan[k].astype(np.float32))
        if term or trunc:
            break
    rem = cfg.n_actuators - state.fired
    z_fit = np.random.default_rng(0).standard_normal((COPIES, 3))
    z_test = np.random.default_rng(1).standard_normal((sizes["replays"], 3))

    def play(X: np.ndarray, Z: np.ndarray):
        Xn = np.clip(X[:, None, :] + sigma * Z[None], -1, 1).reshape(-1, 3)
        P = np.zeros((Xn.shape[0], rem, 3))
        P[:, 0] = Xn
        P[:, 1:] = best.plan[k + 1:]  # later firings as planned (rarely reached)
        return roll.run(P, target, start=state)

    def cost(X: np.ndarray) -> np.ndarray:
        r = play(X, z_fit)
        return robust_cost(r.abs_error_m, r.rest, tol, miss=1e-3).reshape(-1, COPIES).mean(1)

    g = np.linspace(-1, 1, sizes["grid"])
    grid = np.array(np.meshgrid(g, g, np.linspace(-1, 1, sizes["grid_delay"]),
                                indexing="ij")).reshape(3, -1).T
    c = np.concatenate([cost(grid[i:i + 2000]) for i in range(0, len(grid), 2000)])
    starts = [best.plan[k]] + [grid[i] for i in np.argsort(c)[:4]]
    found = []
    for j, x0 in enumerate(starts):
        res = de_minimize(cost, [(-1, 1)] * 3, sizes["refine_budget"], j, popsize=30,
                          x0=np.asarray(x0, float))
        r = play(res.x[None], z_test)
        found.append((float(r.success.mean()), float(np.median(r.abs_error_m)), res.x.tolist()))
    nominal = play(best.plan[k][None], z_test)
    top = max(found)
    return {"target_m": target, "sigma": sigma, "launch_firing": int(state.fired + 1),
            "nominal_plan_error_m": best.error_m,
            "nominal_launch_success": float(nominal.success.mean()),
            "nominal_launch_median_abs_error_m": float(np.median(nominal.abs_error_m)),
            "robust_launch_success": top[0], "robust_launch_median_abs_error_m": top[1],
            "robust_launch_action": top[2], "wall_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma", type=float, default=3e-3, help="execution noise [action units]")
    ap.add_argument("--targets", default="2,4,6,8,10", help="targets [mm], comma list")
    ap.add_argument("--out", default=None, help="JSON file")
    ap.add_argument("--quick", action="store_true",
                    help=f"tiny searches, to check that the script runs: {QUICK}")
    args = ap.parse_args()
    sizes = QUICK if args.quick else SIZES
    cfg = env_config("MicroConveyor-v1")
    roll = LineRollouts(cfg)
    rows = []
    for t in (float(v) * 1e-3 for v in args.targets.split(",")):
        row = launch_bound(t, args.sigma, cfg, roll, sizes)
        rows.append(row)
        print(f"{t * 1e3:g} mm (launched by firing {row['launch_firing']}): nominal launch "
              f"{100 * row['nominal_launch_success']:.0f} %, robust launch "
              f"{100 * row['robust_launch_success']:.0f} % within ±50 µm (median "
              f"{1e6 * row['robust_launch_median_abs_error_m']:.0f} µm) under σ = {args.sigma:g}",
              flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"env_id": "MicroConveyor-v1", "copies": COPIES, "replays": sizes["replays"],
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
