"""The registered env ids as the envs see them: the config of any id, its config class and
batched env, and what counts as the scene, over the registry of :mod:`microconveyor_env.env_ids`
(each :class:`~microconveyor_env.env_ids.Registration` names its config class and entry points,
loaded here on first use, so the core names no scene).

A version is a scene's env with its defaults: ``MicroConveyor-v0`` the dataclass defaults of the
line's config (``configs/envs/MicroConveyor-v0.yaml``), each later version those plus the
overrides of its own ``configs/envs/<id>.yaml``, which become the registered
``gym.spec(id).kwargs`` (as Gymnasium's own versions carry theirs). What each version changed
and why: the env cards' version histories (docs/env.md).
"""
from __future__ import annotations

import dataclasses
from typing import Any

from ...env_ids import DEFAULT_ENV_ID, NOT_SCENE, PERTURBATION_FIELDS, REGISTRY, \
    base_id, overrides, resolve
from ...physics.materials import ParameterError

__all__ = ["base_env_id", "check_env_id", "config_class", "nominal", "not_scene",
           "registered_kwargs", "scene_config", "scene_differences", "scene_of", "vector_class",
           "vector_class_of"]


def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a registered version, else a ParameterError naming the versions."""
    if env_id not in REGISTRY:
        raise ParameterError(f"unknown env id {env_id!r}; registered: {', '.join(REGISTRY)}")
    return env_id


def base_env_id(env_id: str) -> str:
    """The scene version of ``env_id`` (itself, or the version an interface variant wraps)."""
    return base_id(check_env_id(env_id))


def config_class(env_id: str) -> type:
    """The config class of a registered ``env_id``, as its registration names it."""
    return resolve(REGISTRY[check_env_id(env_id)].config)


def vector_class(env_id: str) -> type:
    """The batched env of a registered ``env_id`` (an interface variant's: its scene
    version's), as its registration names it."""
    reg = REGISTRY[check_env_id(env_id)]
    ref = reg.vector_entry_point or REGISTRY[reg.base].vector_entry_point
    if ref is None:
        raise ParameterError(f"{env_id} has no batched env")
    return resolve(ref)


def vector_class_of(config: Any) -> type:
    """The batched env of the scene whose config class ``config`` is an instance of."""
    for env_id in REGISTRY:
        if config_class(env_id) is type(config):
            return vector_class(env_id)
    raise ParameterError(f"no registered env takes a {type(config).__name__}")


def registered_kwargs(env_id: str) -> dict[str, Any]:
    """The keyword arguments ``env_id`` is registered with (its defaults beyond its config
    class's own), checked against that class's fields."""
    kw = overrides(check_env_id(env_id))
    unknown = sorted(set(kw) - {f.name for f in dataclasses.fields(config_class(env_id))})
    if unknown:
        raise ParameterError(f"configs/envs/{base_id(env_id)}.yaml: unknown keys {unknown}")
    return kw


def scene_config(env_id: str = DEFAULT_ENV_ID, **overrides: Any) -> Any:
    """The validated config of ``gym.make(env_id, **overrides)`` (SI units) of any registered
    id: its config class's ``from_yaml`` with the id's registered kwargs, then ``overrides``."""
    cls: Any = config_class(env_id)
    if "path" in overrides:
        raise ParameterError(f"{cls.__name__}: unknown key 'path' (an env is made from its id "
                             "and field values; from_yaml reads a file)")
    return cls.from_yaml(None, **{**registered_kwargs(env_id), **overrides})


def scene_differences(trained: Any, asked: Any) -> dict[str, tuple[Any, Any]]:
    """Fields (name -> (trained, asked)) in which two configs describe different scenes or
    tasks; runtime knobs, per-episode randomisation and the reward's weights are not the
    scene. Configs of two geometries (two config classes) differ in ``"geometry"``."""
    if type(trained) is not type(asked):
        return {"geometry": (_geometry(trained), _geometry(asked))}
    a, b = dataclasses.asdict(trained), dataclasses.asdict(asked)
    skip = not_scene(trained)
    return {k: (a[k], b[k]) for k in a if k not in skip and a[k] != b[k]}


def _geometry(config: Any) -> str:
    """The geometry and config class of ``config``, e.g. ``"the line (EnvConfig)"``, for
    messages."""
    kind = next((reg.geometry for reg in REGISTRY.values()
                 if config_class(reg.env_id) is type(config)), "unknown")
    return f"the {kind} ({type(config).__name__})"


def not_scene(config: Any) -> frozenset[str]:
    """The fields of ``config`` that are not its scene, as its registrations say."""
    for reg in REGISTRY.values():
        if config_class(reg.env_id) is type(config):
            return reg.not_scene
    return NOT_SCENE


def scene_of(config: Any) -> dict[str, Any]:
    """The fields of ``config`` that are its scene (those :func:`scene_differences` compares),
    JSON-safe: SI values, ranges as lists."""
    skip = not_scene(config)
    return {k: list(v) if isinstance(v, tuple) else v
            for k, v in dataclasses.asdict(config).items() if k not in skip}


def nominal(config: Any) -> Any:
    """``config`` with per-episode randomisation off (its scene under nominal conditions); a
    config without randomisation fields as it is."""
    off: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(type(config))
                           if f.name in PERTURBATION_FIELDS}
    if not off:
        return config
    return dataclasses.replace(config, **off)
