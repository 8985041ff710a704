"""The cost of a step of each scene, against MicroConveyor-v1's, in one run (a benchmark script,
not a test).

    python benchmarks/scene_step_cost.py [--envs MicroPositioner-v0 ...] [--rounds 3] [--seconds 2]

For each round and each env id (MicroConveyor-v1 first, then the others, alternating so drift in
the machine's load falls on all of them): gymnasium's ``benchmark_step`` on the single env
(random actions in the box, resets included) and the batched env's steps per second with
``--num-envs`` parts on the serial loop (``num_threads = 1``: the loop trainings use), with the
per-episode randomisation of the positioner's PPO recipe (σ = 3e-3, friction and mass factors in
[0.95, 1.05]). Prints JSON: per env the median over rounds of each figure, and its cost per step
relative to MicroConveyor-v1's (> 1: dearer). A step is one firing in every scene; the
positioner's also runs the part to rest. Timings are noisy: say what else was running.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils.performance import benchmark_step

import microconveyor_env  # noqa: F401  (registers the ids)

BASE = "MicroConveyor-v1"
PERTURBED: dict[str, Any] = {"action_noise": 3e-3, "friction_factor_range": (0.95, 1.05),
             "mass_factor_range": (0.95, 1.05)}


def single_steps_per_s(env_id: str, seconds: float) -> float:
    env = gym.make(env_id, **PERTURBED).unwrapped
    # gymnasium annotates target_duration [s] as an int; it takes any number of seconds
    benchmark_step(env, target_duration=0.3, seed=0)  # type: ignore[arg-type]  # warm-up
    return float(benchmark_step(env, target_duration=seconds, seed=0))  # type: ignore[arg-type]


def batched_steps_per_s(env_id: str, num_envs: int, seconds: float) -> float:
    venv: Any = gym.make_vec(env_id, num_envs=num_envs, num_threads=1, **PERTURBED)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(3):
        venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))
    fired = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        resetting = venv.done.copy()
        venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))
        fired += int((~resetting).sum())
    return fired / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", nargs="+", default=["MicroPositioner-v0"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--num-envs", type=int, default=64)
    args = ap.parse_args()
    ids = [BASE, *args.envs]
    runs: dict[str, dict[str, list[float]]] = {i: {"single": [], "batched": []} for i in ids}
    for _ in range(args.rounds):
        for env_id in ids:
            runs[env_id]["single"].append(single_steps_per_s(env_id, args.seconds))
            runs[env_id]["batched"].append(batched_steps_per_s(env_id, args.num_envs,
                                                               args.seconds))
    med = {i: {k: statistics.median(v) for k, v in r.items()} for i, r in runs.items()}
    out = {"cpu_count": os.cpu_count(), "load_average": os.getloadavg(),
           "rounds": args.rounds, "seconds": args.seconds, "num_envs": args.num_envs,
           "randomisation": {k: list(v) if isinstance(v, tuple) else v
                             for k, v in PERTURBED.items()},
           "envs": {i: {"single_env_steps_per_s": round(med[i]["single"]),
                        "batched_serial_steps_per_s": round(med[i]["batched"]),
                        "single_steps_per_s_rounds": [round(x) for x in runs[i]["single"]],
                        "batched_steps_per_s_rounds": [round(x) for x in runs[i]["batched"]],
                        "single_cost_vs_v1": round(med[BASE]["single"] / med[i]["single"], 3),
                        "batched_cost_vs_v1": round(med[BASE]["batched"] / med[i]["batched"],
                                                    3)}
                     for i in ids}}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
