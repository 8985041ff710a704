"""Placement time against precision: every controller of a scene on the same held-out targets, the
share of parts resting within ±50, ±20, ±10 and ±5 µm of their target beside the median and 90th
percentile of the time they took to come to rest.

A *method* (:class:`Method`) plays one episode per target in a given env config and returns each
episode's final error [m], outcome and placement time [s] (the env's ``sim_time_s`` at the end):
a shipped policy folder (closed loop, :func:`agents.rl.evaluation.evaluate.rollout`), the line's
staged expert (:class:`agents.mpc.staged.StagedExpert`) and the plane's one-step controller
(:class:`agents.planning.plane.PlaneController`) acting on the batched env's parts, model-predictive
control (:mod:`agents.mpc.harness`) and open-loop plans searched per target on the nominal model
(:func:`agents.openloop.target.solve_target`, differential evolution) then replayed.

The *request* is the env config's ``tolerance`` [m]: the env ends an episode once the part rests
within it, so a method run at a tighter request keeps firing where a looser one stops.
Methods whose result depends on the request are run at each of :data:`REQUESTS`; the others once,
at the scene's own tolerance. The placement time is the env's clock when the episode ended: for a
part that rests outside the request, the firings the conveyor still fires (their delays
included) count, even where they no longer reach the part. Each row is one method at one request and one perturbation level
(:data:`LEVELS`: nominal, and execution noise σ = 3e-3 with friction and mass factors within
±5 %), on ``n_targets`` of the held-out targets (``fixed_targets(config, n, seed=1)``; a slow
planner plays the first ``n`` of the same targets). Sub-env ``i`` is seeded ``i`` for every
method (common random numbers).

::

    from agents.experiments.frontier import methods_for, frontier_row, frontier_table
    cfg = scene_config("MicroConveyor-v1")
    for m in methods_for("MicroConveyor-v1"):
        row = frontier_row("MicroConveyor-v1", "nominal", m, 50e-6, targets[:m.n_targets])
"""
from __future__ import annotations

import dataclasses
import inspect
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs.core.episodes import run_episodes
from microconveyor_env.envs.core.versions import nominal, scene_config

from ..rl.evaluation.evaluate import batched_env, fixed_targets, placement_times, rollout
from .perturb import Level

__all__ = ["REQUESTS", "RADII", "LEVELS", "TARGET_SEED", "Method", "methods_for",
           "frontier_row", "frontier_rows", "frontier_table", "row_figures", "POLICY_ROOT"]

REQUESTS = (50e-6, 20e-6, 10e-6, 5e-6)   # [m] the tolerances a method is asked for
RADII = (50e-6, 20e-6, 10e-6, 5e-6)      # [m] the shares within reported per row
LEVELS = {"nominal": Level(0.0, 0.0), "perturbed": Level(0.003, 0.05)}
TARGET_SEED = 1                          # the held-out targets' seed
POLICY_ROOT = Path(__file__).resolve().parents[1] / "policies"
TIME_WEIGHT = 1e3                        # [1/s] DE's time weight A (A T_f + |e / T_d|^10)
DE_BUDGET = 10_000                       # [episodes] DE's search per target
SLOW_TARGETS = 40                        # targets of an MPC row by default
DE_TARGETS = 20                          # targets of a DE row by default (a search per target)
FAST_TARGETS = 500                       # targets of a policy's or a fast planner's row

# (config, targets [m], seed) -> {"error_m", "outcome", "time_s"}: one episode per target
RunFn = Callable[[Any, np.ndarray, int], dict]


@dataclass(frozen=True)
class Method:
    """One controller: ``name``; ``run`` plays one episode per target in a config; ``per_request``
    whether its result depends on the request (it is run at each of :data:`REQUESTS`, else once
    at the scene's own tolerance); ``n_targets`` its default number of targets per row."""

    name: str
    run: RunFn
    per_request: bool = True
    n_targets: int = FAST_TARGETS


def row_figures(error_m: Any, outcome: Any, time_s: Any) -> dict[str, Any]:
    """The figures of one row from per-episode arrays: the share at rest within each radius of
    :data:`RADII`, median and p90 absolute error [m], detach rate, and the median and p90
    placement time [s] over the episodes that ended at rest (None when none did)."""
    err = np.abs(np.asarray(error_m, float))
    out = np.asarray(outcome).astype(str)
    rest = out == "rest"
    row: dict[str, Any] = {f"success_rate_{round(r * 1e6)}um": float(np.mean(rest & (err <= r)))
                           for r in RADII}
    finite = err[np.isfinite(err)]
    row["median_abs_error_m"] = float(np.median(finite)) if finite.size else None
    row["p90_abs_error_m"] = float(np.percentile(finite, 90)) if finite.size else None
    row["detach_rate"] = float(np.mean(out == "detached"))
    return {**row, **placement_times(time_s, out)}


def frontier_row(env_id: str, level: str, method: Method, request_m: float | None,
                 targets: np.ndarray, seed: int = 0) -> dict[str, Any]:
    """One row: ``method`` on ``targets`` in ``env_id``'s scene at perturbation ``level`` (a key
    of :data:`LEVELS`) with the env's tolerance ``request_m`` [m] (None: the scene's own).
    ``wall_s_per_target`` [s]: the method's computing time per target (for DE its searches,
    whichever row ran them, and the replay)."""
    base = scene_config(env_id)
    cfg = LEVELS[level].config(base)
    if request_m is not None:
        cfg = dataclasses.replace(cfg, tolerance=float(request_m))
    t0 = time.perf_counter()
    res = method.run(cfg, np.asarray(targets, float), seed)
    # a method that reuses work of another row reports what the row's episodes cost in all
    wall = float(res.get("compute_s", time.perf_counter() - t0))
    n = len(targets)
    return {"env_id": env_id, "level": level, "method": method.name,
            "request_tolerance_m": float(cfg.tolerance), "n_targets": int(n),
            **row_figures(res["error_m"], res["outcome"], res["time_s"]),
            "wall_s_per_target": wall / max(n, 1)}


def frontier_rows(env_id: str, methods: list[Method], n_targets: int | None = None,
                  slow_targets: int | None = None, levels: tuple[str, ...] = tuple(LEVELS),
                  seed: int = 0, requests: tuple[float, ...] = REQUESTS,
                  done: Callable[[dict[str, Any]], bool] | None = None
                  ) -> Iterator[dict[str, Any]]:
    """Every row of ``methods`` in ``env_id``'s scene, level by level, as each completes.
    ``n_targets`` / ``slow_targets`` override the targets of fast / slow methods' rows (a
    method's own ``n_targets`` otherwise); ``done(row_key)`` skips a row already stored (its
    key: env_id, level, method, request_tolerance_m)."""
    base = scene_config(env_id)
    most = max(n_targets or 0, slow_targets or 0, *(m.n_targets for m in methods))
    held_out = fixed_targets(base, most, seed=TARGET_SEED)
    for level in levels:
        for m in methods:
            n = m.n_targets
            if m.n_targets >= FAST_TARGETS and n_targets is not None:
                n = n_targets
            elif m.n_targets < FAST_TARGETS and slow_targets is not None:
                n = slow_targets
            for req in (requests if m.per_request else (float(base.tolerance),)):
                key = {"env_id": env_id, "level": level, "method": m.name,
                       "request_tolerance_m": float(req)}
                if done is not None and done(key):
                    continue
                yield frontier_row(env_id, level, m, req, held_out[:n], seed)


# ---- the methods -------------------------------------------------------------------------------

def policy_method(folder: Path, name: str | None = None) -> Method:
    """A policy folder, closed loop (:func:`~agents.rl.evaluation.evaluate.rollout`): the env's
    stop at the request changes what it fires, so it is run at every request (a request-conditioned
    policy also sees the request)."""
    from ..rl.artefacts.policy_files import PolicyError, load_policy

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        try:
            policy = load_policy(folder, config)
        except PolicyError:   # a policy that does not read the request: its own scene's
            policy = load_policy(folder)
        return rollout(policy, targets, config, seed=seed)

    return Method(name or folder.name, run)


def env_actor_rollout(choose: Callable[[Any, np.ndarray], np.ndarray], config: Any,
                      targets: np.ndarray, seed: int) -> dict:
    """One episode per target on ``config``'s batched env (sub-env ``i`` seeded ``seed + i``),
    each firing chosen by ``choose(env, live)`` from the env's parts (``live``: the sub-envs
    whose first episode has not ended)."""
    env = batched_env(config, len(targets))
    live = np.ones(len(targets), bool)

    class Actor:
        def act(self, obs: np.ndarray) -> np.ndarray:
            return choose(env, live.copy())

    def track(env: Any, src: dict, new: np.ndarray, done: np.ndarray) -> None:
        live[:] = ~done

    plane = targets.ndim == 2
    try:
        ep = run_episodes(env, Actor(), seed, {"target": targets}, on_step=track)
    finally:
        env.close()
    f = ep.final
    return {"error_m": f["distance_m" if plane else "position_error_m"],
            "outcome": f["outcome"], "time_s": f["sim_time_s"]}


def staged_method() -> Method:
    """MicroConveyor-v1's staged expert (:class:`agents.mpc.staged.StagedExpert`) on its nominal
    model, firing on the env's parts."""
    from ..mpc.staged import StagedExpert

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        expert = StagedExpert(nominal(config))
        return env_actor_rollout(lambda env, live: expert.act(env.conveyor.parts, rows=live)[0],
                                 config, targets, seed)

    return Method("staged_expert", run)


def plane_controller_method() -> Method:
    """The plane's one-step controller (:class:`agents.planning.plane.PlaneController`)."""
    from ..planning.plane import PlaneController

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        ctl = PlaneController(nominal(config))
        return env_actor_rollout(lambda env, live: ctl.act(env, live)[0], config, targets, seed)

    return Method("plane_controller", run)


def mpc_method(name: str, settings: Any, prior: Path | None = None,
               n_targets: int = SLOW_TARGETS) -> Method:
    """Model-predictive control (:class:`agents.mpc.harness.MPCRollout`, one worker): the env's
    stop at the request ends its re-planning, so it is run at every request."""
    from ..mpc.harness import MPCRollout

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        with MPCRollout(settings, prior=None if prior is None else str(prior)) as roll:
            return roll(config, targets, seed)

    return Method(name, run, n_targets=n_targets)


def takes_time_weight() -> bool:
    """Whether :func:`agents.openloop.target.solve_target` searches a time-weighted cost."""
    from ..openloop.target import solve_target

    return "time_weight" in inspect.signature(solve_target).parameters


def de_method(time_weight: float | None = None, budget: int = DE_BUDGET,
              n_targets: int = DE_TARGETS) -> Method:
    """Differential evolution per target on the nominal model (``time_weight`` [1/s]: the
    time-weighted cost at the request, else |error| alone at the tightest request, where every
    firing of a plan that misses it is scored), each plan then replayed unchanged in the row's
    config: the env's stop at the request decides which of its firings are fired, so it is run
    at every request (precision-only DE searches once)."""
    from ..openloop.target import plans_rollout, solve_target

    # the rows share the searches: (tolerance, target, i) -> (plan, search wall time [s])
    searched: dict[tuple[float, float, int], tuple[np.ndarray, float]] = {}

    def plan(model: Any, target: float, i: int) -> tuple[np.ndarray, float]:
        key = (float(model.tolerance), target, i)
        if key not in searched:
            kw: dict[str, Any] = {} if time_weight is None else {"time_weight": time_weight}
            r = solve_target(target, "de", budget, seed=i, config=model, **kw)
            searched[key] = (r.plan, r.wall_time_s)
        return searched[key]

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        model = nominal(config)
        if time_weight is None:
            model = dataclasses.replace(model, tolerance=min(REQUESTS))
        found = [plan(model, float(t), i) for i, t in enumerate(targets)]
        t0 = time.perf_counter()
        out = plans_rollout(np.stack([p for p, _ in found]))(config, targets, seed)
        out["compute_s"] = sum(w for _, w in found) + time.perf_counter() - t0
        return out

    name = "de" if time_weight is None else f"de_time_weighted_{time_weight:g}"
    return Method(name, run, n_targets=n_targets)


def methods_for(env_id: str, names: list[str] | None = None,
                policy_root: Path = POLICY_ROOT) -> list[Method]:
    """The methods of ``env_id``'s scene that exist now (shipped policy folders, the model-based
    controllers, DE, time-weighted DE where :func:`solve_target` takes ``time_weight``), only
    ``names`` if given (an unknown name is a ValueError listing the known)."""
    from ..mpc.control import MPCSettings, OneStepSettings

    out: list[Method] = []
    folder = policy_root / env_id
    if folder.is_dir():
        out += [policy_method(p) for p in sorted(folder.iterdir())
                if (p / "model.zip").is_file() and not p.name.startswith("ppo_randomised")
                and (env_id != "MicroConveyor-v1" or p.name != "ppo")]
    if env_id == "MicroConveyor-v1":
        out.append(staged_method())
        out.append(mpc_method("mpc_de", MPCSettings(method="de")))
        prior = folder / "ppo_refined"
        if (prior / "model.zip").is_file():
            out.append(mpc_method("mpc_newton", MPCSettings(method="newton"), prior))
        out.append(de_method())
        if takes_time_weight():
            out.append(de_method(TIME_WEIGHT))
    elif env_id == "MicroPositioner-v0":
        out.append(mpc_method("mpc_one_step", OneStepSettings(), n_targets=100))
        out.append(de_method())
        if takes_time_weight():
            out.append(de_method(TIME_WEIGHT))
    elif env_id.startswith("MicroConveyor2D"):
        out.append(plane_controller_method())
    if names is not None:
        known = {m.name for m in out}
        unknown = sorted(set(names) - known)
        if unknown:
            raise ValueError(f"methods {unknown} are not available for {env_id}: known "
                             f"{sorted(known)}")
        out = [m for m in out if m.name in names]
    return out


# ---- the table ---------------------------------------------------------------------------------

def _pct(v: Any) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def _ms(v: Any) -> str:
    return "–" if v is None else f"{1e3 * v:.1f}"


def _um(v: Any) -> str:
    return "–" if v is None else f"{1e6 * v:.1f}"


def frontier_table(data: dict[str, Any]) -> str:
    """The stored frontier JSON (``{"env_id", "rows": [...]}``) as a markdown table, one line per
    row: level, method, request [µm], targets, the shares within ±50/20/10/5 µm, median and p90
    |error| [µm], detached, median and p90 placement time [ms], wall time per target [s]."""
    head = ("| level | method | request [µm] | targets | ±50 µm | ±20 µm | ±10 µm | ±5 µm | "
            "median error [µm] | p90 error [µm] | detached | median time [ms] | p90 time [ms] | "
            "wall per target [s] |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    rows = data.get("rows", [])
    levels = [*LEVELS, *dict.fromkeys(r["level"] for r in rows)]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for r in sorted(rows, key=lambda r: (levels.index(r["level"]), methods.index(r["method"]),
                                         -r["request_tolerance_m"])):
        lines.append(
            f"| {r['level']} | {r['method']} | {1e6 * r['request_tolerance_m']:g} | "
            f"{r['n_targets']} | " + " | ".join(_pct(r.get(f"success_rate_{k}um"))
                                               for k in (50, 20, 10, 5))
            + f" | {_um(r.get('median_abs_error_m'))} | {_um(r.get('p90_abs_error_m'))} | "
            f"{_pct(r.get('detach_rate'))} | {_ms(r.get('median_placement_time_s'))} | "
            f"{_ms(r.get('p90_placement_time_s'))} | {r.get('wall_s_per_target', 0.0):.3g} |")
    return "\n".join(lines) + "\n"
