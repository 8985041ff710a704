"""Training PPO, SAC or TQC (:mod:`.algos`) on the conveyor.

Hyperparameters from ``configs/<algo>.yml`` (:mod:`.hyperparams`). During training: a progress
bar, tensorboard logs (``OUT/tb``), one line per checkpoint and per evaluation (through ``log``),
a checkpoint generation every ``checkpoint_freq`` steps in ``OUT/checkpoints`` (written
atomically, :mod:`.checkpoint`; ``resume=True`` continues from the newest complete one, so a
kill loses at most one interval) and an evaluation on a fixed seeded target set every
``eval_freq`` steps (success within ±50/100/250 µm, to tensorboard and ``OUT/evaluations.jsonl``).
At the end ``OUT`` holds the final ``model.zip``, ``normalization.json`` and ``metadata.json``.

A folder is used by one training at a time (``OUT/.lock``). ``resume`` refuses what it cannot
honour: nothing to resume, damaged checkpoints only, a config other than the checkpoint's (unless
``allow_config_change``, which the metadata records).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ProgressBarCallback
from stable_baselines3.common.vec_env import VecEnv, VecMonitor, VecNormalize

from microconveyor_env.envs import EnvConfig, env_config
from microconveyor_env.envs.versions import GOAL_ENV_IDS, check_env_id
from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

from ..artefacts import checkpoint, normalization
from . import hyperparams, phases, wrappers
from .algos import ALGO_NAMES, algo_class
from ..artefacts.checkpoint import META, MODEL, NORMALIZATION, CheckpointError
from ..evaluation.evaluate import Policy, evaluate
from ..artefacts.actor_net import actor_of_model
from ..artefacts.sb3_files import ModelFileError, algo_of, read_data, safe_load

FORMAT = 2          # run-folder layout: checkpoints/gen-*, normalization.json (1: pickles)
LEGACY_CHECKPOINT = "checkpoint"
Log = Callable[[str], None]


def config_hash(cfg: EnvConfig, hp: dict, algo: str = "ppo") -> str:
    blob = json.dumps({"env": dataclasses.asdict(cfg), algo: hp}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


class Periodic(BaseCallback):
    """Checkpoints and fixed-target evaluations at step intervals, with the wall-time budget."""

    def __init__(self, out: Path, cfg: EnvConfig, checkpoint_freq: int, eval_freq: int,
                 eval_targets: int, eval_seed: int, t_start: float, wall_before: float,
                 run_meta: dict, max_seconds: float | None = None, log: Log | None = None,
                 on_eval: Callable[[dict], None] | None = None):
        super().__init__()
        self.max_seconds, self.on_eval = max_seconds, on_eval
        self.out, self.cfg, self.run_meta, self.log = out, cfg, run_meta, log
        self.checkpoint_freq, self.eval_freq = checkpoint_freq, eval_freq
        self.eval_targets, self.eval_seed = eval_targets, eval_seed
        self.t_start, self.wall_before = t_start, wall_before
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
        gen = checkpoint.write_generation(self.out, n, meta, lambda d: _write_model(self.model, d))
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


def _write_model(model: BaseAlgorithm, folder: Path) -> None:
    model.save(folder / MODEL)
    env = model.get_env()
    if isinstance(env, VecNormalize):
        normalization.write(env, folder / NORMALIZATION)


def make_env(cfg: EnvConfig, hp: dict, seed: int, env_id: str = hyperparams.ENV_ID
             ) -> VecEnv:
    """The training envs: the compiled batch (Box observations), or for a goal-conditioned id
    ``n_envs`` single Dict-observation envs (what SB3's HerReplayBuffer relabels)."""
    n = int(hp.get("n_envs", 64))
    venv: VecEnv
    if env_id in GOAL_ENV_IDS:
        from stable_baselines3.common.vec_env import DummyVecEnv

        from microconveyor_env.envs.line.goal import MicroConveyorGoalEnv

        venv = DummyVecEnv([lambda: MicroConveyorGoalEnv(config=cfg)] * n)
    else:
        venv = MicroConveyorSB3VecEnv(n, config=cfg)
    # training-only wrappers a recipe names (rl-zoo3's vec_env_wrapper: reward shaping, a
    # target distribution), before VecNormalize; the monitor inside them records the env's
    # own returns. Seeded through them (a wrapper that draws seeds its own generator).
    wrapped = wrappers.wrap(VecMonitor(venv), hp.get("vec_env_wrapper"))
    wrapped.seed(seed)
    return wrapped


def check_budgets(steps: int | None, max_minutes: float | None, checkpoint_freq: int,
                  eval_freq: int, eval_targets: int) -> None:
    """Refuse budgets that cannot mean anything: ValueError naming the argument."""
    def whole(name: str, v: Any, lo: int) -> None:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} must be a whole number >= {lo}, got {v!r}")

    if steps is not None:
        whole("steps", steps, 1)
    if max_minutes is not None and (isinstance(max_minutes, bool) or
                                    not isinstance(max_minutes, (int, float)) or
                                    not math.isfinite(max_minutes) or max_minutes <= 0):
        raise ValueError(f"max_minutes must be a positive finite number of minutes, got "
                         f"{max_minutes!r}")
    whole("checkpoint_freq", checkpoint_freq, 1)
    whole("eval_freq", eval_freq, 0)
    whole("eval_targets", eval_targets, 0)


def _refuse_used_folder(out: Path) -> None:
    gens = checkpoint.generations(out)
    if gens or (out / LEGACY_CHECKPOINT).exists() or (out / META).exists():
        what = (f"{len(gens)} checkpoint(s), the newest {gens[0].name}" if gens
                else "a finished or old-format training")
        raise CheckpointError(f"{str(out)!r} already holds a training ({what}): pass --resume "
                              "to continue it, or choose another --out")


def _check_generation(algo: str, need_stats: bool) -> Callable[[Path, dict], None]:
    def check(folder: Path, meta: dict) -> None:
        if meta.get("algo") != algo or algo_of(read_data(folder / MODEL)) != algo:
            raise CheckpointError(f"not a {algo.upper()} checkpoint")
        if need_stats:
            normalization.read(folder / NORMALIZATION)
    return check


def _resumable(out: Path, chash: str, hp: dict, allow_config_change: bool,
               log: Log | None, algo: str) -> checkpoint.Generation:
    need_stats = hyperparams.normalize_kwargs(hp) is not None
    try:
        gen = checkpoint.latest(out, _check_generation(algo, need_stats))
    except ModelFileError as exc:  # pragma: no cover - latest() turns these into skips
        raise CheckpointError(str(exc)) from None
    if gen is None:
        if (out / LEGACY_CHECKPOINT).is_dir():
            raise CheckpointError(
                f"{str(out / LEGACY_CHECKPOINT)!r} is a checkpoint of an earlier version "
                "(VecNormalize as a pickle, files overwritten in place); it cannot be resumed "
                "safely: start a new --out")
        damaged = checkpoint.generations(out)
        raise CheckpointError(f"nothing to resume in {str(out)!r}: " + (
            f"none of its {len(damaged)} checkpoint(s) is complete" if damaged else
            "no checkpoint in it (run without --resume to start a training)"))
    if log:
        for skip in gen.skipped:
            log(f"resume: skipped damaged checkpoint {skip}")
    if gen.meta.get("config_hash") != chash:
        changed = hyperparams.changed_keys(gen.meta.get("hyperparams") or {}, hp)
        what = (f"hyperparameters {', '.join(changed)}" if changed else "the env config")
        if not allow_config_change:
            raise CheckpointError(
                f"the checkpoint at step {gen.steps} was trained with another config ({what} "
                "differ); resume with the same --conf-file and env settings, or pass "
                "--allow-config-change to change it on purpose (recorded in the metadata)")
    return gen


def _resumed_seed(model: Any, seed: int | None) -> int:
    """The seed a resumed run trains on: its own (SB3 reseeds the envs, torch and numpy from the
    checkpoint's ``seed`` as it loads), which the metadata records; another one is refused
    rather than recorded while the run goes on under its own."""
    own = int(model.seed)
    if seed is not None and int(seed) != own:
        raise ValueError(f"seed {seed}: this run trains with seed {own} and a resume continues "
                         f"it; drop the seed (or give {own})")
    return own


def _new_model(env: VecEnv, hp: dict, seed: int, tb: str | None, algo: str) -> Any:
    norm = hyperparams.normalize_kwargs(hp)
    if norm is not None:
        env = VecNormalize(env, **{"gamma": hp.get("gamma", 0.99), **norm})
    return algo_class(algo)(hp.get("policy", "MlpPolicy"), env, seed=seed, device="cpu",
                            verbose=0, tensorboard_log=tb, **hyperparams.algo_kwargs(hp))


def _resumed_model(gen: checkpoint.Generation, env: VecEnv, hp: dict, tb: str | None,
                   algo: str) -> Any:
    """The checkpoint's model around ``env``. Off-policy: the replay buffer is not in the
    checkpoint (SB3 stores it as a pickle), so a resumed SAC/TQC refills it from scratch."""
    if (gen.folder / NORMALIZATION).is_file():
        env = normalization.restore(env, normalization.read(gen.folder / NORMALIZATION))
    kw = hyperparams.algo_kwargs(hp)
    try:
        given = {k: kw[k] for k in ("learning_rate", "clip_range", "replay_buffer_class",
                                    "replay_buffer_kwargs", "target_entropy")
                 if k in kw and kw[k] != "auto"}
        model = safe_load(gen.folder / MODEL, algo, env.observation_space, env.action_space,
                          cls=algo_class(algo), env=env, load_kwargs={"tensorboard_log": tb},
                          **given)
    except ModelFileError as exc:
        raise CheckpointError(str(exc)) from None
    if hasattr(model, "learning_starts"):
        # the refilled buffer collects learning_starts steps again before the first update
        model.learning_starts = int(gen.steps) + int(hp.get("learning_starts", 100))
    return model


def train(out: str | Path, steps: int | None = None, seed: int | None = None, conf_file: str | None = None,
          config: EnvConfig | None = None, resume: bool = False, checkpoint_freq: int = 200_000,
          eval_freq: int = 250_000, eval_targets: int = 100, eval_seed: int = 12345,
          progress_bar: bool = True, tensorboard: bool = True, overrides: dict | None = None,
          max_minutes: float | None = None, allow_config_change: bool = False,
          log: Log | None = None, env_id: str = hyperparams.ENV_ID,
          env_kwargs: dict | None = None, algo: str = "ppo",
          on_eval: Callable[[dict], None] | None = None, fork_seed: int | None = None) -> dict:
    """Train (or resume) ``algo`` (:data:`.algos.ALGO_NAMES`; hyperparameters from
    ``conf_file``, default ``configs/<algo>.yml``) into ``out`` for ``steps`` (or until ``max_minutes`` of wall time,
    resumed runs included); returns the metadata written there. The env: ``env_id`` (a
    registered version; its entry in the conf file gives the hyperparameters) with the conf
    file's ``env_kwargs`` updated by ``env_kwargs`` (as ``gym.make(env_id, **kwargs)``), or
    ``config`` if given; the metadata records ``env_id`` and the merged ``env_kwargs``.
    ``on_eval``: called with each periodic evaluation's result (as written to
    ``evaluations.jsonl``); an exception it raises stops the run there and propagates (a tuner's
    pruning), the checkpoints written so far stay. ``seed``: a new run's training seed (default
    0); a resume continues the run's own seed (SB3 reseeds from the checkpoint), so another
    ``seed`` is refused. ``fork_seed`` (with ``resume``): continue the checkpoint under that
    seed instead (a fork: the same state, other samples; the metadata's ``forks`` records it
    and ``seed`` becomes it); how much of a run's final figure its last updates decide is
    measured this way (docs/agents.md)."""
    import torch

    check_budgets(steps, max_minutes, checkpoint_freq, eval_freq, eval_targets)
    if fork_seed is not None and not resume:
        raise ValueError("fork_seed forks a checkpoint: it needs resume (a new run takes seed)")
    if algo not in ALGO_NAMES:
        raise ValueError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGO_NAMES)}")
    torch.set_num_threads(1)  # small nets: one thread is fastest, and 2 cores are shared with the env
    out = Path(out)
    with checkpoint.folder_lock(out):
        hp = hyperparams.load(conf_file, check_env_id(env_id), algo)
        hp.update(overrides or {})
        if env_kwargs:
            hp["env_kwargs"] = {**(hp.get("env_kwargs") or {}), **env_kwargs}
        cfg = config or env_config(env_id, **(hp.get("env_kwargs") or {}))
        if env_id in GOAL_ENV_IDS and hyperparams.normalize_kwargs(hp) is not None:
            # HER relabels the raw goals it stores; the policy files keep statistics of Box
            # observations only. Refused before training rather than at the first save.
            raise ValueError(f"normalize: {env_id} has Dict observations (goal-conditioned); "
                             "observation normalisation is for the Box envs. Drop normalize "
                             "from the recipe")
        chash = config_hash(cfg, hp, algo)
        run_seed = 0 if seed is None else int(seed)  # a resume: the run's own (below)
        run_meta = {"format": FORMAT, "env_id": env_id, "algo": algo,
                    "env_kwargs": dict(hp.get("env_kwargs") or {}),
                    "config_hash": chash, "seed": run_seed, "hyperparams": hp,
                    "env_config": dataclasses.asdict(cfg)}
        tb = str(out / "tb") if tensorboard else None
        env = make_env(cfg, hp, run_seed, env_id)
        wall_before = 0.0
        if resume:
            gen = _resumable(out, chash, hp, allow_config_change, log, algo)
            model = _resumed_model(gen, env, hp, tb, algo)
            run_meta["seed"] = own_seed = _resumed_seed(model, seed)
            if fork_seed is not None:
                run_meta["forks"] = [*gen.meta.get("forks", []), {
                    "at_steps": gen.steps, "from_seed": own_seed, "seed": fork_seed}]
                model.seed = run_meta["seed"] = int(fork_seed)
                model.set_random_seed(model.seed)   # torch, numpy, the envs' next reset
                model._last_obs = None               # new episodes under the fork's seed
            elif gen.meta.get("forks"):
                run_meta["forks"] = gen.meta["forks"]
            wall_before = float(gen.meta.get("wall_time_s", 0.0))
            changes = list(gen.meta.get("config_changes", []))
            if gen.meta.get("config_hash") != chash:
                changes.append({"at_steps": gen.steps, "from": gen.meta.get("config_hash"),
                                "to": chash})
            if changes:
                run_meta["config_changes"] = changes
            if log:
                how = (f"forked to seed {fork_seed} from seed {own_seed}"
                       if fork_seed is not None else f"seed {own_seed}")
                log(f"resume: from step {gen.steps} ({gen.folder.name}), {how}, "
                    f"{wall_before:.0f} s of wall time already spent")
        else:
            _refuse_used_folder(out)
            model = _new_model(env, hp, run_seed, tb, algo)
        total = int(steps if steps is not None else hp.get("n_timesteps", 1e6))
        # the run's progress now, under this call's budgets (a resume may extend them)
        done_now = max(model.num_timesteps / total,
                       wall_before / (60.0 * max_minutes) if max_minutes else 0.0)
        model.phase_log = log  # the restart, the shift and the frozen statistics say when
        phases.exploration_restart(model, hp, algo, done_now)
        phases.exploration_shift(model, hp, algo, done_now)
        phases.freeze_obs_stats(model, hp, done_now)
        if resume:
            _check_budget_left(model.num_timesteps, total, wall_before, max_minutes, log)
            if log and hasattr(model, "replay_buffer"):
                log(f"resume: the replay buffer is not checkpointed; it refills for "
                    f"{model.learning_starts - model.num_timesteps} steps before updates resume")
        return _learn(model, out, cfg, total, resume, run_meta, wall_before, checkpoint_freq,
                      eval_freq, eval_targets, eval_seed, progress_bar, max_minutes, log, on_eval)


def _check_budget_left(done: int, total: int, wall_before: float, max_minutes: float | None,
                       log: Log | None) -> None:
    """A resumed run continues the whole run's budgets (steps and wall time count from its
    start): refuse one with nothing left, rather than stopping after one rollout in silence."""
    if done >= total:
        raise ValueError(f"nothing to resume: the run already has {done} of its {total} steps; "
                         "give a larger --steps (the budget counts the whole run)")
    if max_minutes is not None and wall_before >= 60.0 * max_minutes:
        raise ValueError(f"nothing to resume: the run already used {wall_before / 60:.2f} min of "
                         f"its --max-minutes {max_minutes:g}; give a larger --max-minutes (the "
                         "budget counts the whole run)")
    if log:
        left = "" if max_minutes is None else \
            f", {max_minutes - wall_before / 60:.2f} of {max_minutes:g} min left"
        log(f"resume: continuing at step {done} of {total}{left}; the learning-rate schedule "
            "continues from the run's progress")


def _learn(model: Any, out: Path, cfg: EnvConfig, total: int, resume: bool, run_meta: dict,
           wall_before: float, checkpoint_freq: int, eval_freq: int, eval_targets: int,
           eval_seed: int, progress_bar: bool, max_minutes: float | None, log: Log | None,
           on_eval: Callable[[dict], None] | None = None) -> dict:
    t0 = time.perf_counter()
    periodic = Periodic(out, cfg, checkpoint_freq, eval_freq, eval_targets, eval_seed, t0,
                        wall_before, run_meta,
                        None if max_minutes is None else 60.0 * max_minutes, log, on_eval)
    if max_minutes is not None:
        budget_s = 60.0 * max_minutes
        model.budget_clock = lambda: periodic.wall() / budget_s
    callbacks: list[BaseCallback] = [periodic]
    if progress_bar:
        callbacks.append(ProgressBarCallback())
    remaining = max(0, total - model.num_timesteps)
    if model.tensorboard_log is None:
        # no tensorboard: a logger without outputs (SB3's default makes an empty tmp/SB3-* folder)
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    model.learn(remaining, callback=CallbackList(callbacks), reset_num_timesteps=not resume,
                tb_log_name=str(run_meta["algo"]), progress_bar=False)
    wall = periodic.wall()
    done_now = periodic.last_eval.get("steps") == model.num_timesteps
    final = (periodic.last_eval if done_now else periodic.run_eval()) if eval_targets else {}
    meta = {**run_meta, "steps": int(model.num_timesteps), "wall_time_s": wall,
            "steps_per_s": model.num_timesteps / max(wall, 1e-9),
            "target_range_m": list(cfg.target_range), "evaluation": final}
    gen = periodic.save_checkpoint({k: meta[k] for k in ("steps_per_s", "target_range_m",
                                                           "evaluation")})
    names = tuple(n for n in (MODEL, NORMALIZATION) if (gen / n).is_file()) + (META,)
    checkpoint.replace_files(gen, out, names)
    return checkpoint.read_meta(out)
