"""DAgger on MicroPositioner-v0: a policy network that imitates the one-step model-based expert
(:mod:`agents.mpc.positioner`) on the states the policy itself visits, saved as a policy folder that loads as
data like every trained policy.

Each round plays ``episodes`` episodes at once on the batched env with the training's
per-episode randomisation (round 0 with the expert acting, later rounds with the policy), asks
the expert what it would fire from every state visited (it sees where the part rests and the
target, never the episode's friction, mass or noise), adds those pairs to the data set, and fits
the policy network to the whole set (mean squared error on the action). Ross, Gordon and
Bagnell's DAgger (2011): the policy learns the expert's answers on its own mistakes, which
behaviour cloning from the expert's episodes alone never shows it.

The network is SB3 PPO's actor (``MlpPolicy``, tanh, ``net_arch``), trained in place inside a PPO
model with observation normalisation (VecNormalize's formula, statistics of the data set,
frozen), so the result is an ordinary PPO policy folder: ``model.zip``, ``normalization.json``
and ``metadata.json`` (``trained_by: "dagger"``, the expert, every round's figures), which
``evaluate``, ``compare`` and ``video`` load as data (:mod:`agents.rl.artefacts.policy_files`). It acts in
one forward pass; the expert needs ~10^3 model firings per decision.
"""
from __future__ import annotations

import dataclasses
import json
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.envs.versions import check_env_id, scene_config

from ..mpc.positioner import BatchExpert

ENV_ID = "MicroPositioner-v0"
# the training's per-episode randomisation: the level the policy is meant to hold
TRAIN_KWARGS = {"action_noise": 3e-3, "friction_factor_range": (0.95, 1.05),
                "mass_factor_range": (0.95, 1.05)}
NO_FIRING = np.array([1.0, -1.0, -1.0], np.float32)  # the weakest firing of a far actuator


@dataclass(frozen=True)
class DaggerSettings:
    """``env_id`` (a positioner id) with ``env_kwargs`` (``gym.make`` overrides, SI; default:
    :data:`TRAIN_KWARGS`); ``seed`` [-]; ``rounds`` [-] (round 0: the expert acts);
    ``episodes`` [-] per round; ``net_arch`` [-] hidden layer widths; ``epochs`` [-] passes
    over the whole data set after each round; ``batch_size`` [-]; ``learning_rate`` [-] (Adam);
    ``frequencies``, ``strokes`` [-], ``margin`` [-], ``slack_m`` [m], ``heavier`` [-]: the
    expert's candidate grid, its margins from detachment (grid cells; a part that much heavier)
    and how much farther a gentler firing may land
    (:class:`~agents.mpc.positioner.BatchExpert`); ``lr_decay`` [-]: the learning rate is multiplied by it
    after every round."""

    env_id: str = ENV_ID
    env_kwargs: dict[str, Any] = field(default_factory=lambda: dict(TRAIN_KWARGS))
    seed: int = 0
    rounds: int = 10
    episodes: int = 256
    net_arch: tuple[int, ...] = (256, 256)
    epochs: int = 30
    batch_size: int = 256
    learning_rate: float = 1e-3
    frequencies: int = 41
    strokes: int = 6
    margin: int = 2
    slack_m: float = 5e-6
    heavier: float = 0.1
    lr_decay: float = 0.7

    def __post_init__(self) -> None:
        check_env_id(self.env_id)
        for name, least in (("seed", 0), ("rounds", 1), ("episodes", 1), ("epochs", 1),
                            ("batch_size", 1), ("frequencies", 2), ("strokes", 2),
                            ("margin", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} = {v!r} is invalid: must be an integer >= {least}")
        if not self.net_arch or any(not isinstance(w, int) or w < 1 for w in self.net_arch):
            raise ValueError(f"net_arch = {self.net_arch!r} is invalid: positive widths")
        for name in ("learning_rate", "lr_decay"):
            v = getattr(self, name)
            if not (isinstance(v, float) and 0.0 < v <= 1.0) or v == 1.0 and name != "lr_decay":
                raise ValueError(f"{name} = {v!r} is invalid: must be in (0, 1)")
        if not (isinstance(self.heavier, float) and 0.0 <= self.heavier <= 1.0):
            raise ValueError(f"heavier = {self.heavier!r} is invalid: must be in [0, 1]")
        if not (isinstance(self.slack_m, float) and 0.0 <= self.slack_m < 1e-3):
            raise ValueError(f"slack_m = {self.slack_m!r} is invalid: must be in [0, 1e-3) m")

    def config(self) -> PositionerConfig:
        cfg = scene_config(self.env_id, **self.env_kwargs)
        if not isinstance(cfg, PositionerConfig):
            raise ValueError(f"{self.env_id} is not a positioner: DAgger's expert plans firings "
                             "of any actuator to rest (MicroPositioner-v0)")
        return cfg


def _play(venv: MicroPositionerVectorEnv, expert: BatchExpert, act: Any,
          seed: int) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """One episode per sub-env: ``act(obs)`` fires (None: the expert); every state visited
    before a firing is labelled with the expert's action. Returns (observations, labels,
    figures of the episodes)."""
    n = venv.num_envs
    obs, _ = venv.reset(seed=seed)
    done = np.zeros(n, bool)
    err = np.zeros(n)
    outcome = np.empty(n, dtype=object)
    X, Y = [], []
    firings = 0
    while not done.all():
        live = ~done
        label, ok = expert.act(venv.x.copy(), venv.t.copy(), venv.target.copy())
        keep = live & ok
        X.append(obs[keep].copy())
        Y.append(label[keep])
        a = label.copy() if act is None else np.asarray(act(obs), np.float32)
        if act is None:
            a[~ok] = NO_FIRING
        obs, _, term, trunc, info = venv.step(a)
        firings += int(live.sum())
        end = live & (term | trunc)
        err[end] = info["position_error_m"][end]
        outcome[end] = info["outcome"][end]
        done |= end
    hit = (outcome == "rest") & (np.abs(err) <= venv.config.tolerance)
    return np.concatenate(X), np.concatenate(Y), {
        "episodes": n, "firings": firings, "success_rate": float(hit.mean()),
        "median_abs_error_m": float(np.median(np.abs(err))),
        "detach_rate": float(np.mean(outcome == "detached"))}


class Student:
    """SB3 PPO's actor inside a PPO model, fitted by regression (module docstring)."""

    def __init__(self, s: DaggerSettings, cfg: PositionerConfig) -> None:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import VecNormalize

        from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

        torch.manual_seed(s.seed)
        self.venv = VecNormalize(MicroConveyorSB3VecEnv(1, config=cfg), norm_obs=True,
                                 norm_reward=False, training=False)
        arch = list(s.net_arch)
        self.model = PPO("MlpPolicy", self.venv, seed=s.seed, device="cpu", verbose=0,
                         policy_kwargs={"net_arch": {"pi": arch, "vf": [64, 64]},
                                        "log_std_init": -3.0})
        pol = self.model.policy
        self.params = [*pol.mlp_extractor.policy_net.parameters(), *pol.action_net.parameters()]
        self.opt = torch.optim.Adam(self.params, lr=s.learning_rate)
        self.rng = np.random.default_rng(s.seed)
        self.s = s

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        out = self.venv.normalize_obs(obs.astype(np.float32))
        assert isinstance(out, np.ndarray)   # a Box observation
        return out

    def set_stats(self, X: np.ndarray) -> None:
        rms = self.venv.obs_rms
        assert not isinstance(rms, dict)      # a Box observation
        rms.mean, rms.var, rms.count = X.mean(0).astype(np.float64), \
            X.var(0).astype(np.float64), float(len(X))

    def forward(self, obs_n: Any) -> Any:
        pol = self.model.policy
        return pol.action_net(pol.mlp_extractor.policy_net(obs_n))

    def fit(self, X: np.ndarray, Y: np.ndarray) -> float:
        import torch

        xs = torch.as_tensor(self.normalise(X))
        ys = torch.as_tensor(Y, dtype=torch.float32)
        n, bs = len(xs), self.s.batch_size
        loss_v = 0.0
        for _ in range(self.s.epochs):
            order = torch.as_tensor(self.rng.permutation(n))
            for k in range(0, n, bs):
                idx = order[k:k + bs]
                loss = ((self.forward(xs[idx]) - ys[idx]) ** 2).mean()
                self.opt.zero_grad()
                loss.backward()
                self.opt.step()
                loss_v = loss.item()
        return loss_v

    def act(self, obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            a = self.forward(torch.as_tensor(self.normalise(obs))).numpy()
        return np.clip(a, -1.0, 1.0)

    def save(self, out: Path, meta: dict[str, Any]) -> None:
        from ..rl.artefacts import normalization
        from ..rl.artefacts.checkpoint import META, MODEL, NORMALIZATION, sha256

        out.mkdir(parents=True, exist_ok=True)
        self.model.save(out / MODEL)
        normalization.write(self.venv, out / NORMALIZATION)
        meta = {**meta, "files": {n: sha256(out / n) for n in (MODEL, NORMALIZATION)}}
        (out / META).write_text(json.dumps(meta, indent=2, default=str) + "\n")


def dagger(out: str | Path, s: DaggerSettings | None = None, progress: Any = print,
           command: str | None = None) -> dict:
    """Train by DAgger (module docstring) into the policy folder ``out``; returns its metadata.
    ``progress(line)`` is told each round's figures; ``command``: the command line that ran it
    (recorded in the metadata)."""
    import torch

    s = s or DaggerSettings()
    cfg = s.config()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    venv = MicroPositionerVectorEnv(s.episodes, config=dataclasses.replace(cfg, num_threads=1))
    expert = BatchExpert(cfg, s.frequencies, s.strokes, s.margin, s.slack_m, s.heavier)
    student = Student(s, cfg)
    X = np.zeros((0, venv.conveyor.obs_dim), np.float32)
    Y = np.zeros((0, 3), np.float32)
    rounds, steps = [], 0
    for r in range(s.rounds):
        xr, yr, fig = _play(venv, expert, None if r == 0 else student.act,
                            seed=s.seed * 1_000_003 + r * s.episodes)
        steps += fig["firings"]
        X, Y = np.concatenate([X, xr]), np.concatenate([Y, yr])
        if r == 0:
            student.set_stats(X)   # the observation statistics of the expert's own states
        loss = student.fit(X, Y)
        for group in student.opt.param_groups:
            group["lr"] *= s.lr_decay
        fig.update(round=r, acting="expert" if r == 0 else "policy", samples=int(len(X)),
                   loss=loss, wall_time_s=time.perf_counter() - t0)
        rounds.append(fig)
        progress(f"round {r} ({fig['acting']} acting): {fig['success_rate']:.0%} within "
                 f"±{cfg.tolerance * 1e6:.0f} µm, median {fig['median_abs_error_m'] * 1e6:.1f} µm, "
                 f"detached {fig['detach_rate']:.0%}; {len(X):,} samples, loss {loss:.4f}, "
                 f"{fig['wall_time_s']:.0f} s")
    wall = time.perf_counter() - t0
    env_kwargs = {k: list(v) if isinstance(v, tuple) else v for k, v in s.env_kwargs.items()}
    # portable inference: an episode of many firings amplifies torch's CPU-specific float32
    # rounding into other trajectories, so the policy is evaluated with the same bits everywhere
    meta = {"format": 2, "env_id": s.env_id, "algo": "ppo", "trained_by": "dagger",
            "inference": "portable",
            "env_kwargs": env_kwargs, "seed": s.seed, "steps": int(steps),
            "wall_time_s": wall, "hyperparams": {**dataclasses.asdict(s), "env_kwargs":
                                                  env_kwargs},
            "expert": {"kind": "one-step model-based, nominal model, the gentlest firing within "
                               "the slack of the nearest",
                       "frequencies": s.frequencies, "strokes": s.strokes,
                       "margin": s.margin, "slack_m": s.slack_m, "heavier": s.heavier},
            "command": command, "rounds": rounds, "machine": {"cpu_count": os.cpu_count(),
                                          "processor": platform.processor()},
            "note": "A policy network trained by DAgger to imitate the one-step model-based "
                    "controller on the nominal model (it never sees an episode's friction, "
                    "mass or noise), under the per-episode randomisation in env_kwargs; one "
                    "forward pass per firing."}
    student.save(Path(out), meta)
    return meta
