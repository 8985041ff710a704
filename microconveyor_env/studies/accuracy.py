"""Speed versus accuracy of the integrator settings (mode x kinematics x dt).

For the reference firing (950 Hz, 200 um, start 0.125 mm, coast to rest) each setting's final position is
compared with a converged reference of the same kinematics level (event mode, a very small step),
and its wall time per firing is measured (median of repeats, compiled kernel). The default setting
is the cheapest one within ``tolerance_m`` of the reference *that also stays within it at every
smaller dt of the same mode* (Karnopp's error is erratic in dt, so a lucky hit is not accepted).
"""
from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

from ..physics.schedule import Schedule
from ..physics.simulator import MIN_STEPS_PER_STROKE, Result, Simulator
from ..presets import simulator

DTS = (5e-5, 2.5e-5, 1.25e-5, 6.25e-6, 3.125e-6, 1.5625e-6, 7.8125e-7)
REFERENCE_DT = 1e-7


def time_firing(sim: Simulator, schedule: Schedule, x0: float,
                repeats: int) -> tuple[Result, float]:
    """(result, median wall time [s]) of ``repeats`` [-] runs from ``x0`` [m] after one warm-up."""
    res = sim.simulate(schedule, x0=x0)
    walls: list[float] = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.simulate(schedule, x0=x0)
        walls.append(time.perf_counter() - t0)
    return res, statistics.median(walls)


def accuracy_study(preset: str = "feasibility", freq: float = 950.0, stroke: float = 200e-6,
                   x0: float = 0.125e-3, dts: Sequence[float] = DTS, repeats: int = 30,
                   tolerance_m: float = 1e-6, progress: bool = True) -> dict[str, Any]:
    """The speed/accuracy study of one firing (``freq`` [Hz], ``stroke`` [m], start ``x0`` [m]) over
    the steps ``dts`` [s], ``repeats`` [-] timed runs each; the default setting is the cheapest within
    ``tolerance_m`` [m] (see the module docstring)."""
    from tqdm import tqdm

    schedule = Schedule.single(freq, stroke)
    rows: list[dict[str, Any]] = []
    refs: dict[str, float] = {}
    combos = [(m, k) for k in ("reduced", "exact") for m in ("event", "karnopp")]
    bar = tqdm(total=len(combos) * len(dts) + 2, desc="accuracy", file=sys.stderr,
               disable=not progress, leave=False)
    for kin in ("reduced", "exact"):
        ref = simulator(preset, kinematics=kin, mode="event", dt=REFERENCE_DT, min_steps=2)
        refs[kin] = ref.simulate(schedule, x0=x0).final_position_m
        bar.update()
    for mode, kin in combos:
        for dt in dts:
            sim = simulator(preset, kinematics=kin, mode=mode, dt=dt, min_steps=MIN_STEPS_PER_STROKE)
            res, wall = time_firing(sim, schedule, x0, repeats)
            rows.append({"mode": mode, "kinematics": kin, "dt_s": dt,
                         "steps_per_stroke": sim.steps_per_stroke(freq),
                         "error_m": abs(res.final_position_m - refs[kin]),
                         "wall_time_s": wall, "outcome": res.outcome})
            bar.update()
    bar.close()
    default = pick_default(rows, "reduced", tolerance_m)
    return {"freq_hz": freq, "stroke_m": stroke, "x0_m": x0, "tolerance_m": tolerance_m,
            "reference_dt_s": REFERENCE_DT, "reference_final_position_m": refs,
            "rows": rows, "default": default}


def pick_default(rows: list[dict[str, Any]], kinematics: str,
                 tolerance_m: float) -> dict[str, Any] | None:
    """Cheapest (mode, dt) of ``kinematics`` within ``tolerance_m`` [m] at that dt and all smaller
    dts."""
    ok = []
    for r in rows:
        if r["kinematics"] != kinematics:
            continue
        finer = [q for q in rows if q["kinematics"] == kinematics and q["mode"] == r["mode"]
                 and q["dt_s"] <= r["dt_s"]]
        if all(q["error_m"] <= tolerance_m for q in finer):
            ok.append(r)
    return min(ok, key=lambda r: r["wall_time_s"]) if ok else None
