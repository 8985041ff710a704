"""Training PPO, SAC or TQC (:mod:`.algos`) on any registered env: the line's and the plane's on
their compiled batch, the goal-conditioned one on single Dict-observation envs.

Hyperparameters from ``configs/<algo>.yml`` (:mod:`.hyperparams`), what the run does from a
:class:`~.settings.TrainSettings`. During training: a progress bar, tensorboard logs
(``OUT/tb``), one line per checkpoint and per evaluation (through ``log``), a checkpoint
generation every ``checkpoint_freq`` steps in ``OUT/checkpoints`` (written atomically,
:mod:`..artefacts.checkpoint`; ``resume`` continues from the newest complete one, :mod:`.resume`,
so a kill loses at most one interval) and an evaluation on a fixed seeded target set every
``eval_freq`` steps (success within ±50/100/250 µm, to tensorboard and ``OUT/evaluations.jsonl``;
:mod:`.callbacks`). At the end ``OUT`` holds the final ``model.zip``, ``normalization.json`` and
``metadata.json``.

A folder is used by one training at a time (``OUT/.lock``); one that is or holds a symbolic
link is refused (nothing is written through one). ``resume`` refuses what it cannot
honour: nothing to resume, damaged checkpoints only, a config other than the checkpoint's (unless
``allow_config_change``, which the metadata records).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ProgressBarCallback
from stable_baselines3.common.vec_env import VecEnv, VecMonitor, VecNormalize

from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.env_ids import GOAL_ENV_IDS
from microconveyor_env.envs.core.versions import check_env_id, scene_config

from ..artefacts import checkpoint
from ..artefacts.checkpoint import META, MODEL, NORMALIZATION
from ..artefacts.folders import refuse_links
from . import hyperparams, phases, resume, wrappers
from .algos import algo_class
from .callbacks import Periodic
from .settings import TrainSettings

FORMAT = 2          # run-folder layout: checkpoints/gen-*, normalization.json (1: pickles)
Log = Callable[[str], None]


def config_hash(cfg: Any, hp: dict, algo: str = "ppo") -> str:
    blob = json.dumps({"env": dataclasses.asdict(cfg), algo: hp}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def make_env(cfg: Any, hp: dict, seed: int, env_id: str = hyperparams.ENV_ID) -> VecEnv:
    """The training envs: the compiled batch (Box observations) of the line or the plane, or
    for a goal-conditioned id ``n_envs`` single Dict-observation envs (what SB3's
    HerReplayBuffer relabels)."""
    n = int(hp.get("n_envs", 64))
    venv: VecEnv
    if env_id in GOAL_ENV_IDS:
        from stable_baselines3.common.vec_env import DummyVecEnv

        from microconveyor_env.envs.line.goal import MicroConveyorGoalEnv

        venv = DummyVecEnv([lambda: MicroConveyorGoalEnv(config=cfg)] * n)
    elif isinstance(cfg, PlaneEnvConfig):
        venv = MicroConveyorSB3VecEnv(n, env_id=env_id, **(hp.get("env_kwargs") or {}))
    else:
        venv = MicroConveyorSB3VecEnv(n, config=cfg)
    # training-only wrappers a recipe names (rl-zoo3's vec_env_wrapper: reward shaping, a
    # target distribution), before VecNormalize; the monitor inside them records the env's
    # own returns. Seeded through them (a wrapper that draws seeds its own generator).
    wrapped = wrappers.wrap(VecMonitor(venv), hp.get("vec_env_wrapper"))
    wrapped.seed(seed)
    return wrapped


def new_model(env: VecEnv, hp: dict, seed: int, tb: str | None, algo: str) -> Any:
    norm = hyperparams.normalize_kwargs(hp)
    if norm is not None:
        env = VecNormalize(env, **{"gamma": hp.get("gamma", 0.99), **norm})
    return algo_class(algo)(hp.get("policy", "MlpPolicy"), env, seed=seed, device="cpu",
                            verbose=0, tensorboard_log=tb, **hyperparams.algo_kwargs(hp))


def recipe(s: TrainSettings, config: Any | None = None) -> tuple[dict, Any]:
    """The hyperparameters (conf file, overrides, env kwargs merged) and the env config of a
    run; a goal-conditioned env with observation normalisation is refused."""
    hp = hyperparams.load(s.conf_file, check_env_id(s.env_id), s.algo)
    hp.update(s.overrides or {})
    if s.env_kwargs:
        hp["env_kwargs"] = {**(hp.get("env_kwargs") or {}), **s.env_kwargs}
    if s.env_id in GOAL_ENV_IDS and hyperparams.normalize_kwargs(hp) is not None:
        # HER relabels the raw goals it stores; the policy files keep statistics of Box
        # observations only. Refused before training rather than at the first save.
        raise ValueError(f"normalize: {s.env_id} has Dict observations (goal-conditioned); "
                         "observation normalisation is for the Box envs. Drop normalize "
                         "from the recipe")
    return hp, config or scene_config(s.env_id, **(hp.get("env_kwargs") or {}))


def train(out: str | Path, settings: TrainSettings | None = None, config: Any | None = None,
          log: Log | None = None, on_eval: Callable[[dict], None] | None = None,
          on_model: Callable[[Any, BaseCallback], None] | None = None) -> dict:
    """Train (or resume) as ``settings`` say (:class:`~.settings.TrainSettings`) into ``out``;
    returns the metadata written there. The env: ``settings.env_id`` with the conf file's
    ``env_kwargs`` updated by ``settings.env_kwargs``, or ``config`` if given; the metadata
    records ``env_id`` and the merged ``env_kwargs``. ``log``: where the run's lines go.
    ``on_eval``: called with each periodic evaluation's result (as written to
    ``evaluations.jsonl``); an exception it raises stops the run there and propagates (a tuner's
    pruning), the checkpoints written so far stay. A fork (``fork_seed``) records itself in the
    metadata's ``forks`` and its ``seed`` becomes the fork's; how much of a run's final figure
    its last updates decide is measured this way (docs/agents.md). ``on_model``: called with the
    live model and the periodic evaluation-and-checkpoint callback just before learning starts
    (a benchmark's instruments: benchmarks/train_time_breakdown.py)."""
    import torch

    s = settings or TrainSettings()
    torch.set_num_threads(1)  # small nets: one thread is fastest, and 2 cores are shared with the env
    out = Path(out)
    refuse_links(out)   # every file of the run is written as a real file inside it
    with checkpoint.folder_lock(out):
        hp, cfg = recipe(s, config)
        chash = config_hash(cfg, hp, s.algo)
        run_seed = 0 if s.seed is None else int(s.seed)  # a resume: the run's own (below)
        run_meta = {"format": FORMAT, "env_id": s.env_id, "algo": s.algo,
                    "env_kwargs": dict(hp.get("env_kwargs") or {}),
                    "config_hash": chash, "seed": run_seed, "hyperparams": hp,
                    "env_config": dataclasses.asdict(cfg)}
        tb = str(out / "tb") if s.tensorboard else None
        env = make_env(cfg, hp, run_seed, s.env_id)
        wall_before = 0.0
        if s.resume:
            model, wall_before = _resume(out, s, env, hp, chash, tb, run_meta, log)
        else:
            resume.refuse_used_folder(out)
            model = new_model(env, hp, run_seed, tb, s.algo)
        total = int(s.steps if s.steps is not None else hp.get("n_timesteps", 1e6))
        # the run's progress now, under this call's budgets (a resume may extend them)
        done_now = max(model.num_timesteps / total,
                       wall_before / s.max_seconds if s.max_seconds else 0.0)
        model.phase_log = log  # the restart, the shift and the frozen statistics say when
        phases.exploration_restart(model, hp, s.algo, done_now)
        phases.exploration_shift(model, hp, s.algo, done_now)
        phases.freeze_obs_stats(model, hp, done_now)
        if s.resume:
            resume.check_budget_left(model.num_timesteps, total, wall_before, s.max_minutes, log)
            if log and hasattr(model, "replay_buffer"):
                log(f"resume: the replay buffer is not checkpointed; it refills for "
                    f"{model.learning_starts - model.num_timesteps} steps before updates resume")
        periodic = Periodic(out, cfg, s, run_meta, wall_before, log, on_eval)
        if on_model is not None:
            on_model(model, periodic)
        return _learn(model, periodic, total, s)


def _resume(out: Path, s: TrainSettings, env: VecEnv, hp: dict, chash: str, tb: str | None,
            run_meta: dict, log: Log | None) -> tuple[Any, float]:
    """The checkpoint's model and the wall time already spent [s]; ``run_meta`` gets the
    run's seed, its forks and its config changes."""
    gen = resume.resumable(out, chash, hp, s.allow_config_change, log, s.algo)
    model = resume.resumed_model(gen, env, hp, tb, s.algo)
    run_meta["seed"] = own_seed = resume.resumed_seed(model, s.seed)
    if s.fork_seed is not None:
        run_meta["forks"] = [*gen.meta.get("forks", []), {
            "at_steps": gen.steps, "from_seed": own_seed, "seed": s.fork_seed}]
        model.seed = run_meta["seed"] = int(s.fork_seed)
        model.set_random_seed(model.seed)   # torch, numpy, the envs' next reset
        model._last_obs = None               # new episodes under the fork's seed
    elif gen.meta.get("forks"):
        run_meta["forks"] = gen.meta["forks"]
    wall_before = float(gen.meta.get("wall_time_s", 0.0))
    changes = list(gen.meta.get("config_changes", []))
    if gen.meta.get("config_hash") != chash:
        changes.append({"at_steps": gen.steps, "from": gen.meta.get("config_hash"), "to": chash})
    if changes:
        run_meta["config_changes"] = changes
    if log:
        how = (f"forked to seed {s.fork_seed} from seed {own_seed}"
               if s.fork_seed is not None else f"seed {own_seed}")
        log(f"resume: from step {gen.steps} ({gen.folder.name}), {how}, "
            f"{wall_before:.0f} s of wall time already spent")
    return model, wall_before


def targets_of(cfg: Any) -> dict[str, Any]:
    """Where a scene's targets lie: the line's ``target_range_m``, the plane's
    ``target_box_m``."""
    if isinstance(cfg, PlaneEnvConfig):
        return {"target_box_m": [list(b) for b in cfg.grid_box]}
    return {"target_range_m": list(cfg.target_range)}


def _learn(model: Any, periodic: Periodic, total: int, s: TrainSettings) -> dict:
    if s.max_seconds is not None:
        budget_s = s.max_seconds
        model.budget_clock = lambda: periodic.wall() / budget_s
    callbacks: list[BaseCallback] = [periodic]
    if s.progress_bar:
        callbacks.append(ProgressBarCallback())
    remaining = max(0, total - model.num_timesteps)
    if model.tensorboard_log is None:
        # no tensorboard: a logger without outputs (SB3's default makes an empty tmp/SB3-* folder)
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    model.learn(remaining, callback=CallbackList(callbacks), reset_num_timesteps=not s.resume,
                tb_log_name=str(periodic.run_meta["algo"]), progress_bar=False)
    wall = periodic.wall()
    done_now = periodic.last_eval.get("steps") == model.num_timesteps
    final = (periodic.last_eval if done_now else periodic.run_eval()) if s.eval_targets else {}
    where = targets_of(periodic.cfg)
    meta = {**periodic.run_meta, "steps": int(model.num_timesteps), "wall_time_s": wall,
            "steps_per_s": model.num_timesteps / max(wall, 1e-9), **where, "evaluation": final}
    gen = periodic.save_checkpoint({k: meta[k] for k in ("steps_per_s", *where, "evaluation")})
    out = periodic.out
    names = tuple(n for n in (MODEL, NORMALIZATION) if (gen / n).is_file()) + (META,)
    checkpoint.replace_files(gen, out, names)
    return checkpoint.read_meta(out)
