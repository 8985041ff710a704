"""The settings of a tuning command (:func:`.tune.tune`), validated once."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..training import hyperparams
from ..training.settings import check_budgets
from .space import SPACE

DEFAULT_STUDY = "microconveyor-ppo"
SEED_MAX = 2**31 - 1   # the largest seed (a worker's sampler takes sampler_seed + its index)


@dataclass(frozen=True)
class TuneSettings:
    """A study's trials run by one command.

    ``out``: folder of the trials' run folders (``OUT/<study>/trial-N``), the default SQLite
    storage and ``best.yml``; ``n_trials`` [-] trials this command runs over ``workers`` [-]
    local processes; ``storage``: Optuna storage URL (None: ``$MICROCONVEYOR_TUNE_STORAGE``,
    else ``sqlite:///OUT/optuna.db``); ``study_name``. Every trial: ``env_id`` with
    ``env_kwargs`` (SI units), base hyperparameters from ``conf_file`` (None: the shipped
    ``configs/ppo.yml``), ``fixed`` search-space keys, ``trial_steps`` [steps],
    ``trial_minutes`` [min] (None: no wall budget), an evaluation every ``eval_freq`` [steps] on
    ``eval_targets`` [-] targets of ``eval_seed`` [-], training seed ``seed`` [-]; ``prune``:
    Optuna's median pruner on those evaluations; ``sampler_seed`` [-] of worker 0's TPE sampler
    (worker i: + i; None: random); ``best_file``: where the best trial's config entry goes
    (None: ``OUT/<study>/best.yml``); ``verbose``: one line per finished trial on stderr;
    ``heartbeat_s`` [s]: a new study's heartbeat interval (None: the default; a study keeps the
    one it was created with)."""

    out: str | Path = field(default="runs/tune", metadata={
        "help": "folder of the trials' run folders (OUT/STUDY/trial-N), the default SQLite "
                "storage and best.yml (default: {default})"})
    n_trials: int = field(default=20, metadata={
        "help": "trials this command runs, split over its workers (other machines add theirs to "
                "the same study)", "flag": "--trials", "bounds": (1, None)})
    workers: int = field(default=1, metadata={
        "help": "local worker processes (each trains on one core)", "bounds": (1, None)})
    storage: str | None = field(default=None, metadata={
        "help": "Optuna storage URL shared by all workers: sqlite:///PATH (one machine) or a "
                "database for many machines, e.g. postgresql://USER@HOST/DB (default: "
                "$MICROCONVEYOR_TUNE_STORAGE, else sqlite:///OUT/optuna.db)"})
    study_name: str = field(default=DEFAULT_STUDY, metadata={
        "help": "study name (default: {default})", "flag": "--study"})
    env_id: str = hyperparams.ENV_ID
    env_kwargs: dict[str, Any] | None = None
    conf_file: str | None = field(default=None, metadata={
        "help": "rl-zoo3 style YAML giving the base hyperparameters (default: the shipped "
                "configs/ppo.yml)"})
    fixed: dict[str, Any] | None = field(default=None, metadata={
        "help": f"do not tune KEY, use VALUE; keys: {', '.join(SPACE)}", "flag": "--fix",
        "nargs": "+", "metavar": "KEY:VALUE"})
    trial_steps: int = field(default=1_000_000, metadata={
        "help": "environment steps per trial (default: {default:,})", "flag": "--steps",
        "bounds": (1, None)})
    trial_minutes: float | None = field(default=None, metadata={
        "help": "wall budget of one trial [min] (default: none, --steps only)"})
    eval_freq: int = field(default=250_000, metadata={
        "help": "steps between periodic evaluations (0: none)", "bounds": (0, None)})
    eval_targets: int = field(default=100, metadata={"help": "targets per evaluation",
                                                     "bounds": (1, None)})
    eval_seed: int = 12345
    seed: int = field(default=0, metadata={"help": "training seed of every trial"})
    prune: bool = field(default=True, metadata={
        "help": "no median pruning on the periodic evaluations", "flag": "--no-prune"})
    sampler_seed: int | None = field(default=None, metadata={
        "help": "seed of the TPE sampler (worker i uses SEED + i; default: random)"})
    best_file: str | Path | None = field(default=None, metadata={
        "help": "where to write the best trial's config entry (rl-zoo3 YAML; default: "
                "OUT/STUDY/best.yml)", "flag": "--best"})
    verbose: bool = False
    heartbeat_s: int | None = field(default=None, metadata={
        "help": "a new study's heartbeat interval: a running trial without a heartbeat for 3x "
                "this (its worker or machine lost) is marked failed (default: 60; a study keeps "
                "the one it was created with)", "flag": "--heartbeat", "metavar": "SECONDS",
        "bounds": (1, None)})

    def __post_init__(self) -> None:
        if self.n_trials < 1 or self.workers < 1:
            raise ValueError(f"n_trials and workers must be >= 1, got {self.n_trials!r}, "
                             f"{self.workers!r}")
        hb = self.heartbeat_s
        if hb is not None and (isinstance(hb, bool) or not isinstance(hb, int) or hb < 1):
            raise ValueError(f"heartbeat_s must be a whole number of seconds >= 1, got {hb!r}")
        for name in ("seed", "eval_seed", "sampler_seed"):
            v = getattr(self, name)
            given = v is not None or name != "sampler_seed"
            if given and (isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= SEED_MAX):
                raise ValueError(f"{name} must be a whole number in [0, {SEED_MAX}], got {v!r}")
        check_budgets(self.trial_steps, self.trial_minutes, 1, self.eval_freq, self.eval_targets)
        if self.eval_targets < 1:
            raise ValueError("eval_targets must be >= 1: the objective is the final evaluation")

    def job(self, storage: str) -> dict[str, Any]:
        """What every worker of the command needs (a plain dict, sent to the worker
        processes), with the storage URL resolved."""
        keep = ("study_name", "env_id", "conf_file", "trial_steps", "trial_minutes", "eval_freq",
                "eval_targets", "eval_seed", "seed", "prune", "sampler_seed", "heartbeat_s")
        d = dataclasses.asdict(self)
        return {"out": str(self.out), "storage": storage, "env_kwargs": self.env_kwargs or None,
                "fixed": dict(self.fixed or {}), **{k: d[k] for k in keep}}
