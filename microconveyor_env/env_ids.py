"""The registered env ids and what registering them needs, importable without the envs.

``import microconveyor_env`` registers the envs with Gymnasium from this module alone (stdlib and
PyYAML), so the import stays light; the envs, their configs and the scene logic load when an env
is made (:mod:`microconveyor_env.envs.core.versions` loads what a :class:`Registration` names, with
:func:`resolve`). Package infrastructure: imports no room.
"""
from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass
from importlib import resources
from typing import Any

@dataclass(frozen=True)
class Registration:
    """One registered env id: what ``gym.make`` builds and what the rest of the package needs
    to know of it.

    ``geometry``: ``"line"`` (:class:`~.envs.line.config.EnvConfig`: the next actuator fires),
    ``"positioner"`` (:class:`~.envs.positioner.config.PositionerConfig`: a line on which any
    actuator fires, each firing run to rest) or ``"plane"``
    (:class:`~.envs.plane.config.PlaneEnvConfig`); ``config``: the config class
    (``module:Class``) whose ``from_yaml(None, **kwargs)`` makes the env's config;
    ``entry_point`` / ``vector_entry_point``: the single and batched envs (None: Gymnasium's
    Sync/Async wrappers); ``base``: the scene version (itself, or the version an interface
    variant wraps: the goal env); ``defaults``: whether ``configs/envs/<base>.yaml`` holds
    defaults beyond the config class's own, registered as ``spec.kwargs`` (the plane's config
    class reads its file itself); ``max_episode_steps``: ``spec.max_episode_steps`` (None: no
    TimeLimit, as v0 always was); ``not_scene``: the config fields that are not the scene (how
    the env runs, per-episode randomisation, the reward's weights), so a policy trained with
    other values of them still acts in the same scene."""

    env_id: str
    geometry: str
    config: str
    entry_point: str
    vector_entry_point: str | None
    base: str
    defaults: bool
    max_episode_steps: int | None
    not_scene: frozenset[str]


MAX_ACTUATORS = 1000  # an episode has at most this many steps (one firing per actuator)
PLANE_MAX_FIRINGS = 1000  # spec.max_episode_steps: the most firings a 2-D config allows
POSITIONER_MAX_FIRINGS = 1000  # spec.max_episode_steps: the most firings a positioner allows
_ENVS = "microconveyor_env.envs"
# how an env runs, not what it simulates: may differ between training and evaluation
RUNTIME_FIELDS = frozenset({"num_threads", "max_steps"})
# per-episode randomisation: the conditions a policy is tested under, not the scene it acts in
PERTURBATION_FIELDS = frozenset({"action_noise", "friction_factor_range", "mass_factor_range"})
# how training scores an episode: the scene, the targets, the episode's end and success (at rest
# within the tolerance) do not depend on them, so a policy trained with another reward scale is
# evaluated in the same scene
REWARD_FIELDS = frozenset({"progress_scale", "progress_horizon", "time_cost", "success_bonus",
                           "detach_penalty"})
NOT_SCENE = RUNTIME_FIELDS | PERTURBATION_FIELDS | REWARD_FIELDS

REGISTRY: dict[str, Registration] = {r.env_id: r for r in (
    Registration("MicroConveyor-v0", "line", f"{_ENVS}.line.config:EnvConfig",
                 f"{_ENVS}.line.env:MicroConveyorEnv", f"{_ENVS}.line.vector:MicroConveyorVectorEnv",
                 "MicroConveyor-v0", False, None, NOT_SCENE),
    Registration("MicroConveyor-v1", "line", f"{_ENVS}.line.config:EnvConfig",
                 f"{_ENVS}.line.env:MicroConveyorEnv", f"{_ENVS}.line.vector:MicroConveyorVectorEnv",
                 "MicroConveyor-v1", True, MAX_ACTUATORS, NOT_SCENE),
    Registration("MicroConveyorGoal-v1", "line", f"{_ENVS}.line.config:EnvConfig",
                 f"{_ENVS}.line.goal:MicroConveyorGoalEnv", None,
                 "MicroConveyor-v1", True, MAX_ACTUATORS, NOT_SCENE),
    Registration("MicroConveyor2D-v0", "plane", f"{_ENVS}.plane.config:PlaneEnvConfig",
                 f"{_ENVS}.plane.env:MicroConveyor2DEnv",
                 f"{_ENVS}.plane.vector:MicroConveyor2DVectorEnv",
                 "MicroConveyor2D-v0", False, PLANE_MAX_FIRINGS, NOT_SCENE),
    Registration("MicroConveyor2D-v1", "plane", f"{_ENVS}.plane.config:PlaneEnvConfig",
                 f"{_ENVS}.plane.env:MicroConveyor2DEnv",
                 f"{_ENVS}.plane.vector:MicroConveyor2DVectorEnv",
                 "MicroConveyor2D-v1", True, PLANE_MAX_FIRINGS, NOT_SCENE),
    Registration("MicroPositioner-v0", "positioner",
                 f"{_ENVS}.positioner.config:PositionerConfig",
                 f"{_ENVS}.positioner.env:MicroPositionerEnv",
                 f"{_ENVS}.positioner.vector:MicroPositionerVectorEnv",
                 "MicroPositioner-v0", False, POSITIONER_MAX_FIRINGS, NOT_SCENE),
)}
DEFAULT_ENV_ID = "MicroConveyor-v1"   # what every command and function uses unless told
FIRST_ENV_ID = "MicroConveyor-v0"     # the first registered id: chapter 3's line

# views of the registry
ALL_ENV_IDS = tuple(REGISTRY)
ENV_IDS = tuple(i for i, r in REGISTRY.items() if r.geometry == "line" and r.base == i)
LATEST = ENV_IDS[-1]
# interface variants: the scene and defaults of their base version, another observation
GOAL_ENV_IDS = {i: r.base for i, r in REGISTRY.items() if r.base != i}   # Dict observation
PLANE_ENV_IDS = tuple(i for i, r in REGISTRY.items() if r.geometry == "plane")
POSITIONER_ENV_IDS = tuple(i for i, r in REGISTRY.items() if r.geometry == "positioner")
ENTRY_POINTS = {i: r.entry_point for i, r in REGISTRY.items()}


def base_id(env_id: str) -> str:
    """The scene version of ``env_id`` (itself, or the version an interface variant wraps)."""
    reg = REGISTRY.get(env_id)
    return env_id if reg is None else reg.base


@functools.cache
def _overrides(env_id: str) -> tuple[tuple[str, Any], ...]:
    import yaml

    base = base_id(env_id)
    reg = REGISTRY.get(env_id)
    if reg is None or not reg.defaults:
        return ()
    text = (resources.files("microconveyor_env.configs") / "envs" / f"{base}.yaml").read_text()
    data = yaml.safe_load(text) or {}   # the package's own file
    return tuple((k, tuple(v) if isinstance(v, list) else v) for k, v in data.items())


def overrides(env_id: str) -> dict[str, Any]:
    """``env_id``'s defaults beyond MicroConveyor-v0's (its ``configs/envs/<id>.yaml``); the
    kwargs it is registered with. Unchecked: :func:`.envs.core.versions.registered_kwargs` checks."""
    return dict(_overrides(env_id))


def resolve(ref: str) -> Any:
    """What a registration names (``"module:Name"``: a config class, an env class), imported on
    first use."""
    module, name = ref.split(":")
    return getattr(importlib.import_module(module), name)


def max_episode_steps(env_id: str) -> int | None:
    """``spec.max_episode_steps``: None for v0 (registered as it always was), else the longest
    episode any config of the id can have (:data:`MAX_ACTUATORS`: one step per actuator;
    :data:`PLANE_MAX_FIRINGS`), so the TimeLimit ``gym.make`` adds never cuts an episode
    short."""
    return REGISTRY[env_id].max_episode_steps


def register_all() -> None:
    """Register every id of :data:`REGISTRY` with Gymnasium (idempotent): its entry points,
    ``spec.kwargs`` (its defaults file's values) and episode limit."""
    from gymnasium.envs.registration import register, registry

    for env_id, reg in REGISTRY.items():
        if env_id not in registry:
            register(id=env_id, entry_point=reg.entry_point,
                     vector_entry_point=reg.vector_entry_point, kwargs=overrides(env_id),
                     max_episode_steps=reg.max_episode_steps, disable_env_checker=False)
