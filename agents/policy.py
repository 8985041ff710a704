"""The shipped policy: PPO trained from scratch by ``microconveyor train`` (see its
``metadata.json`` for the config hash, steps, wall time and evaluation)."""
from __future__ import annotations

from importlib import resources
from pathlib import Path


def shipped_path() -> Path:
    return Path(str(resources.files("agents") / "policy"))
