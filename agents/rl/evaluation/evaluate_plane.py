"""Evaluating a policy on MicroConveyor2D-v0 (the plane, issue 22): fixed, seeded targets, one
episode each on the batched plane env, the deterministic policy.

Success is the env's own: the part at rest within ``tolerance`` (50 um) of the target, Euclidean.
The error of an episode is the Euclidean distance [m] from the target where it ended (at rest,
detached or cut by the time limit); the summary's median is over all episodes.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from microconveyor_env.envs.plane.config import PlaneEnvConfig

PLANE_TARGET_SEED = 2026   # the fixed targets of scripts/plane_agents.py and the shipped record
PLANE_TOLERANCES = (50e-6, 100e-6, 250e-6)   # [m] success radii reported


class Actor(Protocol):
    """Anything with ``act(observations) -> actions``."""

    def act(self, obs: np.ndarray) -> np.ndarray: ...


def plane_targets(config: PlaneEnvConfig, n: int, seed: int = PLANE_TARGET_SEED) -> np.ndarray:
    """``(n, 2)`` targets [m], uniform on the grid's box (x then y draws of one seeded
    generator, as scripts/plane_agents.py)."""
    if n < 1:
        raise ValueError(f"n = {n!r} targets: must be >= 1")
    (x0, x1), (y0, y1) = config.grid_box
    rng = np.random.default_rng(seed)
    return np.stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)], 1)


def plane_rollout(policy: Actor, targets: np.ndarray, config: PlaneEnvConfig,
                  seed: int = 0) -> dict[str, np.ndarray]:
    """One episode per target (batched, one thread): ``error_m`` (Euclidean distance at the end
    [m]), ``outcome``, ``success`` (the env's: at rest within its tolerance), ``firings``,
    ``targets_m``. Sub-env ``i`` is seeded ``seed + i``."""
    from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv

    targets = np.asarray(targets, dtype=float)
    if targets.ndim != 2 or targets.shape[1] != 2:
        raise ValueError(f"targets have shape {targets.shape}: must be (n, 2) [m]")
    n = len(targets)
    env = MicroConveyor2DVectorEnv(n, config=config)
    obs, _ = env.reset(seed=seed, options={"target": targets})
    live = np.ones(n, bool)
    err, outcome = np.full(n, np.nan), np.full(n, "", dtype=object)
    success, firings = np.zeros(n, bool), np.zeros(n, dtype=int)
    while live.any():
        obs, _, term, trunc, info = env.step(policy.act(obs))
        ended = live & (term | trunc)
        firings += live
        err = np.where(ended, info["distance_m"], err)
        outcome = np.where(ended, info["outcome"], outcome)
        success |= ended & np.asarray(info["is_success"], bool)
        live &= ~ended
    return {"targets_m": targets, "error_m": err, "outcome": outcome, "success": success,
            "firings": firings}


def plane_summary(res: dict, tolerance: float) -> dict:
    """Success rates (at rest within ``tolerance`` and the radii of :data:`PLANE_TOLERANCES`),
    median and 90th-percentile Euclidean error [m], detach and rest rates, mean firings."""
    err = np.asarray(res["error_m"], float)
    rest = np.asarray(res["outcome"], dtype=object) == "rest"
    out = {"n_targets": int(len(err)), "tolerance_m": float(tolerance),
           "success_rate": float(np.mean(rest & (err <= tolerance))),
           "median_error_m": float(np.median(err)),
           "p90_error_m": float(np.percentile(err, 90)),
           "rest_rate": float(np.mean(rest)),
           "detach_rate": float(np.mean(np.asarray(res["outcome"], dtype=object) == "detached"))}
    for tol in PLANE_TOLERANCES:
        out[f"success_rate_{round(tol * 1e6)}um"] = float(np.mean(rest & (err <= tol)))
    if "firings" in res:
        out["mean_firings"] = float(np.mean(res["firings"]))
    return out


# plane_summary's names (those of the stored records) -> the names of every evaluation (the
# line's agents.rl.evaluation.evaluate.evaluate): the Euclidean error is an absolute error
EVALUATION_NAMES = {"median_error_m": "median_abs_error_m", "p90_error_m": "p90_abs_error_m"}


def plane_evaluation(summary: dict) -> dict:
    """:func:`plane_summary`'s figures under the keys every evaluation uses, on the line and in
    the plane (``median_abs_error_m``, ``p90_abs_error_m``: of the Euclidean error); the
    ``evaluate`` command's JSON."""
    return {EVALUATION_NAMES.get(k, k): v for k, v in summary.items()}


def evaluate_plane(policy: Actor, config: PlaneEnvConfig, n_targets: int = 100,
                   seed: int = PLANE_TARGET_SEED) -> dict:
    """:func:`plane_summary` of ``policy`` on ``n_targets`` targets drawn with ``seed``."""
    res = plane_rollout(policy, plane_targets(config, n_targets, seed), config)
    return {**plane_summary(res, config.tolerance), "seed": seed}
