"""Environment throughput (a benchmark script, not a test; timings are noisy, compare in one run).

    python benchmarks/env_speed.py [--seconds 5] [--num-envs 64]

Prints JSON: gymnasium's ``benchmark_step`` on the single env (random actions, resets included)
and the batched env's firings per second with N parts (NEXT_STEP autoreset steps, which fire
nothing, are not counted as firings).
"""
from __future__ import annotations

import argparse
import json
import time

import gymnasium as gym
import numpy as np
from gymnasium.utils.performance import benchmark_step

import microconveyor_env  # noqa: F401  (registers MicroConveyor-v0)


def batched_firings_per_s(num_envs: int, seconds: float, seed: int = 0) -> dict:
    venv = gym.make_vec("MicroConveyor-v0", num_envs=num_envs)
    venv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))  # warm-up
    firings = steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        resetting = venv.done.copy()
        venv.step(rng.uniform(-1, 1, (num_envs, 3)).astype(np.float32))
        firings += int((~resetting).sum())
        steps += 1
    wall = time.perf_counter() - t0
    return {"num_envs": num_envs, "vector_steps": steps, "firings": firings,
            "firings_per_s": firings / wall, "vector_steps_per_s": steps / wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--num-envs", type=int, default=64)
    args = ap.parse_args()
    env = gym.make("MicroConveyor-v0").unwrapped
    benchmark_step(env, target_duration=0.5, seed=0)  # warm-up (kernel load)
    single = benchmark_step(env, target_duration=args.seconds, seed=0)
    print(json.dumps({"single_env_steps_per_s": single,
                      "batched": batched_firings_per_s(args.num_envs, args.seconds)}, indent=2))


if __name__ == "__main__":
    main()
