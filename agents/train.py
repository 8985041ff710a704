"""PPO (stable-baselines3) on the batched env through the SB3 adapter.

Hyperparameters from ``configs/ppo.yml`` (:mod:`.hyperparams`). During training: a progress
bar, tensorboard logs (``OUT/tb``), a checkpoint (model + VecNormalize + step count) every
``checkpoint_freq`` steps in ``OUT/checkpoint`` (``resume=True`` continues from it: at most one
checkpoint interval is lost) and an evaluation on a fixed seeded target set every ``eval_freq``
steps (success at +-50/100/250 um, logged to tensorboard and ``OUT/evaluations.jsonl``). At the
end ``OUT`` holds the final ``model.zip``, ``vecnormalize.pkl`` and ``metadata.json``.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ProgressBarCallback
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.sb3 import MicroConveyorSB3VecEnv

from . import hyperparams
from .evaluate import META, MODEL, STATS, Policy, evaluate

CHECKPOINT = "checkpoint"


class BudgetPPO(PPO):
    """PPO whose schedules (``lin_`` learning rate, clip range) run out with whichever budget
    ends first: the step count or the wall time (``budget_clock() -> fraction of the wall
    budget used``). So a run capped by ``--max-minutes`` on a busy machine still ends with a
    fully decayed learning rate, as the shipped policy's recipe expects."""

    budget_clock = None  # set by train(); not saved with the model
    # torch threads for the gradient updates (rollouts keep one). 2 gain 15 % on an idle 2-core
    # machine but fall to ~450 steps/s when the cores are busy (benchmarks/train_speed.py)
    update_threads = 1

    def _excluded_save_params(self) -> list:
        return [*super()._excluded_save_params(), "budget_clock", "update_threads"]

    def train(self) -> None:
        import torch

        before = torch.get_num_threads()
        torch.set_num_threads(self.update_threads)
        try:
            super().train()
        finally:
            torch.set_num_threads(before)

    def _update_current_progress_remaining(self, num_timesteps: int, total_timesteps: int) -> None:
        super()._update_current_progress_remaining(num_timesteps, total_timesteps)
        if self.budget_clock is not None:
            self._current_progress_remaining = max(0.0, min(
                self._current_progress_remaining, 1.0 - self.budget_clock()))


def config_hash(cfg: EnvConfig, hp: dict) -> str:
    import dataclasses

    blob = json.dumps({"env": dataclasses.asdict(cfg), "ppo": hp}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


class Periodic(BaseCallback):
    """Checkpoints and fixed-target evaluations at step intervals."""

    def __init__(self, out: Path, cfg: EnvConfig, checkpoint_freq: int, eval_freq: int,
                 eval_targets: int, eval_seed: int, t_start: float, wall_before: float,
                 max_seconds: float | None = None):
        super().__init__()
        self.max_seconds = max_seconds
        self.out, self.cfg = out, cfg
        self.checkpoint_freq, self.eval_freq = checkpoint_freq, eval_freq
        self.eval_targets, self.eval_seed = eval_targets, eval_seed
        self.t_start, self.wall_before = t_start, wall_before
        self.next_ckpt = self.next_eval = 0

    def _on_training_start(self):
        n = self.model.num_timesteps
        self.next_ckpt = n + self.checkpoint_freq
        self.next_eval = (n // self.eval_freq + 1) * self.eval_freq if self.eval_freq else 0

    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.t_start

    def _on_step(self) -> bool:
        n = self.model.num_timesteps
        if self.eval_freq and n >= self.next_eval:
            self.next_eval += self.eval_freq
            self.run_eval()
        if self.checkpoint_freq and n >= self.next_ckpt:
            self.next_ckpt += self.checkpoint_freq
            save(self.model, self.out / CHECKPOINT, {"steps": n, "wall_time_s": self.wall()})
        return self.max_seconds is None or self.wall() < self.max_seconds

    def run_eval(self) -> dict:
        vn = self.model.get_env()
        pol = Policy(self.model, vn.obs_rms, vn.clip_obs, {}, self.out)
        res = evaluate(pol, self.eval_targets, self.eval_seed, config=self.cfg)
        res.update(steps=int(self.model.num_timesteps), wall_time_s=self.wall())
        for k in ("success_rate_50um", "success_rate_100um", "success_rate_250um",
                  "median_abs_error_m", "detach_rate"):
            self.logger.record(f"eval/{k}", res[k])
        with open(self.out / "evaluations.jsonl", "a") as fh:
            fh.write(json.dumps(res) + "\n")
        return res


def save(model, folder: Path, meta: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / MODEL)
    model.get_env().save(str(folder / STATS))
    (folder / META).write_text(json.dumps(meta, indent=2))


def make_env(cfg: EnvConfig, hp: dict, seed: int):
    venv = MicroConveyorSB3VecEnv(int(hp.get("n_envs", 64)), config=cfg)
    venv.seed(seed)
    return VecMonitor(venv)


def train(out, steps: int | None = None, seed: int = 0, conf_file: str | None = None,
          config: EnvConfig | None = None, resume: bool = False, checkpoint_freq: int = 200_000,
          eval_freq: int = 250_000, eval_targets: int = 100, eval_seed: int = 12345,
          progress_bar: bool = True, tensorboard: bool = True, overrides: dict | None = None,
          max_minutes: float | None = None):
    """Train (or resume) PPO into ``out`` for ``steps`` (or until ``max_minutes`` of wall time,
    resumed runs included); returns the metadata written there."""
    import torch

    torch.set_num_threads(1)  # small nets: one thread is fastest, and 2 cores are shared with the env
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    hp = hyperparams.load(conf_file)
    hp.update(overrides or {})
    cfg = config or EnvConfig.from_yaml(**(hp.get("env_kwargs") or {}))
    total = int(steps if steps is not None else hp.get("n_timesteps", 1e6))
    norm = hp.get("normalize") or None
    ckpt = out / CHECKPOINT
    env = make_env(cfg, hp, seed)
    wall_before = 0.0
    if resume and (ckpt / MODEL).is_file():
        env = VecNormalize.load(str(ckpt / STATS), env) if (ckpt / STATS).is_file() else env
        model = BudgetPPO.load(ckpt / MODEL, env=env, device="cpu",
                         tensorboard_log=str(out / "tb") if tensorboard else None)
        wall_before = json.loads((ckpt / META).read_text()).get("wall_time_s", 0.0)
    else:
        if norm is not None:
            env = VecNormalize(env, **{"gamma": hp.get("gamma", 0.99), **norm})
        model = BudgetPPO(hp.get("policy", "MlpPolicy"), env, seed=seed, device="cpu", verbose=0,
                    tensorboard_log=str(out / "tb") if tensorboard else None,
                    **hyperparams.ppo_kwargs(hp))
    t0 = time.perf_counter()
    periodic = Periodic(out, cfg, checkpoint_freq, eval_freq, eval_targets, eval_seed, t0,
                        wall_before, None if max_minutes is None else 60.0 * max_minutes)
    if max_minutes is not None:
        budget_s = 60.0 * max_minutes
        model.budget_clock = lambda: periodic.wall() / budget_s
    callbacks = [periodic] + ([ProgressBarCallback()] if progress_bar else [])
    remaining = max(0, total - model.num_timesteps)
    model.learn(remaining, callback=CallbackList(callbacks), reset_num_timesteps=not resume,
                tb_log_name="ppo", progress_bar=False)
    wall = periodic.wall()
    final = periodic.run_eval() if eval_targets else {}
    meta = {"env_id": hyperparams.ENV_ID, "algo": "ppo", "config_hash": config_hash(cfg, hp),
            "seed": seed, "steps": int(model.num_timesteps), "wall_time_s": wall,
            "steps_per_s": model.num_timesteps / max(wall, 1e-9),
            "target_range_m": list(cfg.target_range), "hyperparams": hp,
            "evaluation": final}
    save(model, out, meta)
    save(model, ckpt, {"steps": int(model.num_timesteps), "wall_time_s": wall})
    return meta
