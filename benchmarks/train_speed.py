"""PPO training throughput (env steps per second) with `configs/ppo.yml`, split into rollout
collection and gradient updates, with the updates on 1 or 2 torch threads and the networks'
activation as the recipe has it or replaced, idle and with the cores busy.

    python benchmarks/train_speed.py [--env MicroConveyor-v1] [--steps 204800] [--threads 1,2]
                                     [--activations recipe,ReLU] [--loads idle,busy]

"Busy" runs one spinning process per core beside the training (as `env_speed.py` does). Each
setting trains from scratch into a temporary folder (no evaluations, no checkpoints); the
settings alternate within one run so they share the machine's state: compare them as ratios.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import tempfile
import time
from typing import Any

import torch
from stable_baselines3 import PPO

from agents.rl.training import hyperparams
from agents.rl.training import train as T
from agents.rl.training.settings import TrainSettings
from agents.rl.training.algos import algo_class

# the classes whose methods are timed (patched and restored around each training)
BudgetPPO: Any = algo_class("ppo")
SB3PPO: Any = PPO


def _spin(stop) -> None:
    x = 0
    while not stop.is_set():
        x += 1


def one(steps: int, update_threads: int, env_id: str, activation: str = "recipe") -> dict:
    acc = {"collect": 0.0, "update": 0.0}
    collect, update = SB3PPO.collect_rollouts, BudgetPPO.train

    def timed_collect(self, *a, **k):
        t = time.perf_counter()
        try:
            return collect(self, *a, **k)
        finally:
            acc["collect"] += time.perf_counter() - t

    def timed_update(self):
        t = time.perf_counter()
        try:
            return update(self)
        finally:
            acc["update"] += time.perf_counter() - t

    SB3PPO.collect_rollouts, BudgetPPO.train = timed_collect, timed_update
    BudgetPPO.update_threads = update_threads
    try:
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            meta = T.train(out, TrainSettings(
                steps=steps, eval_targets=0, eval_freq=0, checkpoint_freq=10**12,
                progress_bar=False, tensorboard=False, env_id=env_id,
                overrides=_activation(env_id, activation)))
            wall = time.perf_counter() - t0
    finally:
        SB3PPO.collect_rollouts, BudgetPPO.train = collect, update
        BudgetPPO.update_threads = 1
    n = meta["steps"]
    return {"steps_per_s": n / wall, "collect_s": acc["collect"], "update_s": acc["update"],
            "wall_s": wall, "steps": n}


def _activation(env_id: str, activation: str) -> dict:
    """Recipe overrides that replace the networks' activation (``recipe``: none)."""
    if activation == "recipe":
        return {}
    kwargs = hyperparams.load(None, env_id, "ppo")["policy_kwargs"]
    return {"policy_kwargs": {**kwargs, "activation_fn": getattr(torch.nn, activation)}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=204_800)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--env", default=hyperparams.ENV_ID)
    ap.add_argument("--activations", default="recipe",
                    help="comma-separated: recipe (as configs/ppo.yml has it) or a torch.nn "
                         f"class name ({', '.join(hyperparams.ACTIVATIONS)})")
    ap.add_argument("--loads", default="idle,busy")
    args = ap.parse_args()
    threads = [int(t) for t in args.threads.split(",")]
    acts = args.activations.split(",")
    for a in acts:
        if a != "recipe" and a not in hyperparams.ACTIVATIONS:
            ap.error(f"--activations: {a!r} is not recipe or one of "
                     f"{', '.join(hyperparams.ACTIVATIONS)}")
    one(4096, 1, args.env)  # warm-up: numba and torch caches
    print(f"{args.env}, {args.steps:,} steps per setting")
    print(f"{'load':6} {'activation':>10} {'update threads':>14} {'steps/s':>9} {'collect s':>10} "
          f"{'update s':>9}")
    for load in args.loads.split(","):
        stop = mp.Event()
        spinners = [mp.Process(target=_spin, args=(stop,)) for _ in range(
            os.cpu_count() or 1)] if load == "busy" else []
        for p in spinners:
            p.start()
        try:
            for k in threads:
                for a in acts:
                    r = one(args.steps, k, args.env, a)
                    print(f"{load:6} {a:>10} {k:>14} {r['steps_per_s']:>9,.0f} "
                          f"{r['collect_s']:>10.1f} {r['update_s']:>9.1f}", flush=True)
        finally:
            stop.set()
            for p in spinners:
                p.join()


if __name__ == "__main__":
    main()
