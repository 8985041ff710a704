"""Engaging a moving part (dissertation ch. 4): one firing met by a part already in motion, and
two actuators fired in turn.

*Engaging map.* A part at ``x0`` [m] (relative to the actuator at x = 0) moving at ``v0`` [m/s]
when the stroke starts; travel = final position - x0 after the part comes to rest (or detaches).
Without a firing it would coast ``sign(v0) v0^2 / (2 a)`` on the still flat surface
(``a = Q(m g0)/m``), so ``gain_m`` = travel - coast says whether the firing pushed it on (> 0
along v0) or held it back. ``travel_along_m`` is the travel measured along the initial motion.

*Two actuators.* Actuators at 0 and ``spacing`` [m], the part starting ``start_offset`` upstream
of the first (the reference firing mirrored: 950 Hz, 200 um, 0.125 mm, transport towards +x); the
first fires, and after ``delay`` [s] the second. ``extra_m`` = final position - final position with the first firing only: > 0 where
the second actuator carries the part on (accelerates it), < 0 where it brakes it.
"""
from __future__ import annotations

from typing import Any

import math
from collections.abc import Sequence

import numpy as np

from ..physics.contact_table import TableRangeError
from ..physics.schedule import ActuatorArray, Firing, Schedule
from ..physics.simulator import Result, Simulator
from .engine import run_tasks, simulator

SPEED_STATEMENT = {"freq_hz": 500.0, "stroke_m": 150e-6, "rise_to_m_s": 0.15, "fall_to_m_s": 0.32}


def _run(sim: Simulator, schedule: Schedule, x0: float, v0: float = 0.0,
         to_rest: bool = True) -> Result | None:
    try:
        r = sim.simulate(schedule, x0=x0, v0=v0, to_rest=to_rest)
    except TableRangeError:
        return None
    return r


def map_column(task: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of one (freq [Hz], x0 [m]) column of the engaging map over the task's ``v0s`` [m/s]."""
    sim = simulator(task.get("preset", "feasibility"), **task.get("sim_kw", {}))
    f, h, x0 = task["freq_hz"], task["stroke_m"], task["x0_m"]
    a = sim.flat_deceleration()
    sched = Schedule.single(f, h)
    rows = []
    for v0 in task["v0s"]:
        r = _run(sim, sched, x0, v0)
        coast = math.copysign(v0 * v0 / (2 * a), v0)
        if r is None:
            out: dict[str, Any] = {"outcome": "load_beyond_table", "travel_m": math.nan}
        else:
            out = {"outcome": r.outcome, "travel_m": r.displacement_m}
        along = out["travel_m"] * (1.0 if v0 >= 0 else -1.0)
        rows.append({"freq_hz": f, "stroke_m": h, "x0_m": x0, "v0_m_s": v0, **out,
                     "coast_m": coast, "gain_m": out["travel_m"] - coast,
                     "travel_along_m": along,
                     "gain_along_m": (out["travel_m"] - coast) * (1.0 if v0 >= 0 else -1.0),
                     "detached": out["outcome"] == "detached"})
    return rows


def engage_map_rows(freqs: Sequence[float] = (300.0, 500.0, 700.0), stroke: float = 150e-6,
                    x0s: Sequence[float] = tuple(
                        np.round(np.arange(-0.6e-3, 0.6e-3 + 1e-9, 0.05e-3), 9)),
                    v0s: Sequence[float] = tuple(np.round(np.arange(-0.5, 0.5 + 1e-9, 0.01), 6)),
                    preset: str = "feasibility", sim_kw: dict[str, Any] | None = None,
                    **engine_kw: Any) -> list[dict[str, Any]]:
    """The engaging map: frequencies [Hz] x start positions [m] x initial velocities [m/s], strokes
    of ``stroke`` [m]; ``sim_kw`` go to the simulator, ``engine_kw`` to :func:`.engine.run_tasks`."""
    tasks = [{"freq_hz": float(f), "stroke_m": float(stroke), "x0_m": float(x0),
              "v0s": tuple(float(v) for v in v0s), "preset": preset, "sim_kw": sim_kw or {}}
             for f in freqs for x0 in x0s]
    engage_kw = {"desc": "engage map", **engine_kw}
    return run_tasks(map_column, tasks, **engage_kw)


def _extrema(v: np.ndarray, y: np.ndarray) -> tuple[list[int], list[int]]:
    """Interior local maxima and minima of y(v) (plateaus collapsed)."""
    mx: list[int] = []
    mn: list[int] = []
    for i in range(1, len(v) - 1):
        if y[i] > y[i - 1] and y[i] >= y[i + 1]:
            mx.append(i)
        elif y[i] < y[i - 1] and y[i] <= y[i + 1]:
            mn.append(i)
    return mx, mn


def _pattern(v: np.ndarray, y: np.ndarray) -> tuple[float, float] | None:
    """First (speed of a local max, speed of the next local min) with y rising again after the
    min, or None."""
    mx, mn = _extrema(v, y)
    for i in mx:
        later = [j for j in mn if j > i]
        if later and later[0] + 1 < len(y) and y[later[0] + 1:].max() > y[later[0]]:
            return float(v[i]), float(v[later[0]])
    return None


def check_speed_statement(rows: list[dict[str, Any]], tol_m_s: float = 0.05,
                          statement: dict[str, float] = SPEED_STATEMENT,
                          measures: Sequence[str] = ("travel_along_m", "gain_along_m"),
                          ) -> dict[str, Any]:
    """Test "travel rises with initial speed up to ~0.15 m/s, falls to ~0.32 m/s, then rises
    again" on the map rows at the statement's frequency and stroke, per start position and
    direction of motion, detached runs excluded. Two readings of "travel": the whole travel
    along the motion (``travel_along_m``) and the gain over coasting (``gain_along_m``), both [m];
    speeds match within ``tol_m_s`` [m/s]."""
    f, h = statement["freq_hz"], statement["stroke_m"]
    sel = [r for r in rows if r["freq_hz"] == f and r["stroke_m"] == h]
    if not sel:
        return {"checked": False, "reason": f"no rows at {f} Hz, h = {h} m"}
    target = (statement["rise_to_m_s"], statement["fall_to_m_s"])
    out: dict[str, Any] = {"checked": True, "freq_hz": f, "stroke_m": h, "tolerance_m_s": tol_m_s,
           "statement": "travel rises with initial speed up to ~0.15 m/s, falls to ~0.32 m/s, "
                        "then rises again"}
    for measure in measures:
        per: list[dict[str, Any]] = []
        for x0 in sorted({r["x0_m"] for r in sel}):
            for sgn in (1.0, -1.0):
                col = sorted((abs(r["v0_m_s"]), r[measure]) for r in sel
                             if r["x0_m"] == x0 and r["v0_m_s"] * sgn > 0 and not r["detached"])
                if len(col) < 5:
                    continue
                pat = _pattern(np.array([c[0] for c in col]), np.array([c[1] for c in col]))
                if pat is None:
                    continue
                dev = max(abs(pat[0] - target[0]), abs(pat[1] - target[1]))
                per.append({"x0_m": x0, "direction": int(sgn), "max_at_m_s": pat[0],
                            "min_at_m_s": pat[1], "deviation_m_s": dev,
                            "matches": dev <= tol_m_s})
        best = min(per, key=lambda p: p["deviation_m_s"]) if per else None
        out[measure] = {"starts_with_pattern": len(per),
                        "matching": [p for p in per if p["matches"]], "closest": best,
                        "per_start": per}
    out["reproduced"] = any(out[m]["matching"] for m in measures)
    return out


# ----------------------------------------------------------------------------- two actuators
def two_column(task: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of one spacing [m] of the two-actuator map over the task's delays [s]."""
    sim = simulator(task.get("preset", "feasibility"), **task.get("sim_kw", {}))
    f, h, sp, x0 = task["freq_hz"], task["stroke_m"], task["spacing_m"], task["x0_m"]
    arr = ActuatorArray((0.0, sp))
    one = _run(sim, Schedule(arr, (Firing(0, f, h),)), x0)
    first = _run(sim, Schedule(arr, (Firing(0, f, h),)), x0, to_rest=False)
    decel = sim.flat_deceleration()
    rows = []
    for d in task["delays_s"]:
        r = _run(sim, Schedule(arr, (Firing(0, f, h), Firing(1, f, h, d))), x0)
        # the part's state when the second stroke starts (closed-form coast on the flat)
        v1 = first.final_velocity_m_s if first is not None else math.nan
        t_stop = abs(v1) / decel
        tt = min(d, t_stop)
        v_at = math.copysign(max(abs(v1) - decel * d, 0.0), v1)
        x_at = (first.final_position_m + v1 * tt - math.copysign(0.5 * decel * tt * tt, v1)
                if first is not None else math.nan)
        final = r.final_position_m if r is not None else math.nan
        base = one.final_position_m if one is not None else math.nan
        rows.append({"freq_hz": f, "stroke_m": h, "spacing_m": sp, "delay_s": d, "x0_m": x0,
                     "outcome": r.outcome if r is not None else "load_beyond_table",
                     "final_position_m": final, "single_final_position_m": base,
                     "extra_m": final - base, "x_at_second_m": x_at, "v_at_second_m_s": v_at,
                     "detached": r is not None and r.outcome == "detached"})
    return rows


def two_actuator_rows(freq: float = 950.0, stroke: float = 200e-6, start_offset: float = 0.125e-3,
                      spacings: Sequence[float] = tuple(
                          np.round(np.arange(0.2e-3, 1.5e-3 + 1e-9, 0.05e-3), 9)),
                      delays: Sequence[float] = tuple(
                          np.round(np.arange(0.0, 8e-3 + 1e-12, 0.2e-3), 9)),
                      preset: str = "feasibility", sim_kw: dict[str, Any] | None = None,
                      **engine_kw: Any) -> list[dict[str, Any]]:
    """Final position over (delay [s], spacing [m]) at ``freq`` [Hz] and ``stroke`` [m], the part
    starting ``start_offset`` [m] upstream of the first actuator."""
    tasks = [{"freq_hz": float(freq), "stroke_m": float(stroke), "spacing_m": float(s),
              "x0_m": -float(start_offset), "delays_s": tuple(float(d) for d in delays),
              "preset": preset, "sim_kw": sim_kw or {}} for s in spacings]
    engage_kw = {"desc": "two actuators", **engine_kw}
    return run_tasks(two_column, tasks, **engage_kw)


def summarise_two(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts of runs that the second actuator accelerates (> 1 um further) or brakes, the best
    final position [m] and the strongest brake."""
    ok = [r for r in rows if not r["detached"] and not math.isnan(r["extra_m"])]
    acc = [r for r in ok if r["extra_m"] > 1e-6]
    brk = [r for r in ok if r["extra_m"] < -1e-6]
    best = max(ok, key=lambda r: r["final_position_m"]) if ok else None
    worst = min(ok, key=lambda r: r["extra_m"]) if ok else None
    return {"runs": len(rows), "detached": sum(r["detached"] for r in rows),
            "accelerates": len(acc), "brakes": len(brk),
            "single_final_position_m": rows[0]["single_final_position_m"] if rows else None,
            "best": best, "strongest_brake": worst}
