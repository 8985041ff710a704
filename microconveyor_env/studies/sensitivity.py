"""Sensitivity of the single-firing travel to the scene (the dissertation's Table 3.2 design).

The design crosses the Table 3.2 levels (:data:`LEVELS`): surface energy, roughness, stroke, part
mass, wavelength and start position (a fraction of the wavelength, beside the actuator at x = 0).
For every combination the feasible frequency window is located (a log scan over :data:`SCAN_HZ`,
both edges refined by bisection in log f), then the part is fired on a log grid of frequencies over
that window. Each (surface energy, roughness) pair has its own contact table (built once, cached on
disk); the dissertation preset's fitted beta and friction scale are kept.

The rows (one per simulation, scan and edge runs included, ``phase`` says which) go to
:mod:`.regression` (Box--Cox + OLS, the dissertation's eq. 3-48 and Table 3.4).
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..physics.contact_table import TableRangeError
from ..physics.schedule import Schedule
from ..physics.simulator import Simulator
from .engine import run_tasks, simulator
from .sweep import MIN_TRAVEL_M

# Table 3.2 levels (SI units)
LEVELS = {
    "dgamma_J_m2": (0.5, 1.0, 2.0),
    "sigma_m": (20e-9, 30e-9, 40e-9),
    "stroke_m": (100e-6, 150e-6, 200e-6, 250e-6),
    "mass_kg": (2e-11, 2e-9),
    "wavelength_m": (0.6e-3, 1.2e-3),
    "x0_wl": (0.2, 0.25, 0.33),
}
# window scan [Hz]: 100 Hz to 10 kHz (the dissertation's optimisation range ends at 10 kHz);
# a window still open at 10 kHz is reported as capped there (``window_capped``)
SCAN_HZ = tuple(float(f) for f in np.geomspace(100.0, 10000.0, 41))
REFINE_STEPS = 5        # bisections in log f per window edge (edge known to ~1 % of f)
N_FREQ = 8              # design frequencies per combination (log grid over the window)


def fire(sim: Simulator, freq: float, stroke: float, x0: float, v0: float = 0.0) -> dict[str, Any]:
    """One firing of the actuator at x = 0 (``freq`` [Hz], ``stroke`` [m], start ``x0`` [m] at ``v0``
    [m/s]): outcome, displacement [m], distance [m], detachment time [s].

    A stroke whose load would leave the contact table counts as ``load_beyond_table`` (such
    strokes lie far above the detachment onset)."""
    try:
        r = sim.simulate(Schedule.single(freq, stroke), x0=x0, v0=v0)
    except TableRangeError:
        return {"outcome": "load_beyond_table", "displacement_m": math.nan,
                "distance_m": math.nan, "detach_time_s": math.nan}
    d = r.displacement_m
    return {"outcome": r.outcome, "displacement_m": d, "distance_m": abs(d),
            "detach_time_s": r.detach_time_s if r.detach_time_s is not None else math.nan}


def _fails(res: dict[str, Any]) -> bool:
    return res["outcome"] in ("detached", "load_beyond_table")


def _moves(res: dict[str, Any]) -> bool:
    return not _fails(res) and res["distance_m"] >= MIN_TRAVEL_M


def find_window(sim: Simulator, stroke: float, x0: float, scan: Iterable[float] = SCAN_HZ,
                refine: int = REFINE_STEPS,
                ) -> tuple[list[float] | None, list[tuple[str, float, dict[str, Any]]]]:
    """Feasible window [lo, hi] [Hz] (None if empty) for strokes of ``stroke`` [m] from ``x0`` [m],
    scanning ``scan`` [Hz] and refining each edge by ``refine`` [-] bisections, and the runs made
    to find it.

    ``lo``: lowest frequency with >= 10 um travel; ``hi``: highest frequency below the first
    detachment. Returns ``(window, runs)`` with ``runs`` a list of ``(phase, freq, result)``.
    """
    runs: list[tuple[str, float, dict[str, Any]]] = []
    prev: tuple[float, dict[str, Any]] | None = None  # (freq, result) of the previous scan point
    lo: float | None = None
    hi: float | None = None
    lo_below: float | None = None
    stop: float | None = None
    for f in scan:
        res = fire(sim, f, stroke, x0)
        runs.append(("scan", f, res))
        if _fails(res):
            stop = f
            break
        if lo is None and _moves(res):
            lo, lo_below = f, (prev[0] if prev else None)
        if lo is not None:
            hi = f
        prev = (f, res)
    if lo is None:
        return None, runs
    assert hi is not None  # set together with lo

    def probe(m: float) -> dict[str, Any]:
        res = fire(sim, m, stroke, x0)
        runs.append(("edge", m, res))
        return res

    if lo_below is not None:  # the lower edge, between lo_below (stays) and lo (moves)
        lo = _bisect_log(lo_below, lo, refine, lambda m: _edge_below(probe(m)))[1]
    if stop is not None:  # the upper edge, between hi (attached) and stop (fails)
        hi = _bisect_log(hi, stop, refine, lambda m: _fails(probe(m)))[0]
    return [lo, hi], runs


def _edge_below(res: dict[str, Any]) -> bool | None:
    """Lower-edge probe: the part moves (the edge is below), stays (above), or fails (stop)."""
    return True if _moves(res) else None if _fails(res) else False


def _bisect_log(a: float, b: float, steps: int, edge_below: Callable[[float], bool | None],
                ) -> tuple[float, float]:
    """``steps`` bisections of [a, b] [Hz] in log f: ``edge_below(m)`` True moves b to m, False
    moves a to m, None stops. Returns the final (a, b)."""
    for _ in range(steps):
        m = math.sqrt(a * b)
        side = edge_below(m)
        if side is None:
            break
        a, b = (a, m) if side else (m, b)
    return a, b


def design(levels: Mapping[str, Sequence[float]] | None = None) -> list[dict[str, float]]:
    """The full-factorial combinations of ``levels`` (default :data:`LEVELS`) as task dicts."""
    levels = dict(LEVELS if levels is None else levels)
    keys = list(LEVELS)
    missing = [k for k in keys if k not in levels]
    if missing:
        raise KeyError(f"design levels missing {missing}")
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(levels[k] for k in keys))]


def run_combination(task: dict[str, Any]) -> list[dict[str, Any]]:
    """All rows of one design combination (task keys: :data:`LEVELS`, plus optional ``preset``,
    ``n_freq``, ``scan_hz``, ``refine``, ``profile``)."""
    sim = simulator(task.get("preset", "feasibility"), mass=task["mass_kg"], sigma=task["sigma_m"],
                    dgamma=task["dgamma_J_m2"], profile=task.get("profile", "gaussian"),
                    wavelength=task["wavelength_m"])
    x0 = task["x0_wl"] * task["wavelength_m"]
    stroke = task["stroke_m"]
    window, runs = find_window(sim, stroke, x0, task.get("scan_hz", SCAN_HZ),
                               task.get("refine", REFINE_STEPS))
    if window is not None:
        n = int(task.get("n_freq", N_FREQ))
        grid: Iterable[float] = (np.geomspace(window[0], window[1], n) if window[1] > window[0]
                                 else [window[0]])
        for f in grid:
            runs.append(("design", float(f), fire(sim, float(f), stroke, x0)))
    base = {k: task[k] for k in LEVELS}
    base["x0_m"] = x0
    lo, hi = window if window is not None else (math.nan, math.nan)
    capped = window is not None and not any(_fails(r) for _, _, r in runs)
    return [{**base, "phase": phase, "freq_hz": f, "window_lo_hz": lo, "window_hi_hz": hi,
             "window_capped": capped, **res} for phase, f, res in runs]


def sensitivity_rows(levels: Mapping[str, Sequence[float]] | None = None, n_freq: int = N_FREQ,
                     preset: str = "feasibility", scan_hz: Iterable[float] = SCAN_HZ,
                     **engine_kw: Any) -> list[dict[str, Any]]:
    """Run the design (see :func:`run_combination`), ``n_freq`` [-] frequencies per combination,
    window scan ``scan_hz`` [Hz]; ``engine_kw`` go to :func:`run_tasks`."""
    tasks = [{**t, "n_freq": n_freq, "preset": preset, "scan_hz": tuple(scan_hz)}
             for t in design(levels)]
    engine_kw.setdefault("desc", "sensitivity")
    return run_tasks(run_combination, tasks, **engine_kw)


def windows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One entry per combination: its levels and feasible window [Hz] (None: empty)."""
    seen: dict[tuple[Any, ...], dict[str, Any]] = {}
    for r in rows:
        key = tuple(r[k] for k in LEVELS)
        if key not in seen:
            lo, hi = r["window_lo_hz"], r["window_hi_hz"]
            seen[key] = {**{k: r[k] for k in LEVELS},
                         "window_hz": None if math.isnan(lo) else [lo, hi]}
    return list(seen.values())
