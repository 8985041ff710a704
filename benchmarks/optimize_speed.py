"""Wall time of the open-loop optimisers (a benchmark script, not a test).

    python benchmarks/optimize_speed.py [--repeats 3] [--busy 0]

Times, after a warm-up run (kernel load, contact tables): the dissertation's DE (population 50,
50 generations: 2,550 episodes) and CMA-ES with the same budget, and the per-target search over
the env's 15 actions (2,000 episodes, target 2 mm) with DE and CMA-ES. Prints JSON: per case
the episodes and the wall times of each repeat (min and median), with the machine's load
average before and after (``os.getloadavg``). ``--busy N`` runs N busy-looping processes
meanwhile (as when PPO or a browser share the cores). Timings are noisy: compare within one run.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numba

NUMBA_THREADS: int = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]


def _busy(stop: Any) -> None:
    while not stop.is_set():
        pass


def cases() -> dict[str, Callable[[int], Any]]:
    from agents.openloop.dissertation import solve_dissertation
    from agents.openloop.target import solve_target
    from agents.planning import LineRollouts

    roll = LineRollouts()
    return {
        "dissertation_de_2550": lambda s: solve_dissertation("de", seed=s),
        "dissertation_cmaes_2550": lambda s: solve_dissertation("cmaes", seed=s),
        "target_2mm_de_2000": lambda s: solve_target(2e-3, "de", 2000, seed=s, rollouts=roll),
        "target_2mm_cmaes_2000": lambda s: solve_target(2e-3, "cmaes", 2000, seed=s,
                                                       rollouts=roll),
    }


def measure(repeats: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, fn in cases().items():
        fn(100)  # warm-up
        walls, episodes = [], []
        for seed in range(repeats):
            t0 = time.perf_counter()
            res = fn(seed)
            walls.append(round(time.perf_counter() - t0, 3))
            episodes.append(res.episodes)
        out[name] = {"episodes": episodes, "wall_s": walls, "min_s": min(walls),
                     "median_s": statistics.median(walls)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--busy", type=int, default=0, help="busy-looping processes meanwhile")
    args = ap.parse_args()
    stop = mp.Event()
    procs = [mp.Process(target=_busy, args=(stop,), daemon=True) for _ in range(args.busy)]
    for p in procs:
        p.start()
    load_before = os.getloadavg()
    try:
        result = measure(args.repeats)
    finally:
        stop.set()
        for p in procs:
            p.join(5)
    print(json.dumps({"cores": os.cpu_count(), "numba_threads": NUMBA_THREADS,
                      "busy_processes": args.busy, "loadavg_before": load_before,
                      "loadavg_after": os.getloadavg(), "cases": result}, indent=2))


if __name__ == "__main__":
    main()
