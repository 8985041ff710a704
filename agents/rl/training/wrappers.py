"""The VecEnv wrappers a recipe may name (rl-zoo3's ``vec_env_wrapper`` key), training only.

A recipe is data: :func:`wrap` builds only the classes in :data:`WRAPPERS` and never imports
what a recipe names. They sit outside the monitor (which records the env's own returns) and
inside VecNormalize.
"""
from __future__ import annotations

from typing import Any

from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from .shaping import LogErrorShaping
from .targets import TargetMixture

# what a recipe's vec_env_wrapper may name: rl-zoo3's dotted path -> the class
WRAPPERS: dict[str, type[VecEnvWrapper]] = {
    "agents.rl.training.shaping.LogErrorShaping": LogErrorShaping,
    "agents.rl.training.targets.TargetMixture": TargetMixture,
}


def wrap(venv: VecEnv, spec: Any) -> VecEnv:
    """``venv`` inside the wrappers of a recipe's ``vec_env_wrapper`` (rl-zoo3's forms: a
    name, ``{name: kwargs}``, or a list of these, innermost first); ValueError for a name
    not in :data:`WRAPPERS` or kwargs it does not take."""
    if spec is None:
        return venv
    for item in spec if isinstance(spec, list) else [spec]:
        kwargs: Any
        if isinstance(item, str):
            name, kwargs = item, {}
        elif isinstance(item, dict) and len(item) == 1:
            (name, kwargs), = item.items()
            kwargs = kwargs or {}
        else:
            raise ValueError(f"vec_env_wrapper: expected a name or {{name: kwargs}}, got {item!r}")
        if name not in WRAPPERS:
            raise ValueError(f"vec_env_wrapper {name!r} is not one this package builds "
                             f"(known: {', '.join(WRAPPERS)})")
        if not isinstance(kwargs, dict):
            raise ValueError(f"vec_env_wrapper {name}: kwargs must be a mapping, got {kwargs!r}")
        try:
            venv = WRAPPERS[name](venv, **kwargs)
        except TypeError as exc:
            raise ValueError(f"vec_env_wrapper {name}: {exc}") from None
    return venv
