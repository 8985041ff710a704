"""Which model level a scene needs: each model choice against the most faithful level, and its cost.

Three scenes (:data:`SCENES`): the reference firing, a 5-firing episode ending near its start and one
ending far. Model choices: kinematics ``seed`` / ``exact``, roughness ``constant`` (and
``stretch`` where the simulator offers it), integrator ``event`` / ``karnopp``, and a ladder of
steps ``dt``. Every physics level (kinematics x roughness) also runs at a converged setting (event
mode, ``REFERENCE_DT``); the most faithful level is exact kinematics, the most detailed roughness,
converged.

Per row: the final position (or the detachment point), the outcome, its error against the most
faithful level (``error_vs_faithful_m``: physics + numerics) and against its own physics level
converged (``numerical_error_m``: numerics only), and the wall time of the ``simulate`` call
(median of ``repeats``). A physics disagreement is a level whose converged result differs from the
most faithful one (other outcome, or more than the tolerance apart), whatever the step.
"""
from __future__ import annotations

import math
import statistics
import time
from collections.abc import Iterable, Sequence
from typing import Any
from collections.abc import Callable

from ..physics.contact_table import TableRangeError
from ..physics.schedule import ActuatorArray, Schedule
from .engine import run_tasks, simulator

SCENES: dict[str, dict[str, Any]] = {
    "single": {"what": "the reference firing: 950 Hz, h = 200 µm, start 0.125 mm beside the actuator",
               "count": 1, "spacing_m": 0.5e-3, "freq_hz": 950.0, "stroke_m": 200e-6,
               "delay_s": 0.0, "x0_m": 0.125e-3},
    "episode_near": {"what": "5 firings, spacing 0.5 mm, 500 Hz, h = 150 µm, 1 ms delays, start "
                             "0.15 mm upstream: ends within ~0.1 mm of its start",
                     "count": 5, "spacing_m": 0.5e-3, "freq_hz": 500.0, "stroke_m": 150e-6,
                     "delay_s": 1e-3, "x0_m": -0.15e-3},
    "episode_far": {"what": "5 firings, spacing 0.3 mm, 950 Hz, h = 200 µm, 1 ms delays, start "
                            "0.15 mm upstream: ends ~2 mm downstream",
                    "count": 5, "spacing_m": 0.3e-3, "freq_hz": 950.0, "stroke_m": 200e-6,
                    "delay_s": 1e-3, "x0_m": -0.15e-3},
}
KINEMATICS = ("reduced", "exact")
ROUGHNESS = ("constant",)          # "stretch" is added when the simulator supports it
MODES = ("event", "karnopp")
DTS = (5e-5, 2.5e-5, 1.25e-5, 6.25e-6, 3.125e-6, 1.5625e-6)
REFERENCE_DT = 1e-7
TOLERANCE_M = 1e-6


def schedule_of(scene: dict[str, Any]) -> Schedule:
    """The schedule of a scene of :data:`SCENES` (``count`` actuators ``spacing_m`` [m] apart,
    each fired at ``freq_hz`` [Hz] with ``stroke_m`` [m] after ``delay_s`` [s])."""
    arr = ActuatorArray.uniform(scene["count"], scene["spacing_m"])
    return Schedule.sequence(arr, scene["freq_hz"], scene["stroke_m"], scene["delay_s"])


def roughness_levels() -> tuple[str, ...]:
    """The roughness levels the simulator supports."""
    import inspect

    from ..physics.simulator import Simulator

    return ROUGHNESS + (("stretch",) if "roughness" in inspect.signature(Simulator).parameters
                        and "stretch" not in ROUGHNESS else ())


def run_level(task: dict[str, Any]) -> list[dict[str, Any]]:
    """One row: a scene at one (kinematics, roughness, mode, dt [s]) level."""
    kw: dict[str, Any] = {"kinematics": task["kinematics"], "mode": task["mode"], "dt": task["dt_s"]}
    if task["reference"]:
        kw["min_steps"] = 2
    if task["roughness"] != "constant":
        kw["roughness"] = task["roughness"]
    sim = simulator(task.get("preset", "feasibility"), **kw)
    sched = schedule_of(SCENES[task["scene"]])
    x0 = SCENES[task["scene"]]["x0_m"]
    row = {k: task[k] for k in ("scene", "kinematics", "roughness", "mode", "dt_s", "reference")}
    try:
        r = sim.simulate(sched, x0=x0)
    except TableRangeError:
        return [{**row, "outcome": "load_beyond_table", "position_m": math.nan, "steps": 0,
                 "wall_time_s": math.nan}]
    walls: list[float] = []
    for _ in range(int(task.get("repeats", 3))):
        t0 = time.perf_counter()
        sim.simulate(sched, x0=x0)
        walls.append(time.perf_counter() - t0)
    pos = r.detach_position_m if r.outcome == "detached" else r.final_position_m
    return [{**row, "outcome": r.outcome, "position_m": pos, "steps": r.steps,
             "wall_time_s": statistics.median(walls) if walls else r.wall_time_s}]


def tasks(scenes: Sequence[str] = tuple(SCENES), dts: Sequence[float] = DTS,
          modes: Sequence[str] = MODES, kinematics: Sequence[str] = KINEMATICS,
          roughness: Iterable[str] | None = None, repeats: int = 3,
          preset: str = "feasibility") -> list[dict[str, Any]]:
    """The tasks of the study: per scene and physics level a converged reference (event mode,
    ``REFERENCE_DT`` [s]) and every (mode, dt [s]); ``repeats`` [-] timed runs each."""
    roughness = roughness_levels() if roughness is None else tuple(roughness)
    out: list[dict[str, Any]] = []
    for sc in scenes:
        for kin in kinematics:
            for rough in roughness:
                base = {"scene": sc, "kinematics": kin, "roughness": rough, "repeats": repeats,
                        "preset": preset}
                out.append({**base, "mode": "event", "dt_s": REFERENCE_DT, "reference": True})
                for mode in modes:
                    for dt in dts:
                        out.append({**base, "mode": mode, "dt_s": dt, "reference": False})
    return out


def fidelity_rows(scenes: Sequence[str] = tuple(SCENES), dts: Sequence[float] = DTS,
                  modes: Sequence[str] = MODES, roughness: Iterable[str] | None = None,
                  repeats: int = 3, preset: str = "feasibility",
                  **engine_kw: Any) -> list[dict[str, Any]]:
    """Raw rows of every (scene, level), steps ``dts`` [s]; :func:`assess` adds the errors."""
    engine_kw.setdefault("desc", "fidelity")
    return run_tasks(run_level, tasks(scenes, dts, modes, KINEMATICS, roughness, repeats, preset),
                     **engine_kw)


def _faithful(levels: dict[str, list[str]]) -> tuple[str, str]:
    kin = "exact" if "exact" in levels["kinematics"] else levels["kinematics"][0]
    rough = "stretch" if "stretch" in levels["roughness"] else levels["roughness"][0]
    return kin, rough


def assess(rows: list[dict[str, Any]], tolerance_m: float = TOLERANCE_M) -> dict[str, Any]:
    """Errors per row [m], physics disagreements (beyond ``tolerance_m`` [m]), and per scene the
    cheapest adequate level."""
    levels = {"kinematics": sorted({r["kinematics"] for r in rows}),
              "roughness": sorted({r["roughness"] for r in rows})}
    fk, fr = _faithful(levels)
    refs = {(r["scene"], r["kinematics"], r["roughness"]): r for r in rows if r["reference"]}
    out_rows: list[dict[str, Any]] = []
    physics: list[dict[str, Any]] = []
    rules: dict[str, Any] = {}
    for r in rows:
        own = refs[(r["scene"], r["kinematics"], r["roughness"])]
        top = refs[(r["scene"], fk, fr)]
        e_num = abs(r["position_m"] - own["position_m"])
        e_all = abs(r["position_m"] - top["position_m"])
        out_rows.append({**r, "error_vs_faithful_m": e_all, "numerical_error_m": e_num,
                         "outcome_matches_faithful": r["outcome"] == top["outcome"]})
    for (sc, kin, rough), ref in refs.items():
        top = refs[(sc, fk, fr)]
        if (kin, rough) == (fk, fr):
            continue
        diff = abs(ref["position_m"] - top["position_m"])
        if ref["outcome"] != top["outcome"] or diff > tolerance_m:
            physics.append({"scene": sc, "level": f"{kin} kinematics, {rough} roughness",
                            "outcome": ref["outcome"], "faithful_outcome": top["outcome"],
                            "position_m": ref["position_m"],
                            "faithful_position_m": top["position_m"], "difference_m": diff})
    for sc in sorted({r["scene"] for r in rows}):
        mine = [r for r in out_rows if r["scene"] == sc and not r["reference"]]
        ok_all = _stays_within(mine, lambda r: r["outcome_matches_faithful"]
                               and r["error_vs_faithful_m"] <= tolerance_m)
        def converged(r: dict[str, Any], sc: str = sc) -> bool:
            return bool(r["numerical_error_m"] <= tolerance_m
                        and r["outcome"] == refs[(sc, r["kinematics"], r["roughness"])]["outcome"])

        ok_num = _stays_within(mine, converged)
        rules[sc] = {"cheapest_within_tolerance_of_faithful": _cheapest(ok_all),
                     "cheapest_numerically_converged": _cheapest(ok_num),
                     "faithful": refs[(sc, fk, fr)]}
    return {"tolerance_m": tolerance_m, "faithful_level": {"kinematics": fk, "roughness": fr,
                                                           "mode": "event",
                                                           "dt_s": REFERENCE_DT},
            "rows": out_rows, "physics_disagreements": physics, "per_scene": rules,
            "scenes": {k: v["what"] for k, v in SCENES.items()}}


def _stays_within(rows: list[dict[str, Any]],
                  good: Callable[[dict[str, Any]], bool]) -> list[dict[str, Any]]:
    """Rows that are good at their dt *and at every smaller dt* of the same level and mode (a
    lucky hit of an erratic integrator is not accepted)."""
    out: list[dict[str, Any]] = []
    for r in rows:
        finer = [q for q in rows if q["kinematics"] == r["kinematics"]
                 and q["roughness"] == r["roughness"] and q["mode"] == r["mode"]
                 and q["dt_s"] <= r["dt_s"]]
        if all(good(q) for q in finer):
            out.append(r)
    return out


def _cheapest(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    return dict(min(rows, key=lambda q: q["wall_time_s"])) if rows else None


# ----------------------------------------------------------------------------- firing maps
# the scenes whose maps are reported
MAP_ENV_IDS = ("MicroPositioner-v0", "MicroConveyor-v1", "MicroConveyor2D-v1")


def map_rows(env_ids: Sequence[str] = MAP_ENV_IDS, samples: int = 5000,
             seed: int = 12345) -> list[dict[str, Any]]:
    """Each scene's firing map (:mod:`microconveyor_env.envs.rail.firing_map`, the plane's
    :mod:`microconveyor_env.envs.plane.firing_map`) against the full model on ``samples`` [-]
    held-out strokes drawn with ``seed`` [-] (the plane's in every direction, each coasted to
    rest, with the full model's largest move off the actuator's line ``perpendicular_max_m``
    [m]): one row per env id with
    the grid, its build time [s] (as cached), the error figures of
    :class:`~microconveyor_env.physics.firing_map.MapError` [m] and the wall time per map query
    and per full-model stroke [s] (one thread), and their ratio; for a map of moving parts
    (errors at the end of the stroke) also ``at_rest``, the same figures where the part then
    comes to rest (the coast multiplies an error of the end velocity)."""
    from ..envs.core.versions import scene_config
    from ..envs.plane import firing_map as plane_map
    from ..envs.plane.config import PlaneEnvConfig
    from ..envs.rail import firing_map as rail_map

    rows = []
    for env_id in env_ids:
        cfg = scene_config(env_id)
        plane = isinstance(cfg, PlaneEnvConfig)
        from_rest = plane or bool(cfg.fires_from_rest)
        m = (plane_map if plane else rail_map).firing_map(cfg)
        e = m.verify(samples, seed)
        # a moving part's error at the end of the stroke, and where it then comes to rest
        landing = None if from_rest else m.verify(samples, seed, to_rest=True)
        g = m.grid
        rows.append({"env_id": env_id, "from_rest": from_rest,
                     "nodes": m.nodes, "offset_m": list(g.offset_m[:2]),
                     "velocity_m_s": list(g.velocity_m_s[:2]),
                     "frequency_hz": list(g.frequency_hz[:2]), "stroke_m": list(g.stroke_m[:2]),
                     "shape": list(g.shape), "build_s": m.build_s, **e.to_dict(),
                     "speedup": e.full_stroke_s / e.map_query_s if e.map_query_s > 0 else None,
                     "at_rest": None if landing is None else landing.to_dict()})
    return rows
