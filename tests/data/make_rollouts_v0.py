"""Record seeded MicroConveyor-v0 rollouts (single and batched env) as JSON.

``tests/data/rollouts_v0.json`` is written by this script, run from the repository root as

    python tests/data/make_rollouts_v0.py

and its ``meta`` block records the package version, the contact-table format and hash, the
machine and the date. History: first recorded with the env as it was before the randomisation
options existed (commit 7497eb3); re-recorded for issue 17 once the contact table became
bit-identical on every CPU (table format 4: before it, the BLAS kernel moved 2-13 rows by
1-248 ULP, so the data could only be replayed on the machine that wrote it).

``tests/test_env_randomisation.py`` replays the stored actions with today's env (randomisation
off) and requires every observation, reward, flag and info value to be bit-identical. Floats are
stored with ``repr`` (exact round trip); observations are float32 values widened to float64.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).with_name("rollouts_v0.json")
# (name, EnvConfig overrides, reset seed, number of steps, action seed)
SINGLE = (("default", {}, 3, 20, 0),
          ("jitter_3_actuators", {"start_jitter": 30e-6, "n_actuators": 3}, 11, 20, 1),
          ("karnopp_exact", {"mode": "karnopp", "kinematics": "exact", "n_actuators": 4}, 5, 12,
           2))
BATCHED = (("default_next_step", {}, 4, 3, 14, 3),)  # (name, kw, seed, num_envs, steps, a-seed)
INFO_KEYS = ("position_error_m", "outcome", "sim_time_s", "frequency_hz", "stroke_m", "delay_s",
             "is_success")


def _py(v):
    if isinstance(v, np.ndarray):
        return [_py(x) for x in v.tolist()]
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    return v


def actions_for(seed: int, shape: tuple) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.2, 1.2, shape).astype(np.float32)


def record_single(kw: dict, seed: int, acts: np.ndarray) -> list:
    from microconveyor_env.envs import MicroConveyorEnv

    env = MicroConveyorEnv(**kw)
    obs, _ = env.reset(seed=seed)
    rows: list = [{"reset_obs": _py(obs.astype(np.float64))}]
    for a in acts:
        obs, r, te, tr, info = env.step(a)
        rows.append({"obs": _py(obs.astype(np.float64)), "reward": float(r), "terminated": te,
                     "truncated": tr, **{k: _py(info[k]) for k in INFO_KEYS}})
        if te or tr:
            obs, _ = env.reset()
            rows.append({"reset_obs": _py(obs.astype(np.float64))})
    return rows


def record_batched(kw: dict, seed: int, n: int, acts: np.ndarray) -> list:
    from microconveyor_env.envs import MicroConveyorVectorEnv

    env = MicroConveyorVectorEnv(n, num_threads=1, **kw)
    obs, _ = env.reset(seed=seed)
    rows: list = [{"reset_obs": _py(obs.astype(np.float64))}]
    for a in acts:
        obs, r, te, tr, info = env.step(a)
        rows.append({"obs": _py(obs.astype(np.float64)), "reward": _py(r),
                     "terminated": _py(te), "truncated": _py(tr),
                     **{k: _py(info[k]) for k in INFO_KEYS}})
    return rows


def provenance() -> dict:
    """How the data was produced: package version, table format and hash, machine, date."""
    import datetime
    import platform

    import microconveyor_env
    from microconveyor_env.physics import contact_table

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from support.fingerprint_child import table_hash

    return {"package_version": microconveyor_env.__version__,
            "table_format": contact_table.TABLE_FORMAT, "table_sha256": table_hash(),
            "numpy": np.__version__, "machine": platform.machine(),
            "processor": platform.processor() or platform.machine(),
            "recorded_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "command": "python tests/data/make_rollouts_v0.py"}


def record() -> dict:
    out: dict = {"meta": provenance(), "single": {}, "batched": {}}
    for name, kw, seed, steps, aseed in SINGLE:
        acts = actions_for(aseed, (steps, 3))
        out["single"][name] = {"config": kw, "seed": seed, "actions": _py(acts.astype(np.float64)),
                               "rows": record_single(kw, seed, acts)}
    for name, kw, seed, n, steps, aseed in BATCHED:
        acts = actions_for(aseed, (steps, n, 3))
        out["batched"][name] = {"config": kw, "seed": seed, "num_envs": n,
                                "actions": _py(acts.astype(np.float64)),
                                "rows": record_batched(kw, seed, n, acts)}
    return out


if __name__ == "__main__":
    import microconveyor_env

    print("recording with", microconveyor_env.__file__, file=sys.stderr)
    OUT.write_text(json.dumps(record(), indent=0) + "\n")
    print("wrote", OUT, file=sys.stderr)
