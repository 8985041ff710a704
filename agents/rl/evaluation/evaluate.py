"""Evaluating a policy on a fixed, seeded set of targets with the batched env (loading a policy
folder: :mod:`.policy_files`)."""
from __future__ import annotations

from typing import Protocol

import numpy as np

from microconveyor_env.envs import EnvConfig

from ..artefacts.policy_files import Policy, PolicyError, load_policy


class Actor(Protocol):
    """Anything with ``act(observations) -> actions`` (a loaded :class:`Policy`, a wrapper)."""

    def act(self, obs: np.ndarray) -> np.ndarray: ...

__all__ = ["Policy", "PolicyError", "load_policy", "fixed_targets", "rollout", "summarize",
           "evaluate", "TOLERANCES"]

TOLERANCES = (50e-6, 100e-6, 250e-6)


def fixed_targets(config: EnvConfig, n: int, seed: int) -> np.ndarray:
    lo, hi = config.target_range
    return np.random.default_rng(seed).uniform(lo, hi, n)


def rollout(policy: Actor, targets: np.ndarray, config: EnvConfig, seed: int = 0,
            record: bool = False) -> dict:
    """One episode per target (batched, deterministic policy): final errors, outcomes, times,
    firings (steps: fewer than the actuators when the part was delivered early or detached);
    with ``record`` the positions after each firing. With randomisation on in ``config``
    (docs/randomisation.md) also each episode's ``friction_factor`` and ``mass_factor``; sub-env
    ``i`` is seeded ``seed + i``."""
    from microconveyor_env.envs import MicroConveyorVectorEnv

    n = len(targets)
    env = MicroConveyorVectorEnv(n, config=config, autoreset_mode="SameStep")
    obs, _ = env.reset(seed=seed, options={"target": np.asarray(targets, float)})
    done = np.zeros(n, bool)
    err, outcome, t = np.full(n, np.nan), np.full(n, "", dtype=object), np.zeros(n)
    factors = {k: np.full(n, np.nan) for k in ("friction_factor", "mass_factor")}
    firings = np.zeros(n, dtype=int)
    path = [env.x.copy()]
    while not done.all():
        obs, _, term, trunc, info = env.step(policy.act(obs))
        src = info.get("final_info", info)
        new = (term | trunc) & ~done
        err[new] = src["position_error_m"][new]
        outcome[new] = src["outcome"][new]
        t[new] = src["sim_time_s"][new]
        for key, val in factors.items():
            if key in src:
                val[new] = src[key][new]
        firings[~done] += 1
        done |= term | trunc
        if record:
            x = np.where(done & ~new, path[-1], np.where(new, np.asarray(targets) + err, env.x))
            path.append(x)
    out = {"targets_m": np.asarray(targets, float), "error_m": err, "outcome": outcome,
           "time_s": t, "firings": firings}
    if config.randomised:
        out.update(factors)
    if record:
        out["path_m"] = np.array(path)
    return out


def summarize(res: dict, tolerance: float) -> dict:
    err, rest = np.abs(res["error_m"]), res["outcome"] == "rest"
    out = {"n_targets": int(len(err)), "tolerance_m": tolerance,
           "success_rate": float(np.mean(rest & (err <= tolerance))),
           "median_abs_error_m": float(np.median(err)),
           "detach_rate": float(np.mean(res["outcome"] == "detached"))}
    for tol in TOLERANCES:
        out[f"success_rate_{round(tol * 1e6)}um"] = float(np.mean(rest & (err <= tol)))
    return out


def evaluate(policy: Actor, n_targets: int = 100, seed: int = 0, tolerance: float | None = None,
             config: EnvConfig | None = None) -> dict:
    """Success and errors of ``policy`` on ``n_targets`` fixed targets drawn with ``seed`` from
    the target range of ``config`` (default: the scene a loaded :class:`Policy` was trained in,
    randomisation off; else MicroConveyor-v0's defaults); ``tolerance`` [m] of the success
    figure (default: the config's). Its keys are those of every evaluation, the plane's
    included (:func:`.evaluate_plane.plane_evaluation`): :func:`summarize`'s, the 90th
    percentile of the absolute error ``p90_abs_error_m``, ``rest_rate``, ``mean_firings``, the
    ``seed`` and the targets' ``target_range_m``."""
    cfg = config or getattr(policy, "config", None) or EnvConfig.from_yaml()
    targets = fixed_targets(cfg, n_targets, seed)
    res = rollout(policy, targets, cfg, seed=seed)
    out = summarize(res, cfg.tolerance if tolerance is None else tolerance)
    out.update(p90_abs_error_m=float(np.percentile(np.abs(res["error_m"]), 90)),
               rest_rate=float(np.mean(res["outcome"] == "rest")),
               mean_firings=float(np.mean(res["firings"])),
               seed=seed, target_range_m=list(cfg.target_range))
    return out
