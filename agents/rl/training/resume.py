"""Resuming a training run: the newest complete checkpoint of a folder, checked against the run's
config, algorithm and seed, its model around the training envs, and the budgets left."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from stable_baselines3.common.vec_env import VecEnv

from ..artefacts import checkpoint, normalization
from ..artefacts.checkpoint import META, MODEL, NORMALIZATION, CheckpointError
from ..artefacts.sb3_files import ModelFileError, algo_of, read_data, safe_load
from . import hyperparams
from .algos import algo_class

LEGACY_CHECKPOINT = "checkpoint"
Log = Callable[[str], None]


def refuse_used_folder(out: Path) -> None:
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


def resumable(out: Path, chash: str, hp: dict, allow_config_change: bool,
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


def resumed_seed(model: Any, seed: int | None) -> int:
    """The seed a resumed run trains on: its own (SB3 reseeds the envs, torch and numpy from the
    checkpoint's ``seed`` as it loads), which the metadata records; another one is refused
    rather than recorded while the run goes on under its own."""
    own = int(model.seed)
    if seed is not None and int(seed) != own:
        raise ValueError(f"seed {seed}: this run trains with seed {own} and a resume continues "
                         f"it; drop the seed (or give {own})")
    return own


def resumed_model(gen: checkpoint.Generation, env: VecEnv, hp: dict, tb: str | None,
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


def check_budget_left(done: int, total: int, wall_before: float, max_minutes: float | None,
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
