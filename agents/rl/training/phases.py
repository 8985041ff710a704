"""Recipe keys that change a training at fractions of its run (trainer keys, not SB3's).

* ``exploration_restart: {at: FRACTION, log_std: VALUE}`` (PPO): when the run's progress reaches
  ``at``, PPO's log std is set to ``log_std`` in every action component, once, and the
  learning-rate schedule restarts, decaying in each phase from its initial value to 0.
* ``exploration_shift: {at: FRACTION, by: VALUE}`` (PPO): when the run's progress reaches
  ``at``, PPO's log std is shifted by ``by`` (natural-log units; negative: less noise) in every
  action component, once; the learning rate is not touched. Less action noise late in a run
  keeps the last updates' steps small in action units (PPO's clipped ratio bounds how far the
  mean moves per update to a fraction of the noise).
* ``freeze_obs_stats_at: FRACTION``: from that progress on, VecNormalize's observation
  statistics stop updating (the reward statistics go on), so the last updates see every
  observation through one normalisation.

The two log-std keys are refused with ``use_sde``: gSDE's log std is a matrix over the policy's
latent features, and a value of it is not the action noise the keys' numbers mean.

Progress is the run's (steps or the wall budget, whichever is further, :mod:`.algos`), so
``--steps``, ``--max-minutes`` and resumes scale both. A resumed run takes its progress from its
steps and wall time under the budgets it is given: past ``freeze_obs_stats_at`` it freezes the
statistics at once; past ``at`` a restart the checkpoint had not yet made is made at once and
one it had made is not repeated (the same for the shift); a resume with a larger budget that puts the run back before a
fraction makes that change again when it gets there (as the learning rate re-enters its first
phase). Why the v1 recipe uses both: docs/agents.md,
"PPO on MicroConveyor-v1".
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .hyperparams import number_in


def done_fraction(model: Any) -> float:
    """The run's progress [0, 1] as ``model`` last recorded it (0 for a new model)."""
    return 1.0 - float(getattr(model, "_current_progress_remaining", 1.0))


def exploration_restart(model: Any, hp: dict, algo: str, done_now: float) -> None:
    """Arm the recipe's ``exploration_restart`` on ``model`` (see the module docstring), the
    run being at progress ``done_now`` under this call's budgets."""
    spec = _log_std_spec(hp, "exploration_restart", "log_std", algo)
    if spec is None:
        return
    at = number_in("exploration_restart: at", spec["at"], 0.0, 1.0)
    log_std = number_in("exploration_restart: log_std", spec["log_std"], -20.0, 2.0)
    base = model.lr_schedule

    def schedule(remaining: float) -> float:
        done = 1.0 - remaining
        return base(1.0 - done / at if done < at else (1.0 - done) / (1.0 - at))

    model.lr_schedule = schedule
    model.restart_at, model.restart_log_std = at, log_std
    _arm_once(model, "restart_pending", at, done_now, restart_log_std_now)


def exploration_shift(model: Any, hp: dict, algo: str, done_now: float) -> None:
    """Arm the recipe's ``exploration_shift`` on ``model`` (see the module docstring), the run
    being at progress ``done_now`` under this call's budgets."""
    spec = _log_std_spec(hp, "exploration_shift", "by", algo)
    if spec is None:
        return
    model.shift_at = number_in("exploration_shift: at", spec["at"], 0.0, 1.0)
    model.shift_by = number_in("exploration_shift: by", spec["by"], -10.0, 10.0)
    _arm_once(model, "shift_pending", model.shift_at, done_now, shift_log_std_now)


def _log_std_spec(hp: dict, key: str, value: str, algo: str) -> dict | None:
    """The recipe's ``key: {at: FRACTION, <value>: VALUE}`` (None if absent), refused for
    algorithms without PPO's state-independent log std or in another shape."""
    spec = hp.get(key)
    if spec is None:
        return None
    if algo != "ppo":
        raise ValueError(f"{key} is a PPO setting (its state-independent log std); the {algo} "
                         "recipe cannot use it")
    if not isinstance(spec, dict) or set(spec) != {"at", value}:
        raise ValueError(f"{key} must be {{at: FRACTION, {value}: VALUE}}, got {spec!r}")
    if hp.get("use_sde"):
        # gSDE's log std is a matrix (latent features x actions) whose noise scales with the
        # features: a value of it is not the action noise the key's number means
        raise ValueError(f"{key} sets PPO's state-independent log std; with use_sde the noise "
                         "is gSDE's (a log std per latent feature and action), which it does not "
                         f"handle: drop {key} or use_sde")
    return spec


def _arm_once(model: Any, flag: str, at: float, done_now: float,
              fire: Callable[[Any], None]) -> None:
    """Set ``model.<flag>`` (a change made once at progress ``at``: pending or not), or make
    the change now with ``fire``."""
    # not yet made: as the model saved it; a model that never saved it (new, or a checkpoint
    # of an earlier version) by the progress it saved (the change is made in the update after
    # the first rollout past ``at``, and a checkpoint is written inside a rollout)
    saved = getattr(model, flag, None)
    unfired = done_fraction(model) < at if saved is None else bool(saved)
    if done_now < at:
        # before the point (a resume with a larger budget can put a change made ahead again,
        # as it puts the learning rate back in the first phase)
        setattr(model, flag, True)
    elif unfired:
        # past the point but not made (a checkpoint from the rollout that crossed it): now,
        # as the run that wrote it did after that rollout
        fire(model)
    else:
        setattr(model, flag, False)


def restart_log_std_now(model: Any) -> None:
    """Set PPO's log std to the restart value in every action component, once."""
    import torch

    with torch.no_grad():
        model.policy.log_std.fill_(model.restart_log_std)
    model.restart_pending = False
    tell(model, f"exploration restart at step {model.num_timesteps}: log std set to "
                f"{model.restart_log_std:g} in every action component; the learning rate "
                "decays again from its initial value")


def shift_log_std_now(model: Any) -> None:
    """Shift PPO's log std by the recipe's ``exploration_shift: by`` in every component, once."""
    import torch

    with torch.no_grad():
        model.policy.log_std.add_(model.shift_by)
    model.shift_pending = False
    now = ", ".join(f"{v:.2f}" for v in model.policy.log_std.detach().tolist())
    tell(model, f"exploration shift at step {model.num_timesteps}: log std shifted by "
                f"{model.shift_by:+g}, now [{now}]")


# the log-std changes made once in a run: (pending flag, fraction attribute, change)
_ONCE = (("restart_pending", "restart_at", restart_log_std_now),
         ("shift_pending", "shift_at", shift_log_std_now))


def make_due_changes(model: Any, done: float) -> None:
    """Make each armed change (the restart, then the shift) whose fraction the run's progress
    ``done`` has reached and that is still pending (called after every update)."""
    for flag, at_attr, fire in _ONCE:
        at = getattr(model, at_attr, None)
        if getattr(model, flag, None) and at is not None and done >= at:
            fire(model)


def tell(model: Any, text: str) -> None:
    """Report a phase change through the model's ``phase_log`` (set by train(); None: silent)."""
    log = getattr(model, "phase_log", None)
    if log is not None:
        log(text)


def freeze_obs_stats(model: Any, hp: dict, done_now: float) -> None:
    """Arm the recipe's ``freeze_obs_stats_at`` on ``model``, and freeze now if the run, at
    progress ``done_now`` under this call's budgets, is already past it (a resume)."""
    from .hyperparams import normalize_kwargs

    at = hp.get("freeze_obs_stats_at")
    if at is None:
        return
    at = number_in("freeze_obs_stats_at", at, 0.0, 1.0)
    norm = normalize_kwargs(hp)
    if norm is None or not norm.get("norm_obs", True):
        raise ValueError("freeze_obs_stats_at needs normalised observations (normalize with "
                         "norm_obs true): there are no statistics to freeze")
    model.freeze_obs_at = at
    if done_now >= at:
        model.freeze_obs_now()
