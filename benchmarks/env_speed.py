"""Environment throughput, idle and under load (a benchmark script, not a test).

    python benchmarks/env_speed.py [--seconds 3] [--num-envs 64] [--no-load] [--randomise]

Prints JSON with two columns, ``idle`` and ``loaded`` (as many busy processes as cores, as when
PPO, an evaluation or a browser share the machine): gymnasium's ``benchmark_step`` on the single
env (random actions, resets included) and the batched env's firings per second with N parts for
``num_threads`` = 1 (serial), all cores (numba parallel) and ``None`` (the automatic choice),
and the parallel/serial ratio of the firings per second (the batched env's parallel efficiency
times the cores).
NEXT_STEP autoreset steps fire nothing and are not counted. ``--randomise`` turns the per-episode
randomisation on (``RANDOMISE``: action noise, friction and mass factors). Timings are noisy:
compare within one run.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import time
from typing import Any

import gymnasium as gym
import numba
import numpy as np
from gymnasium.utils.performance import benchmark_step

import microconveyor_env  # noqa: F401  (registers MicroConveyor-v0)

NUMBA_THREADS: int = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]

RANDOMISE: dict[str, Any] = {"action_noise": 0.05, "friction_factor_range": (0.8, 1.2),
             "mass_factor_range": (0.8, 1.2)}


def batched_firings_per_s(num_envs: int, seconds: float, num_threads, seed: int = 0,
                          **kw) -> dict:
    venv: Any = gym.make_vec("MicroConveyor-v0", num_envs=num_envs, num_threads=num_threads, **kw)
    venv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(3):  # warm-up (kernel load; the automatic mode tries both choices)
        venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))
    firings = steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        resetting = venv.done.copy()
        venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))
        firings += int((~resetting).sum())
        steps += 1
    wall = time.perf_counter() - t0
    return {"firings_per_s": round(firings / wall), "vector_steps_per_s": round(steps / wall),
            "threads_in_use": venv.threads.current}


def _busy(stop) -> None:
    while not stop.is_set():
        pass


def measure(num_envs: int, seconds: float, **kw) -> dict:
    env = gym.make("MicroConveyor-v0", **kw).unwrapped
    # gymnasium annotates target_duration [s] as an int; it takes any number of seconds
    benchmark_step(env, target_duration=0.5, seed=0)  # type: ignore[arg-type]  # warm-up
    out: dict[str, Any] = {"single_env_steps_per_s": round(benchmark_step(
        env, target_duration=seconds, seed=0))}  # type: ignore[arg-type]
    for label, nt in (("serial", 1), ("parallel", NUMBA_THREADS),
                      ("auto", None)):
        out[f"batched_{label}"] = batched_firings_per_s(num_envs, seconds, nt, **kw)
    out["parallel_over_serial"] = round(out["batched_parallel"]["firings_per_s"]
                                        / out["batched_serial"]["firings_per_s"], 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--num-envs", type=int, default=64)
    ap.add_argument("--no-load", action="store_true", help="only the idle column")
    ap.add_argument("--randomise", action="store_true",
                    help=f"per-episode randomisation on: {RANDOMISE}")
    args = ap.parse_args()
    kw = RANDOMISE if args.randomise else {}
    result: dict[str, Any] = {"num_envs": args.num_envs, "cores": os.cpu_count(),
              "numba_threads": NUMBA_THREADS, "randomise": kw,
              "idle": measure(args.num_envs, args.seconds, **kw)}
    if not args.no_load:
        stop = mp.Event()
        procs = [mp.Process(target=_busy, args=(stop,), daemon=True)
                 for _ in range(os.cpu_count() or 1)]
        for p in procs:
            p.start()
        try:
            result["loaded"] = measure(args.num_envs, args.seconds, **kw)
        finally:
            stop.set()
            for p in procs:
                p.join(5)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
