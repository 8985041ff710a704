"""Loading a saved PPO policy (model + VecNormalize statistics) and evaluating it on a fixed,
seeded set of targets with the batched env."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig

MODEL, STATS, META = "model.zip", "vecnormalize.pkl", "metadata.json"
TOLERANCES = (50e-6, 100e-6, 250e-6)


class PolicyError(ValueError):
    """A policy path that cannot be loaded or does not fit the env."""


@dataclass
class Policy:
    model: Any              # stable_baselines3 PPO
    obs_rms: Any            # RunningMeanStd of the observations (None: no normalization)
    clip_obs: float
    metadata: dict
    path: Path

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is not None:
            obs = np.clip((obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + 1e-8),
                          -self.clip_obs, self.clip_obs).astype(np.float32)
        action, _ = self.model.predict(obs, deterministic=True)
        return action


def load_policy(path, config: EnvConfig | None = None) -> Policy:
    """A policy folder (``model.zip``, ``vecnormalize.pkl``, optional ``metadata.json``) or a
    model zip with ``vecnormalize.pkl`` beside it; one clear :class:`PolicyError` otherwise."""
    import pickle

    from stable_baselines3 import PPO

    path = Path(path)
    folder, model_file = (path, path / MODEL) if path.is_dir() else (path.parent, path)
    if not model_file.is_file():
        raise PolicyError(f"no policy at {str(path)!r}: expected a folder with {MODEL} and "
                          f"{STATS}, or a model .zip")
    try:
        model = PPO.load(model_file, device="cpu")
    except Exception as exc:  # noqa: BLE001 - any unreadable file is the same user error
        raise PolicyError(f"{str(model_file)!r} is not a stable-baselines3 PPO model "
                          f"({type(exc).__name__}: {exc})") from None
    cfg = config or EnvConfig.from_yaml()
    from microconveyor_env.envs import task
    from microconveyor_env.envs.actions import ACTION_DIM

    obs_shape, act_shape = model.observation_space.shape, model.action_space.shape
    if obs_shape != (task.OBS_DIM,) or act_shape != (ACTION_DIM,):
        raise PolicyError(f"{str(model_file)!r} was trained for observations {obs_shape} and "
                          f"actions {act_shape}; MicroConveyor-v0 has ({task.OBS_DIM},) and "
                          f"({ACTION_DIM},)")
    obs_rms, clip_obs = None, 10.0
    stats = folder / STATS
    if not stats.is_file() and (folder / model_file.stem / STATS).is_file():
        stats = folder / model_file.stem / STATS  # rl-zoo3's layout: ENV_ID.zip + ENV_ID/
    if stats.is_file():
        with open(stats, "rb") as fh:
            vn = pickle.load(fh)
        if getattr(vn, "norm_obs", False):
            obs_rms, clip_obs = vn.obs_rms, vn.clip_obs
            if np.shape(obs_rms.mean) != (task.OBS_DIM,):
                raise PolicyError(f"{str(stats)!r} normalizes observations of shape "
                                  f"{np.shape(obs_rms.mean)}, not ({task.OBS_DIM},)")
    meta_file = folder / META
    meta = json.loads(meta_file.read_text()) if meta_file.is_file() else {}
    return Policy(model, obs_rms, clip_obs, meta, folder)


def fixed_targets(config: EnvConfig, n: int, seed: int) -> np.ndarray:
    lo, hi = config.target_range
    return np.random.default_rng(seed).uniform(lo, hi, n)


def rollout(policy, targets: np.ndarray, config: EnvConfig, seed: int = 0,
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


def evaluate(policy, n_targets: int = 100, seed: int = 0, tolerance: float | None = None,
             config: EnvConfig | None = None) -> dict:
    cfg = config or EnvConfig.from_yaml()
    targets = fixed_targets(cfg, n_targets, seed)
    res = rollout(policy, targets, cfg, seed=seed)
    out = summarize(res, cfg.tolerance if tolerance is None else tolerance)
    out.update(seed=seed, target_range_m=list(cfg.target_range))
    return out
