"""Kernel benchmark: median wall time of the reference firing per mode (the whole ``simulate`` call and
the compiled call alone), and kernel steps per second; :func:`bench_plane` times one firing in the
plane (docs/physics.md §10) against the same firing on the line.

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


# the plane's off-axis firing: the reference firing's actuator and stroke, the part at the same
# distance (0.125 mm) but off the x axis, passing sideways at 0.05 m/s (a curved path)
PLANE_OFF_AXIS = {"x0_m": 0.1e-3, "y0_m": 0.075e-3, "vx0_m_s": 0.0, "vy0_m_s": 0.05}


def bench_plane(preset: str = "feasibility", repeats: int = 500) -> dict[str, Any]:
    """Compiled-call time [s] of one firing in the plane against the 1-D reference firing (event
    mode, the Simulator's default step), measured interleaved (1-D, plane on the line, plane off
    the axis, in turn) so that a shared machine's load falls on all three alike; ``repeats`` [-]
    rounds, medians. The plane on the line is the same firing (the same steps and events); off
    the axis is :data:`PLANE_OFF_AXIS`. Ratios [-] are plane time over 1-D time, per firing and
    per step."""
    from ..physics import dynamics_kernel as k1
    from ..physics.plane import kernel as k2
    from ..physics.plane.simulator import PlaneSimulator
    from ..presets import load_preset

    line = simulator(preset)
    plane = PlaneSimulator(load_preset(preset).contact)
    one = np.zeros(1)
    f, h = one + REFERENCE_FIRING["freq"], one + REFERENCE_FIRING["stroke"]
    out1, out2 = np.zeros(k1.N_OUT), np.zeros(k2.N_OUT)
    rec1, rec2 = np.zeros((0, k1.N_REC)), np.zeros((0, k2.N_REC))
    x0 = REFERENCE_FIRING["x0"]
    off = PLANE_OFF_AXIS

    zero = np.zeros(1)  # the actuator at the origin, no delay

    def run_line() -> None:
        k1.run(zero, f, h, zero, x0, 0.0, 0.0, line.dt,  # type: ignore[call-arg]
               line.min_steps, True, line.max_time, line.params, *line.tables, rec1, out1)

    def run_plane(x: float, y: float, vx: float, vy: float) -> None:
        k2.run(zero, zero, f, h, zero, x, y, vx, vy, 0.0,  # type: ignore[call-arg]
               plane.dt, plane.min_steps, True, plane.max_time, plane.params, *plane.tables, rec2,
               out2)

    calls = {"line": run_line, "plane_on_line": lambda: run_plane(x0, 0.0, 0.0, 0.0),
             "plane_off_axis": lambda: run_plane(off["x0_m"], off["y0_m"], off["vx0_m_s"],
                                                       off["vy0_m_s"])}
    walls: dict[str, list[float]] = {k: [] for k in calls}
    steps: dict[str, int] = {}
    for name, call in calls.items():  # warm-up (compile/load) and the firing's step count
        call()
        steps[name] = int((out1 if name == "line" else out2)[k1.O_STEPS if name == "line"
                                                              else k2.O_STEPS])
    for _ in range(repeats):
        for name, call in calls.items():
            t0 = time.perf_counter()
            call()
            walls[name].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in walls.items()}
    res: dict[str, Any] = {k: {"median_kernel_time_s": med[k], "steps": steps[k],
                               "kernel_time_per_step_s": med[k] / steps[k]} for k in calls}
    for k in ("plane_on_line", "plane_off_axis"):
        res[f"{k}_cost_ratio"] = med[k] / med["line"]
        res[f"{k}_cost_ratio_per_step"] = (med[k] / steps[k]) / (med["line"] / steps["line"])
    res["off_axis_start"] = dict(off)
    return res
