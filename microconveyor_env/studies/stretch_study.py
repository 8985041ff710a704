"""Stretch-dependent roughness in the dynamics (dissertation ch. 5): travel against frequency with
constant and with stretched roughness, and what the stretched level costs.

With ``roughness="stretch"`` the simulator looks up Q(N) and the pull-off force at the roughness
of the stretched active zone under the part (docs/physics.md §4; :mod:`..physics.stretch`). The study
fires the seed scene over a frequency grid at both levels; per row the outcome, the travel, the
peak zone strain of the stroke and the wall time of the ``simulate`` call (median of repeats).
"""
from __future__ import annotations

from typing import Any

import math
import statistics
import time
from collections.abc import Iterable

import numpy as np

from ..physics.contact_table import TableRangeError
from ..physics.schedule import Schedule
from .engine import run_tasks, simulator
from .sweep import feasible_window

LEVELS = ("constant", "stretch")


def run_freq(task: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of one frequency [Hz] at both roughness levels."""
    rows: list[dict[str, Any]] = []
    for level in task["levels"]:
        kw = dict(task.get("sim_kw", {}))
        if level != "constant":
            kw["roughness"] = level
        else:
            kw.pop("n_sigma", None)  # a stretch-table setting
        sim = simulator(task.get("preset", "feasibility"), wavelength=task["wavelength_m"],
                        profile=task["profile"], **kw)
        sched = Schedule.single(task["freq_hz"], task["stroke_m"])
        row = {"freq_hz": task["freq_hz"], "stroke_m": task["stroke_m"], "x0_m": task["x0_m"],
               "profile": task["profile"], "wavelength_m": task["wavelength_m"],
               "roughness": level}
        try:
            r = sim.simulate(sched, x0=task["x0_m"])
        except TableRangeError:
            rows.append({**row, "outcome": "load_beyond_table", "displacement_m": math.nan,
                         "peak_strain": math.nan, "wall_time_s": math.nan})
            continue
        walls: list[float] = []
        for _ in range(int(task.get("repeats", 3))):
            t0 = time.perf_counter()
            sim.simulate(sched, x0=task["x0_m"])
            walls.append(time.perf_counter() - t0)
        peak = sim.peak_strain(task["stroke_m"]) if level == "stretch" else 0.0
        rows.append({**row, "outcome": r.outcome, "displacement_m": r.displacement_m,
                     "peak_strain": peak, "steps": r.steps,
                     "wall_time_s": statistics.median(walls) if walls else r.wall_time_s})
    return rows


def stretch_rows(freqs: Iterable[float] = tuple(np.arange(200.0, 1500.0 + 1e-9, 25.0).tolist()),
                 stroke: float = 200e-6, x0: float = 0.125e-3, profile: str = "gaussian",
                 wavelength: float = 0.6e-3, repeats: int = 3, preset: str = "feasibility",
                 sim_kw: dict[str, Any] | None = None,
                 **engine_kw: Any) -> list[dict[str, Any]]:
    """Both levels over ``freqs`` [Hz] for the single-firing scene (stroke [m], start x0 [m],
    ``wavelength`` [m], ``repeats`` [-] timed runs)."""
    tasks = [{"freq_hz": float(f), "stroke_m": float(stroke), "x0_m": float(x0),
              "profile": profile, "wavelength_m": float(wavelength), "levels": LEVELS,
              "repeats": repeats, "preset": preset, "sim_kw": sim_kw or {}} for f in freqs]
    engine_kw.setdefault("desc", "stretch")
    return run_tasks(run_freq, tasks, **engine_kw)


def compare(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Windows, travel differences (where both rest) and the cost ratio of the two levels."""
    out: dict[str, Any] = {}
    by = {lv: sorted((r for r in rows if r["roughness"] == lv), key=lambda r: r["freq_hz"])
          for lv in LEVELS}
    for lv, rs in by.items():
        f = [r["freq_hz"] for r in rs]
        d = [r["displacement_m"] for r in rs]
        o = [r["outcome"] for r in rs]
        ok = [r for r in rs if r["outcome"] == "rest"]
        best = max(ok, key=lambda r: abs(r["displacement_m"])) if ok else None
        out[lv] = {"window_hz": feasible_window(f, d, o),
                   "first_detachment_hz": next((r["freq_hz"] for r in rs
                                                if r["outcome"] == "detached"), None),
                   "max_travel_m": abs(best["displacement_m"]) if best else None,
                   "max_travel_at_hz": best["freq_hz"] if best else None,
                   "median_wall_time_s": statistics.median(
                       [r["wall_time_s"] for r in rs if not math.isnan(r["wall_time_s"])])}
    pairs = [(a, b) for a, b in zip(by["constant"], by["stretch"], strict=True)
             if a["outcome"] == b["outcome"] == "rest" and abs(a["displacement_m"]) >= 10e-6]
    rel = [abs(b["displacement_m"]) / abs(a["displacement_m"]) - 1.0 for a, b in pairs]
    out["both_rest_runs"] = len(pairs)
    out["travel_change_rel"] = ({"median": statistics.median(rel), "min": min(rel),
                                 "max": max(rel)} if rel else None)
    out["outcome_differs_hz"] = [a["freq_hz"] for a, b in zip(by["constant"], by["stretch"], strict=True)
                                 if a["outcome"] != b["outcome"]]
    out["cost_ratio"] = out["stretch"]["median_wall_time_s"] / out["constant"]["median_wall_time_s"]
    return out
