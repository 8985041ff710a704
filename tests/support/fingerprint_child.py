"""Child process of tests/test_portable_math.py: prints the sha256 of the dissertation preset's
contact table (built, never read from a cache) and of a short seeded env rollout, one JSON line.
Run under different BLAS core types and numpy CPU-feature settings, the hashes must not change."""
import hashlib
import json

import numpy as np

from microconveyor_env.physics.contact_table import build_base_table
from microconveyor_env.presets import load_preset


def table_hash() -> str:
    base = build_base_table(load_preset("feasibility").contact)
    h = hashlib.sha256()
    for key, value in base.arrays().items():
        if key != "build_seconds":
            h.update(key.encode() + np.ascontiguousarray(value, dtype=float).tobytes())
    return h.hexdigest()


def rollout_hash() -> str:
    from microconveyor_env.envs import MicroConveyorEnv

    env = MicroConveyorEnv()
    obs, _ = env.reset(seed=3)
    h = hashlib.sha256(obs.tobytes())
    for a in np.random.default_rng(0).uniform(-1, 1, (6, 3)).astype(np.float32):
        obs, r, term, trunc, info = env.step(a)
        h.update(obs.tobytes() + np.float64(r).tobytes() + np.float64(info["sim_time_s"]).tobytes())
        if term or trunc:
            obs, _ = env.reset()
    return h.hexdigest()


if __name__ == "__main__":
    print(json.dumps({"table": table_hash(), "rollout": rollout_hash()}))
