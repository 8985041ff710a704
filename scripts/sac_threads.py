"""Plain stable-baselines3 SAC on ``MicroConveyor-v1`` with torch's default threads and with
``torch.set_num_threads(1)``: steps per second of the same training, both settings alternated in
one run so they share the machine's state (compare them as a ratio)::

    nice python scripts/sac_threads.py [--steps 3000] [--repeats 2] [--out docs/figures/sac_threads.json]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import gymnasium as gym
import torch
from stable_baselines3 import SAC

import microconveyor_env  # noqa: F401  (registers the ids)


def one(steps: int, threads: int) -> float:
    torch.set_num_threads(threads)
    env = gym.make("MicroConveyor-v1")
    model = SAC("MlpPolicy", env, learning_starts=100, seed=0, device="cpu")
    t0 = time.perf_counter()
    model.learn(steps)
    return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/sac_threads.json"))
    args = ap.parse_args()
    default = torch.get_num_threads()
    rates: dict[str, list[float]] = {f"default ({default} threads)": [], "1 thread": []}
    for _ in range(args.repeats):
        rates[f"default ({default} threads)"].append(one(args.steps, default))
        rates["1 thread"].append(one(args.steps, 1))
    best = {k: max(v) for k, v in rates.items()}
    out = {"env_id": "MicroConveyor-v1", "algo": "SAC (stable-baselines3, MlpPolicy, defaults)",
           "steps": args.steps, "steps_per_s": rates,
           "speedup_1_thread": best["1 thread"] / best[f"default ({default} threads)"],
           "provenance": {"machine": f"{platform.machine()}, {os.cpu_count()} cores",
                          "torch": torch.__version__,
                          "recorded_utc": datetime.datetime.now(datetime.UTC)
                          .isoformat(timespec="seconds"),
                          "command": f"nice python scripts/sac_threads.py --steps {args.steps} "
                                     f"--repeats {args.repeats}"}}
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
