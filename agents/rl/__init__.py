"""Reinforcement learning on the conveyor: :mod:`.training` (PPO, SAC, TQC with stable-baselines3,
recipes, resumable runs), :mod:`.tuning` (Optuna search), :mod:`.artefacts` (policy folders and
checkpoints, loaded as data), :mod:`.evaluation` (fixed seeded targets, aggregates over seeds) and
:mod:`.refinement` (Newton corrections of a policy's aim fitted back into its actor)."""
