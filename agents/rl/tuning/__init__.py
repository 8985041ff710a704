"""Hyperparameter search with Optuna on a shared storage (``microconveyor tune``) and its search
space."""
