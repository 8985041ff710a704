"""The algorithms ``microconveyor train --algo`` runs, and what each needs from the env.

``ppo`` (on-policy) trains on the compiled batch (:class:`MicroConveyorSB3VecEnv`, Box
observations). ``sac`` and ``tqc`` (off-policy; TQC from sb3-contrib) train either on the same
batch or, on a goal-conditioned id (``MicroConveyorGoal-v1``), on single Dict-observation envs
with SB3's ``HerReplayBuffer`` (``replay_buffer_class: HerReplayBuffer`` in the config), which
relabels goals through the env's ``compute_reward``. Each algorithm's hyperparameters live in
``configs/<algo>.yml`` (rl-zoo3's format, keyed by env id).

Every class is wrapped by :func:`budgeted`: its schedules (``lin_`` learning rate, clip range)
run out with whichever budget ends first, the step count or the wall time, and its gradient
updates run on ``update_threads`` torch threads.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

ALGO_NAMES = ("ppo", "sac", "tqc")
ON_POLICY = frozenset({"ppo"})


def budgeted(base: type) -> type:
    """``base`` (an SB3 algorithm class) with the wall-time budget and update threads."""

    class Budgeted(base):
        budget_clock: Callable[[], float] | None = None  # set by train(); not saved
        # torch threads for the gradient updates (rollouts keep one). On v1's recipe 2 gave
        # no gain in a same-state A/B on the idle 2-core machine, and ~500 steps/s when the
        # cores are busy (docs/agents.md, "Where PPO's time goes on v1")
        update_threads = 1
        # where phase changes are reported (the restart, the shift, the frozen statistics;
        # set by train(), not saved); None: silent
        phase_log: Callable[[str], None] | None = None
        # PPO's exploration restart (set by train() from the recipe's exploration_restart):
        # once the run's progress (steps or wall budget, whichever is further) reaches the
        # fraction restart_at, the log std of every action component is set to
        # restart_log_std, once (restart_pending, saved with the model: a resume knows
        # whether it fired; None: a new model or a checkpoint from before it was saved);
        # restart_at None: no restart
        restart_at: float | None = None
        restart_log_std: float = 0.0
        restart_pending: bool | None = None
        # PPO's exploration shift (the recipe's exploration_shift): at progress shift_at the
        # log std is shifted by shift_by, once (shift_pending saved with the model, as above)
        shift_at: float | None = None
        shift_by: float = 0.0
        shift_pending: bool | None = None
        # VecNormalize's observation statistics stop updating once the run's progress reaches
        # freeze_obs_at (set by train() from the recipe's freeze_obs_stats_at); None: never, or
        # already frozen in this run
        freeze_obs_at: float | None = None
        _current_progress_remaining: float

        def _excluded_save_params(self) -> list:
            return [*super()._excluded_save_params(), "budget_clock", "update_threads", "phase_log",
                    "restart_at", "restart_log_std", "shift_at", "shift_by", "freeze_obs_at"]

        def train(self, *args: Any, **kwargs: Any) -> None:
            import torch

            before = torch.get_num_threads()
            torch.set_num_threads(self.update_threads)
            try:
                super().train(*args, **kwargs)
            finally:
                torch.set_num_threads(before)
            # after this update, before the next rollout: the next rollout explores with the
            # changed noise and its log-probabilities are computed with it
            from .phases import make_due_changes

            make_due_changes(self, 1.0 - self._current_progress_remaining)

        def _update_current_progress_remaining(self, num_timesteps: int,
                                               total_timesteps: int) -> None:
            super()._update_current_progress_remaining(num_timesteps, total_timesteps)
            if self.budget_clock is not None:
                self._current_progress_remaining = max(0.0, min(
                    self._current_progress_remaining, 1.0 - self.budget_clock()))
            self.freeze_obs_if_due()

        def freeze_obs_if_due(self) -> bool:
            """Freeze the observation statistics if the run's progress has reached
            ``freeze_obs_at`` (after a rollout, before its update: the next rollout is the
            first normalised with the frozen statistics); True if they were frozen now."""
            if (self.freeze_obs_at is None
                    or 1.0 - self._current_progress_remaining < self.freeze_obs_at):
                return False
            self.freeze_obs_at = None  # done for this run (off-policy calls this every step)
            return self.freeze_obs_now()

        def freeze_obs_now(self) -> bool:
            """Freeze the observation statistics of the VecNormalize the model trains in (once;
            True if they were frozen now)."""
            from ..artefacts.normalization import freeze_obs_stats
            from .phases import tell

            vn = getattr(self, "_vec_normalize_env", None)
            frozen = vn is not None and freeze_obs_stats(vn)
            if frozen:
                tell(self, f"observation statistics frozen at step {self.num_timesteps}")
            return frozen

    Budgeted.__name__ = Budgeted.__qualname__ = f"Budget{base.__name__}"
    Budgeted.__module__ = __name__
    return Budgeted


_CLASSES: dict[str, type] = {}


def algo_class(algo: str) -> type:
    """The budgeted SB3 class of ``algo`` (one of :data:`ALGO_NAMES`)."""
    if algo not in ALGO_NAMES:
        raise ValueError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGO_NAMES)}")
    if algo not in _CLASSES:
        from ..artefacts.sb3_files import algo_class as sb3_class

        try:
            _CLASSES[algo] = budgeted(sb3_class(algo))
        except ImportError:  # pragma: no cover - the agents extra installs sb3-contrib
            raise ValueError(f"--algo {algo} needs sb3-contrib: pip install "
                             "'microconveyor-env[agents]'") from None
    return _CLASSES[algo]
