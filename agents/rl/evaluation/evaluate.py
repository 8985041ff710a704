"""Evaluating a policy on a fixed, seeded set of targets, one episode each on the batched env of
its scene, the line's or the plane's (loading a policy folder: :mod:`..artefacts.policy_files`).

The error of an episode is where the part ended minus the target [m]: signed on the line, the
Euclidean distance in the plane; success is the part at rest within the tolerance of the target.
The placement time of an episode is the simulated time until the part came to rest [s] (the env's
``sim_time_s``); it is reported over the episodes that ended at rest, beside the error.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from microconveyor_env.envs.core.episodes import Actor, run_episodes
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.rail.config import RailConfig

from ..artefacts.policy_files import Policy, PolicyError, bind_request, load_policy

__all__ = ["Policy", "PolicyError", "load_policy", "fixed_targets", "distance_targets", "rollout",
           "summarize", "figures", "placement_times", "evaluate", "evaluate_at", "TOLERANCES",
           "ADDED_FIGURES", "PLANE_TARGET_SEED", "DISTANCE_SPREAD_M"]

TOLERANCES = (5e-6, 10e-6, 20e-6, 50e-6, 100e-6, 250e-6)   # [m] success radii reported
# figures every evaluation reports that the shipped policies' stored records may lack (they were
# recorded before these were): a stored record without them is still whole where it is read
ADDED_FIGURES = ("success_rate_5um", "success_rate_10um", "success_rate_20um",
                 "median_placement_time_s", "p90_placement_time_s")
PLANE_TARGET_SEED = 2026   # the plane's default target seed (its shipped policy's record)
# the plane's stored records name two figures for the Euclidean error they are
PLANE_RECORD_NAMES = {"median_abs_error_m": "median_error_m", "p90_abs_error_m": "p90_error_m"}
DISTANCE_SPREAD_M = 0.1e-3   # [m] the targets of one distance d lie on d +- this (the answer table's)


def fixed_targets(config: RailConfig | PlaneEnvConfig, n: int, seed: int) -> np.ndarray:
    """``n`` targets [m] drawn with ``seed``: uniform on the line's target range ``(n,)``, or on
    the plane's grid box ``(n, 2)`` (x then y draws of one generator)."""
    rng = np.random.default_rng(seed)
    if isinstance(config, PlaneEnvConfig):
        if n < 1:
            raise ValueError(f"n = {n!r} targets: must be >= 1")
        (x0, x1), (y0, y1) = config.grid_box
        return np.stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)], 1)
    lo, hi = config.target_range
    return rng.uniform(lo, hi, n)


def distance_targets(config: RailConfig | PlaneEnvConfig, distances: Any,
                     per_distance: int) -> np.ndarray:
    """``per_distance`` targets [m] for each distance [m] of ``distances``, evenly spaced over
    d ± :data:`DISTANCE_SPREAD_M` and kept inside the target range (one target: d itself), shape
    ``(len(distances), per_distance)``. The line's and the positioner's targets only (a distance
    along the line); a distance outside the target range is a ValueError naming the range."""
    if isinstance(config, PlaneEnvConfig):
        raise ValueError("per-distance targets are distances along a line: the plane's targets "
                         "are points of its grid box (evaluate it on drawn targets)")
    if isinstance(per_distance, bool) or not isinstance(per_distance, (int, np.integer)) \
            or per_distance < 1:
        raise ValueError(f"per_distance = {per_distance!r}: must be a whole number >= 1")
    d = np.asarray(distances, float).reshape(-1)
    lo, hi = (float(v) for v in config.target_range)
    bad = d[~(np.isfinite(d) & (d >= lo) & (d <= hi))]
    if not len(d) or len(bad):
        raise ValueError(f"distances {[float(v) for v in bad] or '(none)'} m: each must lie in "
                         f"the target range, {lo * 1e3:g} to {hi * 1e3:g} mm")
    offsets = (np.linspace(-DISTANCE_SPREAD_M, DISTANCE_SPREAD_M, per_distance)
               if per_distance > 1 else np.zeros(1))
    return np.clip(d[:, None] + offsets[None, :], lo, hi)


def batched_env(config: RailConfig | PlaneEnvConfig, n: int) -> Any:
    """The batched env of ``config``'s scene with ``n`` sub-envs, same-step autoreset."""
    from microconveyor_env.envs.core.versions import vector_class_of

    return vector_class_of(config)(n, config=config, autoreset_mode="SameStep")


def rollout(policy: Actor, targets: np.ndarray, config: RailConfig | PlaneEnvConfig,
            seed: int = 0, record: bool = False) -> dict:
    """One episode per target (batched, deterministic policy): final errors ``error_m`` [m]
    (module docstring), ``outcome``, ``success`` (the env's), ``time_s``, ``firings`` (fewer
    than the actuators when the part was delivered early or detached); on the line with
    ``record`` the positions after each firing ``path_m``. With randomisation on in ``config``
    (docs/randomisation.md; the line's or the plane's) also each episode's ``friction_factor``
    and ``mass_factor``; sub-env ``i`` is seeded ``seed + i`` (its randomisation draws derive
    from that seed)."""
    policy = bind_request(policy, config)   # a request-conditioned one: for config.tolerance
    targets = np.asarray(targets, float)
    plane = isinstance(config, PlaneEnvConfig)
    if plane and (targets.ndim != 2 or targets.shape[1] != 2):
        raise ValueError(f"targets have shape {targets.shape}: must be (n, 2) [m]")
    env = batched_env(config, len(targets))
    path: list[np.ndarray] | None = [] if record and not plane else None

    def trace(env: Any, src: dict[str, Any], new: np.ndarray, done: np.ndarray) -> None:
        if path is not None:
            end = targets + src["position_error_m"]
            path.append(np.where(done & ~new, path[-1], np.where(new, end, env.x)))

    try:
        if path is not None:
            env.reset(seed=seed, options={"target": targets})
            path.append(env.x.copy())
        ep = run_episodes(env, policy, seed, {"target": targets}, on_step=trace)
    finally:
        env.close()
    f = ep.final
    out = {"targets_m": targets, "error_m": f["distance_m" if plane else "position_error_m"],
           "outcome": f["outcome"], "success": f["is_success"], "time_s": f["sim_time_s"],
           "firings": ep.firings}
    if config.randomised:
        out.update({k: f.get(k, np.full(len(targets), np.nan))
                    for k in ("friction_factor", "mass_factor")})
    if path is not None:
        out["path_m"] = np.array(path)
    return out


def summarize(res: dict, tolerance: float) -> dict:
    """Success within ``tolerance`` [m] and the radii of :data:`TOLERANCES` (at rest), median
    absolute error [m], detach rate."""
    err, rest = np.abs(np.asarray(res["error_m"], float)), np.asarray(res["outcome"]) == "rest"
    out = {"n_targets": int(len(err)), "tolerance_m": float(tolerance),
           "success_rate": float(np.mean(rest & (err <= tolerance))),
           "median_abs_error_m": float(np.median(err)),
           "detach_rate": float(np.mean(np.asarray(res["outcome"]) == "detached"))}
    for tol in TOLERANCES:
        out[f"success_rate_{round(tol * 1e6)}um"] = float(np.mean(rest & (err <= tol)))
    return out


def placement_times(time_s: Any, outcome: Any) -> dict:
    """The time to rest over the episodes that ended at rest (outcome ``"rest"``; a detached
    part never arrives): ``median_placement_time_s`` and ``p90_placement_time_s`` (the 90th
    percentile) [s], both None when no episode ended at rest."""
    t = np.asarray(time_s, float).reshape(-1)
    rest = np.asarray(outcome).reshape(-1) == "rest"
    if len(t) != len(rest):
        raise ValueError(f"{len(t)} times for {len(rest)} outcomes: one of each per episode")
    if not rest.any():
        return {"median_placement_time_s": None, "p90_placement_time_s": None}
    return {"median_placement_time_s": float(np.median(t[rest])),
            "p90_placement_time_s": float(np.percentile(t[rest], 90))}


def figures(res: dict, tolerance: float) -> dict:
    """:func:`summarize`'s figures plus the 90th percentile of the absolute error
    ``p90_abs_error_m``, the placement times (:func:`placement_times`, where ``res`` holds the
    episodes' ``time_s``: a stored record of errors alone has none), ``rest_rate`` and
    ``mean_firings``: those of every evaluation."""
    err = np.abs(np.asarray(res["error_m"], float))
    out = {**summarize(res, tolerance), "p90_abs_error_m": float(np.percentile(err, 90))}
    if "time_s" in res:
        out.update(placement_times(res["time_s"], res["outcome"]))
    return {**out, "rest_rate": float(np.mean(np.asarray(res["outcome"]) == "rest")),
            "mean_firings": float(np.mean(res["firings"]))}


def plane_record(summary: dict) -> dict:
    """:func:`figures` under the names of the plane's stored records (``median_error_m``,
    ``p90_error_m``)."""
    return {PLANE_RECORD_NAMES.get(k, k): v for k, v in summary.items()}


def from_plane_record(record: dict) -> dict:
    """A stored plane record under the names every evaluation uses."""
    back = {v: k for k, v in PLANE_RECORD_NAMES.items()}
    return {back.get(k, k): v for k, v in record.items()}


def evaluate(policy: Actor, n_targets: int = 100, seed: int = 0, tolerance: float | None = None,
             config: RailConfig | PlaneEnvConfig | None = None) -> dict:
    """Success and errors of ``policy`` on ``n_targets`` fixed targets drawn with ``seed``
    (:func:`fixed_targets`) in ``config``; ``tolerance`` [m] of the success figure (default:
    the config's). The keys of :func:`figures`, the ``seed`` and the targets' ``target_range_m``
    (line) or ``target_box_m`` (plane).

    ``config`` defaults to the env a loaded :class:`Policy` was trained on, **its per-episode
    randomisation included** (``Policy.trained_config``: its metadata's env id and env kwargs),
    as ``microconveyor evaluate --policy DIR`` does and as the shipped policies' recorded
    ``evaluation`` and ``evaluation_fresh`` were computed; pass ``config=policy.config`` for the
    same scene with randomisation off. An actor that names no env (not a loaded policy) needs
    ``config``."""
    cfg = config or getattr(policy, "trained_config", None) or getattr(policy, "config", None)
    if cfg is None:
        raise ValueError("evaluate: the policy names no env it was trained on; pass config=")
    res = rollout(policy, fixed_targets(cfg, n_targets, seed), cfg, seed=seed)
    out = figures(res, cfg.tolerance if tolerance is None else tolerance)
    out["seed"] = seed
    if isinstance(cfg, PlaneEnvConfig):
        out["target_box_m"] = [list(b) for b in cfg.grid_box]
    else:
        out["target_range_m"] = list(cfg.target_range)
    return out


def evaluate_at(policy: Actor, distances: Any, per_distance: int = 5, seed: int = 0,
                tolerance: float | None = None,
                config: RailConfig | PlaneEnvConfig | None = None) -> dict:
    """:func:`evaluate` on targets at given distances [m] (:func:`distance_targets`:
    ``per_distance`` targets over each d ± 0.1 mm), in the same env by default. The figures of
    every target together, and ``per_distance``: one row per distance with ``distance_m``, its
    ``targets_m`` and the figures of its targets. Sub-env ``i`` is seeded ``seed + i``."""
    cfg = config or getattr(policy, "trained_config", None) or getattr(policy, "config", None)
    if cfg is None:
        raise ValueError("evaluate: the policy names no env it was trained on; pass config=")
    grid = distance_targets(cfg, distances, per_distance)
    assert isinstance(cfg, RailConfig)   # the line's or the positioner's: distance_targets refuses the plane
    tol = cfg.tolerance if tolerance is None else tolerance
    res = rollout(policy, grid.reshape(-1), cfg, seed=seed)
    n = grid.shape[1]
    rows = []
    for k, d in enumerate(np.asarray(distances, float).reshape(-1)):
        part = {key: np.asarray(v)[k * n:(k + 1) * n] for key, v in res.items()
                if key in ("error_m", "outcome", "firings", "time_s")}
        rows.append({"distance_m": float(d), "targets_m": grid[k].tolist(), **figures(part, tol)})
    return {**figures(res, tol), "seed": seed, "targets_per_distance": n,
            "target_range_m": list(cfg.target_range), "per_distance": rows}
