"""Aggregate over training seeds: IQM (interquartile mean, as rliable defines it: the 25 %
trimmed mean, ``scipy.stats.trim_mean``) and its percentile-bootstrap 95 % CI over runs
(``scipy.stats.bootstrap``) of the final evaluations (``metadata.json`` of each run folder).

rliable's stratified bootstrap resamples the runs of each task separately; the runs here share
one task (the fixed target set), so it is the bootstrap over runs. rliable itself cannot be
imported next to pandas 3 (its dependency ``arch`` calls pandas' ``deprecate_kwarg`` with the
old signature), so the same statistics come from scipy.
"""
from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.stats import bootstrap, trim_mean

KEYS = ("success_rate_50um", "success_rate_100um", "success_rate_250um", "median_abs_error_m")


def iqm(x: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean: the 25 % trimmed mean (``scipy.stats.trim_mean``)."""
    return float(trim_mean(np.asarray(x, float), 0.25))


def iqm_interval(values: Sequence[float] | np.ndarray, reps: int = 2000, seed: int = 0) -> dict:
    """:func:`iqm` of per-seed scores and its 95 % percentile-bootstrap interval over the seeds
    (``scipy.stats.bootstrap``, ``reps`` resamples drawn with ``seed``), as rliable computes it
    for one task: ``per_seed``, ``iqm``, ``ci95`` (one seed, or equal scores: the value itself;
    no seed: NaN)."""
    v = np.asarray(values, float)
    out = {"per_seed": v.tolist(), "iqm": iqm(v) if v.size else math.nan,
           "ci95": [math.nan, math.nan]}
    if v.size > 1 and np.ptp(v) > 0:
        ci = bootstrap((v,), lambda x, axis=-1: trim_mean(x, 0.25, axis=axis),
                       n_resamples=reps, method="percentile",
                       rng=np.random.default_rng(seed)).confidence_interval
        out["ci95"] = [float(ci.low), float(ci.high)]
    elif v.size:
        out["ci95"] = [float(v[0]), float(v[0])]
    return out


# what must agree between runs for their seeds to be aggregated (the seed itself may differ)
SAME = ("env_id", "env_kwargs", "algo", "hyperparams")


def check_same_config(metas: Sequence[dict], runs: Sequence[str | Path]) -> None:
    """ValueError naming the runs and keys whose env or training config differ from the first
    run's: averaging seeds of different configs would mean nothing."""
    from ..training.hyperparams import changed_keys

    first = metas[0]
    for run, meta in zip(runs[1:], metas[1:], strict=True):
        diff = changed_keys({k: first.get(k) for k in SAME}, {k: meta.get(k) for k in SAME})
        if "hyperparams" in diff and first.get("hyperparams") and meta.get("hyperparams"):
            diff.remove("hyperparams")
            diff += [f"hyperparams.{k}"
                     for k in changed_keys(first["hyperparams"], meta["hyperparams"])]
        if diff:
            raise ValueError(f"runs of different configs cannot be aggregated over seeds: "
                             f"{str(run)!r} differs from {str(runs[0])!r} in {', '.join(diff)}")


def aggregate(runs: Sequence[str | Path], reps: int = 2000, seed: int = 0) -> dict:
    """IQM and 95 % bootstrap CI of the final evaluations of ``runs`` (run folders of one
    config; refused otherwise, :func:`check_same_config`)."""
    metas = [json.loads((Path(r) / "metadata.json").read_text()) for r in runs]
    check_same_config(metas, runs)
    evs = [m["evaluation"] for m in metas]
    out: dict = {"runs": [str(r) for r in runs]}
    for key in KEYS:
        out[key] = iqm_interval([ev[key] for ev in evs], reps, seed)
    return out


def curves(runs: Sequence[str | Path]) -> dict:
    """Learning curves of each run: its ``evaluations.jsonl`` (steps, success within
    +-50/100/250 um, median error) as lists."""
    out = {}
    for r in runs:
        path = Path(r) / "evaluations.jsonl"
        if not path.is_file():
            raise FileNotFoundError(f"{str(path)!r} not found: a run folder of `microconveyor "
                                    "train` holds it")
        rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
        out[str(r)] = {k: [row[k] for row in rows] for k in ("steps", "wall_time_s", *KEYS)}
    return out
