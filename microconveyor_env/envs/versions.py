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
import functools
from importlib import resources
from typing import Any

from ..physics.materials import ParameterError
from .config import MAX_ACTUATORS, EnvConfig

ENV_IDS = ("MicroConveyor-v0", "MicroConveyor-v1")
LATEST = ENV_IDS[-1]
# interface variants: same scene and defaults as their base version, another observation
GOAL_ENV_IDS = {"MicroConveyorGoal-v1": "MicroConveyor-v1"}   # Dict observation (envs/goal.py)
ALL_ENV_IDS = ENV_IDS + tuple(GOAL_ENV_IDS)
ENTRY_POINTS = {**{i: "microconveyor_env.envs.conveyor:MicroConveyorEnv" for i in ENV_IDS},
                **{i: "microconveyor_env.envs.goal:MicroConveyorGoalEnv" for i in GOAL_ENV_IDS}}
# how an env runs, not what it simulates: may differ between training and evaluation
RUNTIME_FIELDS = frozenset({"num_threads", "max_steps"})
# per-episode randomisation: the conditions a policy is tested under, not the scene it acts in
PERTURBATION_FIELDS = frozenset({"action_noise", "friction_factor_range", "mass_factor_range"})


def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a registered version, else a ParameterError naming the versions."""
    if env_id not in ALL_ENV_IDS:
        raise ParameterError(f"unknown env id {env_id!r}; registered: {', '.join(ALL_ENV_IDS)}")
    return env_id


@functools.cache
def _overrides(env_id: str) -> tuple[tuple[str, Any], ...]:
    from ..presets import parse_yaml

    if env_id == ENV_IDS[0]:
        return ()
    res = resources.files("microconveyor_env.configs") / "envs" / f"{env_id}.yaml"
    data = parse_yaml(res.read_text(), f"env config {env_id}") or {}
    known = {f.name for f in dataclasses.fields(EnvConfig)}
    if not isinstance(data, dict) or set(data) - known:
        raise ParameterError(f"configs/envs/{env_id}.yaml: unknown keys "
                             f"{sorted(set(data) - known) if isinstance(data, dict) else data!r}")
    return tuple((k, tuple(v) if isinstance(v, list) else v) for k, v in data.items())


def base_env_id(env_id: str) -> str:
    """The scene version of ``env_id`` (itself, or the version an interface variant wraps)."""
    return GOAL_ENV_IDS.get(check_env_id(env_id), env_id)


def registered_kwargs(env_id: str) -> dict[str, Any]:
    """The keyword arguments ``env_id`` is registered with (its defaults beyond v0's)."""
    return dict(_overrides(base_env_id(env_id)))


def env_config(env_id: str = LATEST, **overrides: Any) -> EnvConfig:
    """The validated config of ``gym.make(env_id, **overrides)`` (SI units)."""
    return EnvConfig.from_yaml(**{**registered_kwargs(env_id), **overrides})


def max_episode_steps(env_id: str) -> int:
    """``spec.max_episode_steps`` of ``env_id``: the longest episode any config of it can have
    (one step per actuator, at most :data:`~.config.MAX_ACTUATORS`), so the TimeLimit that
    ``gym.make`` adds never cuts an episode short, whatever ``n_actuators`` is."""
    check_env_id(env_id)
    return MAX_ACTUATORS


def scene_differences(trained: EnvConfig, asked: EnvConfig) -> dict[str, tuple[Any, Any]]:
    """Fields (name -> (trained, asked)) in which two configs describe different scenes or
    tasks; runtime knobs and per-episode randomisation are not the scene."""
    a, b = dataclasses.asdict(trained), dataclasses.asdict(asked)
    skip = RUNTIME_FIELDS | PERTURBATION_FIELDS
    return {k: (a[k], b[k]) for k in a if k not in skip and a[k] != b[k]}


def nominal(config: EnvConfig) -> EnvConfig:
    """``config`` with per-episode randomisation off (its scene under nominal conditions)."""
    off: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(EnvConfig)
                           if f.name in PERTURBATION_FIELDS}
    return dataclasses.replace(config, **off)
