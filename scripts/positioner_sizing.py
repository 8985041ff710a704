"""How MicroPositioner-v0's actuator spacing was chosen: the one-step model-based controller on
100 targets over 0.5–10 mm at several spacings (the array always spanning 0–10.5 mm), nominally
and at σ = 3e-3 with friction and mass factors in [0.95, 1.05], with a model that knows each
episode's factors and with the nominal model.

    python scripts/positioner_sizing.py [--spacings 0.2,0.25,0.3,0.4,0.5] [--targets 100] \\
        [--out docs/figures/positioner_sizing.json]

The controller (:class:`agents.mpc.experts.BatchExpert`) fires, before every firing,
the gentlest candidate whose predicted rest is nearest the target, with a margin from
detachment, at most ``max_firings`` (24) times. A part comes to rest where no actuator reaches
it when the spacing leaves gaps. JSON in SI units: per spacing and case, the share within
±50 µm, the median error, the mean firings and why episodes ended.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import sys
import time
from datetime import datetime, UTC
from pathlib import Path

import numpy as np


from agents.mpc.experts import BatchExpert
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv

SPAN = 10.5e-3   # m: the array covers 0 to this
CASES = {"nominal": (0.0, 0.0, False), "perturbed, model knows the factors": (3e-3, 0.05, True),
         "perturbed, nominal model": (3e-3, 0.05, False)}


def run(spacing: float, sigma: float, spread: float, knows: bool, targets: np.ndarray,
        seed: int) -> dict:
    n = int(round(SPAN / spacing)) + 1
    cfg = PositionerConfig.from_yaml(None, spacing=spacing, n_actuators=n, num_threads=1,
                                     action_noise=sigma,
                                     friction_factor_range=(1 - spread, 1 + spread),
                                     mass_factor_range=(1 - spread, 1 + spread))
    venv = MicroPositionerVectorEnv(len(targets), config=cfg)
    expert = BatchExpert(cfg)
    venv.reset(seed=seed, options={"target": targets})
    m = len(targets)
    done = np.zeros(m, bool)
    err, out, fired = np.zeros(m), np.empty(m, object), np.zeros(m, int)
    factors = np.stack([venv.friction_factor, venv.mass_factor], 1).copy() if knows else None
    while not done.all():
        a, ok = expert.act(venv.x.copy(), venv.t.copy(), venv.target.copy(), factors)
        a[~ok] = [1.0, -1.0, -1.0]   # nothing gets closer: the weakest firing, far away
        live = ~done
        _, _, term, trunc, info = venv.step(a)
        fired += live
        end = live & (term | trunc)
        err[end], out[end] = info["position_error_m"][end], info["outcome"][end]
        done |= end
    hit = (out == "rest") & (np.abs(err) <= cfg.tolerance)
    why = collections.Counter("within tolerance" if h else ("firings spent" if o == "rest" else o)
                              for h, o in zip(hit, out, strict=True))
    return {"spacing_m": spacing, "n_actuators": n, "action_noise": sigma, "spread": spread,
            "model_knows_factors": knows, "success_rate": float(hit.mean()),
            "median_abs_error_m": float(np.median(np.abs(err))),
            "mean_firings": float(fired.mean()), "ends": dict(why)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spacings", default="0.2,0.25,0.3,0.4,0.5", help="mm, comma-separated")
    p.add_argument("--targets", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=None)
    args = p.parse_args()
    t0 = time.perf_counter()
    targets = np.random.default_rng(args.seed).uniform(0.5e-3, 10e-3, args.targets)
    rows = []
    for mm in args.spacings.split(","):
        for case, (sigma, spread, knows) in CASES.items():
            row = {"case": case, **run(float(mm) * 1e-3, sigma, spread, knows, targets,
                                       args.seed)}
            rows.append(row)
            print(f"{float(mm):.2f} mm, {case}: {row['success_rate']:.0%} within ±50 µm, median "
                  f"{row['median_abs_error_m'] * 1e6:.1f} µm, {row['mean_firings']:.1f} firings, "
                  f"{row['ends']}", file=sys.stderr)
    out = {"targets": args.targets, "target_seed": args.seed, "span_m": SPAN, "rows": rows,
           "machine": {"cpu_count": os.cpu_count(), "load_average": os.getloadavg()},
           "date": datetime.now(UTC).strftime("%Y-%m-%d"),
           "command": "python scripts/positioner_sizing.py " + " ".join(sys.argv[1:]),
           "wall_time_s": time.perf_counter() - t0}
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
