"""What a training run does between its updates: checkpoints and fixed-target evaluations at step
intervals, and the wall-time budget (:class:`Periodic`)."""
from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from ..artefacts import checkpoint, normalization
from ..artefacts.actor_net import actor_of_model
from ..artefacts.checkpoint import MODEL, NORMALIZATION
from ..evaluation.evaluate import Policy, evaluate
from .settings import TrainSettings

Log = Callable[[str], None]


class Periodic(BaseCallback):
    """Checkpoints and fixed-target evaluations at step intervals, with the wall-time budget."""

    def __init__(self, out: Path, cfg: Any, settings: TrainSettings, run_meta: dict,
                 wall_before: float, log: Log | None = None,
                 on_eval: Callable[[dict], None] | None = None):
        super().__init__()
        self.out, self.cfg, self.settings, self.run_meta = out, cfg, settings, run_meta
        self.log, self.on_eval = log, on_eval
        self.max_seconds = settings.max_seconds
        self.checkpoint_freq, self.eval_freq = settings.checkpoint_freq, settings.eval_freq
        self.eval_targets, self.eval_seed = settings.eval_targets, settings.eval_seed
        self.t_start, self.wall_before = time.perf_counter(), wall_before
        self.next_ckpt = self.next_eval = 0
        self.last_eval: dict = {}

    def _on_training_start(self) -> None:
        n = self.model.num_timesteps
        self.next_ckpt = n + self.checkpoint_freq
        self.next_eval = (n // self.eval_freq + 1) * self.eval_freq if self.eval_freq else 0

    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.t_start

    def _on_step(self) -> bool:
        n = self.model.num_timesteps
        if self.eval_freq and n >= self.next_eval:
            self.next_eval += self.eval_freq
            res = self.run_eval()
            if self.on_eval:
                self.on_eval(res)
        if self.checkpoint_freq and n >= self.next_ckpt:
            self.next_ckpt += self.checkpoint_freq
            self.save_checkpoint({})
        return self.max_seconds is None or self.wall() < self.max_seconds

    def save_checkpoint(self, extra: dict) -> Path:
        n = int(self.model.num_timesteps)
        meta = {**self.run_meta, "wall_time_s": self.wall(), **extra}
        gen = checkpoint.write_generation(self.out, n, meta, lambda d: write_model(self.model, d))
        if self.log:
            self.log(f"checkpoint: step {n} saved ({gen.relative_to(self.out)})")
        return gen

    def run_eval(self) -> dict:
        vn = self.model.get_env()
        norm = (normalization.obs_normalizer(normalization.stats_of(vn))
                if isinstance(vn, VecNormalize) else None)
        pol = Policy(actor_of_model(self.model), norm, {}, self.out)
        res = evaluate(pol, self.eval_targets, self.eval_seed, config=self.cfg)
        res.update(steps=int(self.model.num_timesteps), wall_time_s=self.wall())
        for k in ("success_rate_50um", "success_rate_100um", "success_rate_250um",
                  "median_abs_error_m", "detach_rate"):
            self.logger.record(f"eval/{k}", res[k])
        with open(self.out / "evaluations.jsonl", "a") as fh:
            fh.write(json.dumps(res) + "\n")
        if self.log:
            self.log(f"eval: step {res['steps']:,}, {res['wall_time_s']:.0f} s: within ±50/100/250 "
                     f"µm {res['success_rate_50um']:.0%}/{res['success_rate_100um']:.0%}/"
                     f"{res['success_rate_250um']:.0%}, median |error| "
                     f"{res['median_abs_error_m'] * 1e6:.1f} µm")
        self.last_eval = res
        return res


def write_model(model: BaseAlgorithm, folder: Path) -> None:
    model.save(folder / MODEL)
    env = model.get_env()
    if isinstance(env, VecNormalize):
        normalization.write(env, folder / NORMALIZATION)
