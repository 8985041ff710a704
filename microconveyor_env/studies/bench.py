"""Kernel benchmark: median wall time of the reference firing per mode (the whole ``simulate`` call and
the compiled call alone), and kernel steps per second.

The dissertation-style plain-Python baseline is :mod:`.reference_loop`.
"""
from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from ..physics.schedule import Schedule
from ..physics.simulator import Simulator
from ..presets import simulator

REFERENCE_FIRING = {"freq": 950.0, "stroke": 200e-6, "x0": 0.125e-3}


def bench_modes(preset: str = "feasibility", repeats: int = 500) -> dict[str, dict[str, Any]]:
    """Per mode: median and min wall time [s] of ``repeats`` [-] reference firings, the compiled
    call's median time [s], kernel steps per second [1/s] and the firing's outcome (SI)."""
    sched = Schedule.single(REFERENCE_FIRING["freq"], REFERENCE_FIRING["stroke"])
    out = {}
    for mode in ("event", "karnopp"):
        sim = simulator(preset, mode=mode)
        res = sim.simulate(sched, x0=REFERENCE_FIRING["x0"])  # warm-up (compile/load)
        walls: list[float] = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            sim.simulate(sched, x0=REFERENCE_FIRING["x0"])
            walls.append(time.perf_counter() - t0)
        med = statistics.median(walls)
        kern = _kernel_time(sim, sched, repeats)
        out[mode] = {"median_wall_time_s": med, "min_wall_time_s": min(walls),
                     "median_kernel_time_s": kern, "dt_s": sim.dt, "steps": res.steps,
                     "events": res.events, "kernel_steps_per_s": res.steps / kern,
                     "displacement_m": res.displacement_m, "outcome": res.outcome}
    return out


def _kernel_time(sim: Simulator, sched: Schedule, repeats: int) -> float:
    """Median time of the compiled call alone (no Python-side validation or result objects)."""
    from ..physics import dynamics_kernel as kernel

    xa, f, h, d = sched.arrays()
    rec, out = np.zeros((0, kernel.N_REC)), np.zeros(kernel.N_OUT)
    args = (xa, f, h, d, REFERENCE_FIRING["x0"], 0.0, 0.0, sim.dt, sim.min_steps, True, sim.max_time,
            sim.params, *sim.tables, rec, out)
    kernel.run(*args)
    walls: list[float] = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        kernel.run(*args)
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls)
