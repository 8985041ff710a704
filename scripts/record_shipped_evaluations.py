"""Re-record the shipped policies' evaluations: summaries in each ``metadata.json``, every
episode in ``episodes.json`` beside it, with how they were produced.

Run from the repository root after a change that moves the dynamics (the tests compare a fresh
evaluation with these records within tolerances derived in tests/test_shipped_policies.py)::

    python scripts/record_shipped_evaluations.py

Also records the sha256 of ``model.zip`` and ``normalization.json`` in the metadata (the loader
refuses a folder whose files do not match) and the folder format.
"""
from __future__ import annotations

import datetime
import json
import platform
import sys

import numpy as np

from agents.rl.checkpoint import MODEL, NORMALIZATION, sha256
from agents.rl.policy_files import policy_scene
from agents.rl.evaluate import fixed_targets, load_policy, rollout, summarize
from agents.rl.shipped import shipped_path

# folder -> {evaluation key: which env config ("nominal" or "trained": the run's env_kwargs)}
EVALUATIONS = {"ppo": {"evaluation": "nominal", "evaluation_fresh": "nominal"},
               "ppo_randomised": {"evaluation": "trained", "evaluation_nominal": "nominal"}}
EPISODES = "episodes.json"


def provenance() -> dict:
    import stable_baselines3
    import torch

    import microconveyor_env

    return {"package_version": microconveyor_env.__version__, "torch": torch.__version__,
            "stable_baselines3": stable_baselines3.__version__, "numpy": np.__version__,
            "machine": platform.machine(), "python": platform.python_version(),
            "recorded_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(
                timespec="seconds"),
            "command": "python scripts/record_shipped_evaluations.py"}


def record(name: str) -> None:
    folder = shipped_path(name)
    meta_path = folder / "metadata.json"
    meta = json.loads(meta_path.read_text())
    meta.pop("files", None)                      # re-hashed below
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    pol = load_policy(folder)
    episodes = {}
    for key, which in EVALUATIONS[name].items():
        old = meta[key]
        # "trained": the scene and randomisation it was trained under; "nominal": randomisation off
        cfg = policy_scene(meta) if which == "trained" else pol.config
        targets = fixed_targets(cfg, old["n_targets"], old["seed"])
        res = rollout(pol, targets, cfg, seed=old["seed"])
        summary = summarize(res, cfg.tolerance)
        summary.update(seed=old["seed"], target_range_m=list(cfg.target_range), config=which)
        meta[key] = {**{k: v for k, v in old.items() if k in ("steps", "wall_time_s")}, **summary}
        episodes[key] = {"config": which, "seed": old["seed"],
                         "target_m": res["targets_m"].tolist(), "error_m": res["error_m"].tolist(),
                         "outcome": res["outcome"].tolist(), "firings": res["firings"].tolist()}
        print(f"{name} {key}: success {summary['success_rate_50um']:.3f}, median "
              f"{summary['median_abs_error_m'] * 1e6:.4f} um", file=sys.stderr)
    meta["format"] = 2
    meta["evaluation_provenance"] = provenance()
    meta["files"] = {n: sha256(folder / n) for n in (MODEL, NORMALIZATION)}
    (folder / EPISODES).write_text(json.dumps(episodes, indent=0) + "\n")
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")


if __name__ == "__main__":
    for n in (sys.argv[1:] or list(EVALUATIONS)):
        record(n)
