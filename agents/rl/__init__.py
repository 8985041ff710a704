"""Reinforcement learning: training (SB3 PPO), checkpoints, policy files loaded as data, evaluation, seeds, shipped policies."""
