"""Variance-based global sensitivity (Sobol' indices, SALib) of the single-firing travel.

Beyond the dissertation's linear fit: the factors vary *continuously* over the Table 3.2 ranges
(:data:`PROBLEM`), mass log-uniformly, and frequency as its relative position ``freq_pos`` in
[0, 1] on a log scale inside the sample's own feasible window (``f = lo (hi/lo)^freq_pos``; the
window is located as in :mod:`.sensitivity`). The output is the distance travelled [m]; a scene with
no feasible window (no frequency moves the part 10 um without detaching) counts as 0.

Saltelli/Sobol' sampling (``N (2D + 2)`` runs with second-order indices), first-order ``S1``,
total ``ST`` and second-order ``S2`` indices with bootstrap 95 % confidence intervals. ``ST - S1``
is the share of variance a factor explains only through interactions; ``S2`` names the pairs.
"""
from __future__ import annotations

from typing import Any

import math
from collections.abc import Iterable

import numpy as np

from .engine import run_tasks, simulator
from .sensitivity import SCAN_HZ, fire, find_window

PROBLEM: dict[str, Any] = {
    "num_vars": 7,
    "names": ["dgamma_J_m2", "sigma_m", "stroke_m", "log10_mass_kg", "wavelength_m", "x0_wl",
              "freq_pos"],
    "bounds": [[0.5, 2.0], [20e-9, 40e-9], [100e-6, 250e-6],
               [math.log10(2e-11), math.log10(2e-9)], [0.6e-3, 1.2e-3], [0.2, 0.33], [0.0, 1.0]],
}
SOBOL_SCAN_HZ = SCAN_HZ[::2]  # a coarser scan (edges are refined by bisection anyway)


def samples(n_base: int = 128, seed: int = 0) -> np.ndarray:
    """Saltelli/Sobol' sample matrix, ``n_base * (2 D + 2)`` rows (n_base [-] a power of 2), columns
    in :data:`PROBLEM`'s order and units."""
    from SALib.sample import sobol as sobol_sample

    if n_base < 2 or n_base & (n_base - 1):
        raise ValueError(f"n_base = {n_base} is invalid: must be a power of 2 (>= 2)")
    return sobol_sample.sample(PROBLEM, n_base, calc_second_order=True, scramble=True, seed=seed)


def run_sample(task: dict[str, Any]) -> list[dict[str, Any]]:
    """One row: the sample's parameters, its window [Hz], the firing frequency and the travel."""
    p = {k: task[k] for k in PROBLEM["names"]}
    mass = 10.0 ** p["log10_mass_kg"]
    sim = simulator(task.get("preset", "feasibility"), mass=mass, sigma=p["sigma_m"],
                    dgamma=p["dgamma_J_m2"], wavelength=p["wavelength_m"])
    x0 = p["x0_wl"] * p["wavelength_m"]
    window, runs = find_window(sim, p["stroke_m"], x0, task.get("scan_hz", SOBOL_SCAN_HZ))
    row = {"sample": task["sample"], **p, "mass_kg": mass, "x0_m": x0}
    if window is None:
        return [{**row, "window_lo_hz": math.nan, "window_hi_hz": math.nan, "freq_hz": math.nan,
                 "outcome": "no_window", "distance_m": 0.0, "runs": len(runs)}]
    lo, hi = window
    f = lo * (hi / lo) ** p["freq_pos"]
    res = fire(sim, f, p["stroke_m"], x0)
    d = res["distance_m"] if res["outcome"] == "rest" else 0.0
    return [{**row, "window_lo_hz": lo, "window_hi_hz": hi, "freq_hz": f,
             "outcome": res["outcome"], "distance_m": d, "runs": len(runs) + 1}]


def sobol_rows(n_base: int = 128, seed: int = 0, preset: str = "feasibility",
               scan_hz: Iterable[float] = SOBOL_SCAN_HZ,
               **engine_kw: Any) -> list[dict[str, Any]]:
    """One row per sample of :func:`samples` (``n_base`` [-]), windows scanned over ``scan_hz``
    [Hz]; ``engine_kw`` go to :func:`.engine.run_tasks`."""
    X = samples(n_base, seed)
    tasks = [{"sample": i, **dict(zip(PROBLEM["names"], map(float, x), strict=True)), "preset": preset,
              "scan_hz": tuple(scan_hz)} for i, x in enumerate(X)]
    engine_kw.setdefault("desc", "sobol")
    return run_tasks(run_sample, tasks, **engine_kw)


LOG_FLOOR_M = 1e-6  # log10(distance + 1 um): the log-scale output (no window -> -6)


def _analyze(Y: np.ndarray, seed: int, conf_level: float) -> dict[str, Any]:
    from SALib.analyze import sobol as sobol_analyze

    Si = sobol_analyze.analyze(PROBLEM, Y, calc_second_order=True, conf_level=conf_level,
                               seed=seed, print_to_console=False)
    names = PROBLEM["names"]
    per: list[dict[str, Any]] = []
    for i, name in enumerate(names):
        per.append({"name": name, "S1": float(Si["S1"][i]), "S1_conf": float(Si["S1_conf"][i]),
                    "ST": float(Si["ST"][i]), "ST_conf": float(Si["ST_conf"][i]),
                    "interaction": float(Si["ST"][i] - Si["S1"][i])})
    pairs: list[dict[str, Any]] = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            s2, c2 = float(Si["S2"][i, j]), float(Si["S2_conf"][i, j])
            pairs.append({"pair": [names[i], names[j]], "S2": s2, "S2_conf": c2,
                          "significant": s2 - c2 > 0.0})
    pairs.sort(key=lambda p: -p["S2"])
    interacting = [p["name"] for p in per
                   if p["interaction"] > max(p["ST_conf"], p["S1_conf"], 0.02)]
    return {"indices": per, "pairs": pairs, "interacting": interacting,
            "sum_S1": float(sum(p["S1"] for p in per))}


def indices(rows: list[dict[str, Any]], seed: int = 0, conf_level: float = 0.95) -> dict[str, Any]:
    """S1, ST (with confidence half-widths), S2 pairs, and the interaction shares ``ST - S1``, of
    the distance [m]; the same of ``log10(distance + 1 um)`` under ``log10_distance`` (on the log
    scale multiplicative effects become additive, so what remains in ``ST - S1`` there is a
    genuine, non-multiplicative interaction)."""
    rows = sorted(rows, key=lambda r: r["sample"])
    Y = np.array([r["distance_m"] for r in rows])
    names = PROBLEM["names"]
    out: dict[str, Any] = {"n_runs": len(rows), "n_base": len(rows) // (2 * len(names) + 2),
           "conf_level": conf_level, "output": "distance travelled [m] (0 without a window)",
           "mean_distance_m": float(Y.mean()), "std_distance_m": float(Y.std()),
           "no_window_fraction": float(np.mean([r["outcome"] == "no_window" for r in rows])),
           **_analyze(Y, seed, conf_level)}
    out["log10_distance"] = {"output": "log10(distance [m] + 1e-6)",
                             **_analyze(np.log10(Y + LOG_FLOOR_M), seed, conf_level)}
    return out
