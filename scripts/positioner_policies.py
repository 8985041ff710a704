"""Evaluate MicroPositioner-v0 policies trained with several seeds (one folder each) on held-out
targets, at the training perturbation level and nominally; per seed and their IQM with a 95 %
bootstrap interval over seeds.

    python scripts/positioner_policies.py runs/dagger-s0 runs/dagger-s1 runs/dagger-s2 \\
        [--targets 1000] [--seed 1] [--out docs/figures/positioner_seeds.json]

Per policy and condition (``perturbed``: action noise σ = 3e-3 and friction and mass factors in
[0.95, 1.05], the level the policies are meant to hold; ``nominal``: no randomisation): the
share of targets at rest within ±50 µm and within ±10 µm, the median absolute error [m], the
detachment rate, the mean firings, over ``--targets`` targets uniform over 0.5–10 mm drawn with
``--seed`` (1: not the set training monitors, 12345), episode ``i`` seeded ``seed + i``. Also
each policy's training wall time and steps from its metadata. JSON in SI units.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from datetime import datetime, UTC
from pathlib import Path



from agents.experiments.perturb import Level
from agents.rl.evaluation.evaluate import figures, fixed_targets, load_policy, rollout
from microconveyor_env.envs import PlaneEnvConfig
from agents.rl.evaluation.seeds import iqm_interval

GOAL = Level(action_noise=3e-3, spread=0.05)
METRICS = ("success_rate_50um", "success_rate_10um", "median_abs_error_m", "detach_rate",
           "mean_firings")


def run_figures(res: dict) -> dict:
    """The :data:`METRICS` of one rollout (:func:`~agents.rl.evaluation.evaluate.figures`,
    the 10 µm share as its success within 10 µm)."""
    f = figures(res, 50e-6)
    return {**{m: f[m] for m in METRICS if m != "success_rate_10um"},
            "success_rate_10um": figures(res, 10e-6)["success_rate"]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policies", nargs="+")
    p.add_argument("--targets", type=int, default=1000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", default=None)
    args = p.parse_args()
    t0 = time.perf_counter()
    runs = []
    for path in args.policies:
        pol = load_policy(path)
        cfg = pol.config   # the trained scene, randomisation off
        if cfg is None or isinstance(cfg, PlaneEnvConfig):
            raise SystemExit(f"{path}: not a policy of MicroPositioner-v0")
        targets = fixed_targets(cfg, args.targets, args.seed)
        run = {"policy": path, "seed": pol.metadata.get("seed"),
               "trained_by": pol.metadata.get("trained_by", pol.metadata.get("algo")),
               "train_wall_time_s": pol.metadata.get("wall_time_s"),
               "train_steps": pol.metadata.get("steps")}
        for name, c in (("perturbed", GOAL.config(cfg)), ("nominal", cfg)):
            run[name] = run_figures(rollout(pol, targets, c, seed=args.seed))
            print(f"{path} {name}: {run[name]['success_rate_50um']:.1%} within ±50 µm, "
                  f"{run[name]['success_rate_10um']:.1%} within ±10 µm, median "
                  f"{run[name]['median_abs_error_m'] * 1e6:.1f} µm, detached "
                  f"{run[name]['detach_rate']:.1%}", file=sys.stderr)
        runs.append(run)
    out = {"env_id": "MicroPositioner-v0", "n_targets": args.targets, "target_seed": args.seed,
           "perturbation": {"action_noise": GOAL.action_noise, "spread": GOAL.spread},
           "runs": runs,
           "iqm": {c: {m: iqm_interval([r[c][m] for r in runs]) for m in METRICS}
                   for c in ("perturbed", "nominal")},
           "machine": {"cpu_count": os.cpu_count(), "processor": platform.machine(),
                       "load_average": os.getloadavg()},
           "date": datetime.now(UTC).strftime("%Y-%m-%d"),
           "command": "python scripts/positioner_policies.py " + " ".join(sys.argv[1:]),
           "wall_time_s": time.perf_counter() - t0}
    text = json.dumps(out, indent=1)
    if args.out:
        Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
