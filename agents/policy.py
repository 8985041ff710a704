"""The shipped policy: PPO trained from scratch by ``microconveyor train`` (see its
``metadata.json`` for the config hash, steps, wall time and evaluation)."""
from __future__ import annotations

from importlib import resources
from pathlib import Path


def shipped_path(name: str = "policy") -> Path:
    """The folder of a shipped policy: ``policy`` (the default, trained on the nominal env) or
    ``policy_randomised`` (trained under per-episode randomisation, configs/ppo_randomised.yml)."""
    return Path(str(resources.files("agents") / name))
