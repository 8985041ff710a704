"""Agents that drive :mod:`microconveyor_env` (which never imports this package): open-loop
planning (:mod:`.openloop`: DE and CMA-ES, per-target plans, the dissertation's problem, Table
4.3), reinforcement learning (:mod:`.rl`: PPO, SAC and TQC training, tuning, policy files,
evaluation, refinement), model-predictive control (:mod:`.mpc`), the experiments that compare them
(:mod:`.experiments`), their charts (:mod:`.plots`) and their ``microconveyor`` commands
(:mod:`.cli`)."""
