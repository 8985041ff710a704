"""The registered versions of the conveyor env: their ids, defaults and what counts as the scene.

Every version is :class:`~.conveyor.MicroConveyorEnv` with different defaults:
``MicroConveyor-v0`` the dataclass defaults of :class:`~.config.EnvConfig`
(``configs/envs/MicroConveyor-v0.yaml``), each later version those plus the overrides of its own
``configs/envs/<id>.yaml``, which become the registered ``gym.spec(id).kwargs`` (as Gymnasium's
own versions carry theirs). What each version changed and why: the env card's version history
(:class:`~.conveyor.MicroConveyorEnv`, docs/env.md).
"""
from __future__ import annotations

import dataclasses
from typing import Any

# the ids themselves live in the light ..env_ids (registration imports only it); re-exported
from ..env_ids import ALL_ENV_IDS, ENTRY_POINTS, ENV_IDS, GOAL_ENV_IDS, LATEST, MAX_ACTUATORS, \
    base_id, overrides
from ..physics.materials import ParameterError
from .config import EnvConfig

__all__ = ["ALL_ENV_IDS", "ENTRY_POINTS", "ENV_IDS", "GOAL_ENV_IDS", "LATEST", "MAX_ACTUATORS",
           "base_env_id", "check_env_id", "env_config", "nominal", "registered_kwargs",
           "scene_differences", "scene_of"]
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


def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a registered version, else a ParameterError naming the versions."""
    if env_id not in ALL_ENV_IDS:
        raise ParameterError(f"unknown env id {env_id!r}; registered: {', '.join(ALL_ENV_IDS)}")
    return env_id


def base_env_id(env_id: str) -> str:
    """The scene version of ``env_id`` (itself, or the version an interface variant wraps)."""
    return base_id(check_env_id(env_id))


def registered_kwargs(env_id: str) -> dict[str, Any]:
    """The keyword arguments ``env_id`` is registered with (its defaults beyond v0's), checked
    against :class:`EnvConfig`'s fields."""
    kw = overrides(check_env_id(env_id))
    unknown = sorted(set(kw) - {f.name for f in dataclasses.fields(EnvConfig)})
    if unknown:
        raise ParameterError(f"configs/envs/{base_id(env_id)}.yaml: unknown keys {unknown}")
    return kw


def env_config(env_id: str = LATEST, **overrides: Any) -> EnvConfig:
    """The validated config of ``gym.make(env_id, **overrides)`` (SI units)."""
    if "path" in overrides:
        raise ParameterError("EnvConfig: unknown key 'path' (an env is made from its id and "
                             "field values; EnvConfig.from_yaml reads a file)")
    return EnvConfig.from_yaml(None, **{**registered_kwargs(env_id), **overrides})


def scene_differences(trained: EnvConfig, asked: EnvConfig) -> dict[str, tuple[Any, Any]]:
    """Fields (name -> (trained, asked)) in which two configs describe different scenes or
    tasks; runtime knobs, per-episode randomisation and the reward's weights are not the
    scene."""
    a, b = dataclasses.asdict(trained), dataclasses.asdict(asked)
    return {k: (a[k], b[k]) for k in a if k not in NOT_SCENE and a[k] != b[k]}


def scene_of(config: EnvConfig) -> dict[str, Any]:
    """The fields of ``config`` that are its scene (those :func:`scene_differences` compares),
    JSON-safe: SI values, ranges as lists."""
    return {k: list(v) if isinstance(v, tuple) else v
            for k, v in dataclasses.asdict(config).items() if k not in NOT_SCENE}


def nominal(config: EnvConfig) -> EnvConfig:
    """``config`` with per-episode randomisation off (its scene under nominal conditions)."""
    off: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(EnvConfig)
                           if f.name in PERTURBATION_FIELDS}
    return dataclasses.replace(config, **off)
