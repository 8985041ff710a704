"""Aggregate over training seeds with rliable: IQM and a stratified-bootstrap 95 % CI of the
final evaluations (``metadata.json`` of each run folder)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

KEYS = ("success_rate_50um", "success_rate_100um", "success_rate_250um")


def aggregate(runs, reps: int = 2000, seed: int = 0) -> dict:
    from rliable import library as rly, metrics

    evs = [json.loads((Path(r) / "metadata.json").read_text())["evaluation"] for r in runs]
    out = {"runs": [str(r) for r in runs]}
    np.random.seed(seed)  # rliable's bootstrap draws from numpy's global generator
    for key in KEYS:
        scores = {key: np.array([[ev[key]] for ev in evs])}  # (runs, 1 task)
        point, ci = rly.get_interval_estimates(
            scores, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps)
        out[key] = {"per_seed": [ev[key] for ev in evs], "iqm": float(point[key][0]),
                    "ci95": [float(ci[key][0][0]), float(ci[key][1][0])]}
    med = [ev["median_abs_error_m"] for ev in evs]
    out["median_abs_error_m"] = {"per_seed": med, "median": float(np.median(med))}
    return out
