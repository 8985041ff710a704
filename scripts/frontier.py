"""Placement time against precision for one scene (docs/figures/frontier_<scene>.json and .png):
every controller of the scene on the same held-out targets, nominal and under execution noise
σ = 3e-3 with friction and mass within ±5 %, at the requests 50, 20, 10 and 5 µm (the env's
tolerance), each row the shares within ±50/20/10/5 µm and the median and p90 placement time
(agents/experiments/frontier.py).

    python scripts/frontier.py --env MicroConveyor-v1 --out docs/figures/frontier_line.json --plot docs/figures/frontier_line.png [--targets N] [--slow-targets N] [--methods NAME ...]
    python scripts/frontier.py --plot-only --out docs/figures/frontier_line.json --plot docs/figures/frontier_line.png

The JSON is written after every row, so a run that stops keeps what it finished; run again with
``--resume`` to add only the rows it lacks (``--redo METHOD ...``: and those of these methods
again). ``--plot-only`` redraws the chart from the JSON.
Progress goes to stderr; the markdown table of the rows to stdout.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.frontier import (LEVELS, REQUESTS, TARGET_SEED, frontier_rows,
                                         frontier_table, methods_for)
from agents.plots.frontier import plot_frontier

KEY = ("env_id", "level", "method", "request_tolerance_m")


def time_bound(env_id: str) -> float | None:
    """The physical lower bound on the placement time of the held-out targets' median [s], where
    the scene has one (agents/planning/bounds.py, MicroConveyor-v1)."""
    if env_id != "MicroConveyor-v1":
        return None
    try:
        from agents.planning.bounds import line_time_bound_s
    except ImportError:
        return None
    from agents.rl.evaluation.evaluate import fixed_targets
    from microconveyor_env.envs.core.versions import scene_config

    cfg = scene_config(env_id)
    median = float(np.median(fixed_targets(cfg, 500, seed=TARGET_SEED)))
    return float(np.asarray(line_time_bound_s(cfg, np.array([median]))).reshape(-1)[0])


def write(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="MicroConveyor-v1", help="registered env id")
    ap.add_argument("--targets", type=int, default=None,
                    help="targets of a policy's or fast controller's row (default 500)")
    ap.add_argument("--slow-targets", type=int, default=None,
                    help="targets of an MPC or DE row (default: the method's, 20 to 100)")
    ap.add_argument("--methods", nargs="+", default=None, help="only these methods")
    ap.add_argument("--levels", nargs="+", default=list(LEVELS), choices=list(LEVELS))
    ap.add_argument("--requests-um", nargs="+", type=float, default=[1e6 * r for r in REQUESTS],
                    help="the requests (env tolerances) [µm]")
    ap.add_argument("--out", required=True, help="the JSON of the rows")
    ap.add_argument("--plot", default=None, help="the chart (PNG)")
    ap.add_argument("--resume", action="store_true", help="keep the JSON's rows, add the rest")
    ap.add_argument("--redo", nargs="+", default=[], metavar="METHOD",
                    help="with --resume: run these methods' rows again (the others kept)")
    ap.add_argument("--plot-only", action="store_true", help="redraw the chart from the JSON")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.plot_only:
        stored = json.loads(out.read_text())
        if a.plot:
            plot_frontier(stored, a.plot)
        print(frontier_table(stored), end="")
        return 0
    data: dict[str, Any] = {"env_id": a.env, "target_seed": TARGET_SEED,
                            "levels": {k: {"action_noise": v.action_noise, "spread": v.spread}
                                       for k, v in LEVELS.items() if k in a.levels},
                            "time_bound_s": time_bound(a.env), "rows": []}
    if a.resume and out.is_file():
        data["rows"] = [r for r in json.loads(out.read_text()).get("rows", [])
                        if r["method"] not in a.redo]
    have = {tuple(r[k] for k in KEY) for r in data["rows"]}
    methods = methods_for(a.env, a.methods)
    print(f"{a.env}: methods {[m.name for m in methods]}", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    for row in frontier_rows(a.env, methods, a.targets, a.slow_targets, tuple(a.levels),
                             requests=tuple(r / 1e6 for r in a.requests_um),
                             done=lambda k: tuple(k[c] for c in KEY) in have):
        data["rows"].append(row)
        write(out, data)
        t = row["median_placement_time_s"]
        print(f"[{time.perf_counter() - t0:6.0f} s] {row['level']:9s} {row['method']:22s} "
              f"request {1e6 * row['request_tolerance_m']:4g} µm, n {row['n_targets']}: "
              f"±50/20/10/5 µm {100 * row['success_rate_50um']:.0f}/"
              f"{100 * row['success_rate_20um']:.0f}/{100 * row['success_rate_10um']:.0f}/"
              f"{100 * row['success_rate_5um']:.0f} %, median time "
              f"{'–' if t is None else f'{1e3 * t:.1f} ms'}, "
              f"{row['wall_s_per_target']:.3g} s per target", file=sys.stderr, flush=True)
    write(out, data)
    if a.plot:
        plot_frontier(data, a.plot)
    print(frontier_table(data), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
