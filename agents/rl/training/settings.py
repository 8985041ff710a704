"""The settings of a training run (:func:`.train.train`), validated once."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .algos import ALGO_NAMES
from .hyperparams import ENV_ID


def _whole(name: str, v: Any, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{name} must be a whole number >= {lo}, got {v!r}")


def check_budgets(steps: int | None, max_minutes: float | None, checkpoint_freq: int,
                  eval_freq: int, eval_targets: int) -> None:
    """Refuse budgets that cannot mean anything: ValueError naming the argument."""
    if steps is not None:
        _whole("steps", steps, 1)
    if max_minutes is not None and (isinstance(max_minutes, bool) or
                                    not isinstance(max_minutes, (int, float)) or
                                    not math.isfinite(max_minutes) or max_minutes <= 0):
        raise ValueError(f"max_minutes must be a positive finite number of minutes, got "
                         f"{max_minutes!r}")
    _whole("checkpoint_freq", checkpoint_freq, 1)
    _whole("eval_freq", eval_freq, 0)
    _whole("eval_targets", eval_targets, 0)


@dataclass(frozen=True)
class TrainSettings:
    """What a training run does (:func:`.train.train`).

    ``algo``: one of :data:`.algos.ALGO_NAMES`; ``env_id``: a registered id (its entry in the
    conf file gives the hyperparameters); ``env_kwargs``: overrides of the conf file's
    ``env_kwargs`` (as ``gym.make(env_id, **kwargs)``, SI units); ``conf_file``: rl-zoo3 YAML
    (None: the shipped ``configs/<algo>.yml``); ``overrides``: hyperparameters replacing the conf
    file's. ``steps`` [-] total environment steps (None: the conf file's ``n_timesteps``);
    ``max_minutes`` [min] wall-time budget, resumed time included; ``seed`` [-] a new run's
    training seed (None: 0; a resume continues the run's own, another is refused);
    ``resume``: continue from the newest complete checkpoint; ``allow_config_change``: resume
    under another config (recorded); ``fork_seed`` [-] (with ``resume``): continue the
    checkpoint under this seed instead (a fork). ``checkpoint_freq`` [steps] between
    checkpoints; ``eval_freq`` [steps] between evaluations (0: none); ``eval_targets`` [-]
    targets per evaluation (0: none); ``eval_seed`` [-] of their fixed target set;
    ``progress_bar``, ``tensorboard``: what the run shows and logs."""

    algo: str = field(default="ppo", metadata={
        "help": "algorithm: ppo (stable-baselines3, on the compiled batch), sac "
                "(stable-baselines3), tqc (sb3-contrib); sac and tqc on MicroConveyorGoal-v1 use "
                "HER (default: {default})", "choices": ALGO_NAMES})
    env_id: str = ENV_ID
    env_kwargs: dict[str, Any] | None = None
    conf_file: str | None = field(default=None, metadata={
        "help": "rl-zoo3 style YAML (default: the shipped configs/ALGO.yml)"})
    overrides: dict[str, Any] | None = None
    steps: int | None = field(default=None, metadata={
        "help": "total environment steps (default: n_timesteps of the conf file)",
        "bounds": (1, None)})
    max_minutes: float | None = field(default=None, metadata={
        "help": "stop after this wall time [min], resumed time included"})
    seed: int | None = field(default=None, metadata={
        "help": "training seed (default 0); --resume continues the run's own seed and refuses "
                "another"})
    resume: bool = field(default=False, metadata={
        "help": "continue from the newest complete checkpoint in OUT/checkpoints (refused if "
                "there is none or the config differs)"})
    allow_config_change: bool = field(default=False, metadata={
        "help": "with --resume: continue under a different config (recorded in the metadata)"})
    fork_seed: int | None = field(default=None, metadata={
        "help": "with --resume: continue the checkpoint under this seed instead of the run's (a "
                "fork: the same state, other samples; recorded in the metadata)"})
    checkpoint_freq: int = field(default=200_000, metadata={
        "help": "steps between checkpoints (a kill loses at most this many)", "bounds": (1, None)})
    eval_freq: int = field(default=250_000, metadata={
        "help": "0: no periodic evaluation", "bounds": (0, None)})
    eval_targets: int = field(default=100, metadata={
        "help": "targets per evaluation (0: no evaluation)", "bounds": (0, None)})
    eval_seed: int = 12345
    progress_bar: bool = field(default=True, metadata={"help": "no progress bar",
                                                       "flag": "--no-progress"})
    tensorboard: bool = True

    def __post_init__(self) -> None:
        check_budgets(self.steps, self.max_minutes, self.checkpoint_freq, self.eval_freq,
                      self.eval_targets)
        if self.fork_seed is not None and not self.resume:
            raise ValueError("fork_seed forks a checkpoint: it needs resume (a new run takes "
                             "seed)")
        if self.algo not in ALGO_NAMES:
            raise ValueError(f"unknown algorithm {self.algo!r}; choose from "
                             f"{', '.join(ALGO_NAMES)}")

    @property
    def max_seconds(self) -> float | None:
        """The wall-time budget [s] (None: none)."""
        return None if self.max_minutes is None else 60.0 * self.max_minutes
