"""The shipped policies, one folder per env id and run name under ``agents/policies``:
``agents/policies/<env id>/<name>/`` with ``model.zip``, ``normalization.json``,
``metadata.json`` (config hash, steps, wall time, evaluations and how they were produced, the
files' sha256) and ``episodes.json`` (every evaluated episode)."""
from __future__ import annotations

import datetime
import platform
from importlib import resources
from pathlib import Path
from typing import Any

from microconveyor_env.env_ids import DEFAULT_ENV_ID

# the policy every command uses for an env id unless told (``--policy``): the most accurate one
# shipped for it; an id not named here uses ``ppo``. Chosen here, in code, rather than by a
# marker in a policy's metadata: metadata travels with a folder a user copies or receives, and
# one table cannot name two defaults for one id.
DEFAULT_POLICIES = {"MicroConveyor-v1": "ppo_refined", "MicroPositioner-v0": "dagger"}


def default_policy_name(env_id: str = DEFAULT_ENV_ID) -> str:
    """The name of ``env_id``'s default shipped policy (:data:`DEFAULT_POLICIES`, else ``ppo``)."""
    return DEFAULT_POLICIES.get(env_id, "ppo")


def shipped_path(name: str | None = None, env_id: str = DEFAULT_ENV_ID) -> Path:
    """The folder of a shipped policy of ``env_id``: ``ppo`` (trained on the nominal env),
    ``ppo_randomised`` (trained under per-episode randomisation, configs/ppo_randomised.yml),
    ``ppo_refined`` (``ppo`` with its aim corrected on the simulator); None: the env's default
    (:func:`default_policy_name`)."""
    name = default_policy_name(env_id) if name is None else name
    return Path(str(resources.files("agents") / "policies" / env_id / name))


def shipped_policies(root: str | Path | None = None) -> dict[str, list[str]]:
    """Every shipped policy, as {env id: [names]}: the package's, or those under ``root`` (a
    folder laid out as ``agents/policies``)."""
    root = Path(str(resources.files("agents") / "policies")) if root is None else Path(root)
    return {env.name: sorted(p.name for p in env.iterdir() if (p / "model.zip").is_file())
            for env in sorted(root.iterdir()) if env.is_dir()}


def require_shipped(env_id: str = DEFAULT_ENV_ID, name: str | None = None) -> Path:
    """:func:`shipped_path` (``name`` None: the env's default policy; for an interface variant
    with no policy of its own, e.g. the goal env, its scene version's default), or a ValueError
    naming what is shipped when there is none."""
    from microconveyor_env.env_ids import base_id

    if name is None and not shipped_path(None, env_id).is_dir():
        env_id = base_id(env_id)
    name = default_policy_name(env_id) if name is None else name
    path = shipped_path(name, env_id)
    if not (path / "model.zip").is_file():
        have = "; ".join(f"{e}: {', '.join(n)}" for e, n in shipped_policies().items()) or "none"
        raise ValueError(f"no shipped {name!r} policy for {env_id} (shipped: {have}); train one "
                         "(microconveyor train --env ...) and pass --policy")
    return path


def provenance(command: str = "microconveyor record") -> dict[str, Any]:
    """What a recorded evaluation of a shipped policy was computed with: package, torch, SB3,
    numpy and Python versions, the machine, the time (UTC) and the ``command`` that records."""
    from importlib.metadata import version

    import numpy as np
    import stable_baselines3
    import torch

    return {"package_version": version("microconveyor-env"), "torch": torch.__version__,
            "stable_baselines3": stable_baselines3.__version__, "numpy": np.__version__,
            "machine": platform.machine(), "python": platform.python_version(),
            "recorded_utc": datetime.datetime.now(datetime.UTC).isoformat(
                timespec="seconds"),
            "command": command}
