"""The registered env ids and what registering them needs, importable without the envs.

``import microconveyor_env`` registers the envs with Gymnasium from this module alone (stdlib and
PyYAML), so the import stays light; the envs, their configs and the scene logic load when an env
is made (:mod:`microconveyor_env.envs.versions`). Package infrastructure: imports no room.
"""
from __future__ import annotations

import functools
from importlib import resources
from typing import Any

ENV_IDS = ("MicroConveyor-v0", "MicroConveyor-v1")
LATEST = ENV_IDS[-1]
# interface variants: the scene and defaults of their base version, another observation
GOAL_ENV_IDS = {"MicroConveyorGoal-v1": "MicroConveyor-v1"}   # Dict observation (envs/goal.py)
ALL_ENV_IDS = ENV_IDS + tuple(GOAL_ENV_IDS)
ENTRY_POINTS = {**{i: "microconveyor_env.envs.conveyor:MicroConveyorEnv" for i in ENV_IDS},
                **{i: "microconveyor_env.envs.goal:MicroConveyorGoalEnv" for i in GOAL_ENV_IDS}}
VECTOR_ENTRY_POINT = "microconveyor_env.envs.vector:MicroConveyorVectorEnv"  # ENV_IDS only
MAX_ACTUATORS = 1000  # an episode has at most this many steps (one firing per actuator)
# the plane (issue 22): its own config (envs/plane_config.py, defaults in
# configs/envs/MicroConveyor2D-v0.yaml), registered with kwargs {} as v0 is
PLANE_ENV_IDS = ("MicroConveyor2D-v0",)
PLANE_ENTRY_POINT = "microconveyor_env.envs.plane_env:MicroConveyor2DEnv"
PLANE_VECTOR_ENTRY_POINT = "microconveyor_env.envs.plane_vector:MicroConveyor2DVectorEnv"
PLANE_MAX_FIRINGS = 1000  # spec.max_episode_steps: the most firings a 2-D config allows


def base_id(env_id: str) -> str:
    """The scene version of ``env_id`` (itself, or the version an interface variant wraps)."""
    return GOAL_ENV_IDS.get(env_id, env_id)


@functools.cache
def _overrides(env_id: str) -> tuple[tuple[str, Any], ...]:
    import yaml

    base = base_id(env_id)
    if base == ENV_IDS[0]:
        return ()
    text = (resources.files("microconveyor_env.configs") / "envs" / f"{base}.yaml").read_text()
    data = yaml.safe_load(text) or {}   # the package's own file
    return tuple((k, tuple(v) if isinstance(v, list) else v) for k, v in data.items())


def overrides(env_id: str) -> dict[str, Any]:
    """``env_id``'s defaults beyond MicroConveyor-v0's (its ``configs/envs/<id>.yaml``); the
    kwargs it is registered with. Unchecked: :func:`..envs.versions.registered_kwargs` checks."""
    return dict(_overrides(env_id))


def max_episode_steps(env_id: str) -> int | None:
    """``spec.max_episode_steps``: None for v0 (registered as it always was), else
    :data:`MAX_ACTUATORS`, the longest episode any config can have (one step per actuator),
    so the TimeLimit ``gym.make`` adds never cuts an episode short, whatever ``n_actuators``."""
    return None if env_id == ENV_IDS[0] else MAX_ACTUATORS
