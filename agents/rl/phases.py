"""Recipe keys that change a training at fractions of its run (trainer keys, not SB3's).

* ``exploration_restart: {at: FRACTION, log_std: VALUE}`` (PPO): when the run's progress reaches
  ``at``, PPO's log std is set to ``log_std`` in every action component, once, and the
  learning-rate schedule restarts, decaying in each phase from its initial value to 0.
* ``freeze_obs_stats_at: FRACTION``: from that progress on, VecNormalize's observation
  statistics stop updating (the reward statistics go on), so the last updates see every
  observation through one normalisation.

Progress is the run's (steps or the wall budget, whichever is further, :mod:`.algos`), so
``--steps``, ``--max-minutes`` and resumes scale both. A resumed run continues from the progress
its checkpoint saved: a restart that already happened is not repeated, and statistics frozen
before the checkpoint are frozen again at once. Why the v1 recipe uses both: docs/agents.md,
"PPO on MicroConveyor-v1".
"""
from __future__ import annotations

from typing import Any


def _fraction(name: str, val: Any, lo: float = 0.0, hi: float = 1.0) -> float:
    if isinstance(val, bool) or not isinstance(val, (int, float)) or not lo < val < hi:
        raise ValueError(f"{name} must be a number in ({lo:g}, {hi:g}), got {val!r}")
    return float(val)


def done_fraction(model: Any) -> float:
    """The run's progress [0, 1] as ``model`` last recorded it (0 for a new model)."""
    return 1.0 - float(getattr(model, "_current_progress_remaining", 1.0))


def exploration_restart(model: Any, hp: dict, algo: str) -> None:
    """Arm the recipe's ``exploration_restart`` on ``model`` (see the module docstring)."""
    spec = hp.get("exploration_restart")
    if spec is None:
        return
    if algo != "ppo":
        raise ValueError(f"exploration_restart is a PPO setting (its state-independent log "
                         f"std); the {algo} recipe cannot use it")
    if not isinstance(spec, dict) or set(spec) != {"at", "log_std"}:
        raise ValueError(f"exploration_restart must be {{at: FRACTION, log_std: VALUE}}, got "
                         f"{spec!r}")
    at = _fraction("exploration_restart: at", spec["at"])
    log_std = _fraction("exploration_restart: log_std", spec["log_std"], -20.0, 2.0)
    base = model.lr_schedule

    def schedule(remaining: float) -> float:
        done = 1.0 - remaining
        return base(1.0 - done / at if done < at else (1.0 - done) / (1.0 - at))

    model.lr_schedule = schedule
    model.restart_at, model.restart_log_std = at, log_std
    # it fires in the update after the first rollout past ``at``; a checkpoint written after
    # that rollout has saved a progress >= at
    model.restart_pending = done_fraction(model) < at


def freeze_obs_stats(model: Any, hp: dict) -> None:
    """Arm the recipe's ``freeze_obs_stats_at`` on ``model``, and freeze now if a resumed run
    is already past it."""
    at = hp.get("freeze_obs_stats_at")
    if at is None:
        return
    at = _fraction("freeze_obs_stats_at", at)
    norm = hp.get("normalize") or {}
    if not norm or not norm.get("norm_obs", True):
        raise ValueError("freeze_obs_stats_at needs normalised observations (normalize with "
                         "norm_obs true): there are no statistics to freeze")
    model.freeze_obs_at = at
    model.freeze_obs_if_due()
