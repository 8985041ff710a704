"""PPO hyperparameters from ``configs/ppo.yml`` (rl-zoo3's format, keyed by env id)."""
from __future__ import annotations

from importlib import resources

import yaml

ENV_ID = "MicroConveyor-v0"
# keys the trainer handles itself (the rest go to PPO(...))
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs")


def load(path: str | None = None, env_id: str = ENV_ID) -> dict:
    """The hyperparameters of ``env_id`` from ``path`` (default: the shipped configs/ppo.yml),
    with ``policy_kwargs`` and ``normalize`` strings evaluated as rl-zoo3 does (dict(...))."""
    if path is None:
        text = (resources.files("microconveyor_env.configs") / "ppo.yml").read_text()
    else:
        with open(path) as fh:
            text = fh.read()
    data = yaml.safe_load(text) or {}
    if env_id not in data:
        raise ValueError(f"{path or 'configs/ppo.yml'} has no entry for {env_id!r}")
    hp = dict(data[env_id])
    for key in ("policy_kwargs", "normalize"):
        if isinstance(hp.get(key), str):
            hp[key] = _eval_dict(hp[key])
    if hp.get("normalize") is True:
        hp["normalize"] = {}
    return hp


def linear_schedule(value: float):
    """rl-zoo3's ``lin_<value>``: decays linearly from ``value`` to 0 over the run."""
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * value
    return schedule


def _eval_dict(text: str) -> dict:
    import torch.nn as nn

    value = eval(text, {"__builtins__": {}}, {"dict": dict, "nn": nn})  # noqa: S307 - rl-zoo3 format
    if not isinstance(value, dict):
        raise ValueError(f"{text!r} is not a dict(...)")
    return value


def ppo_kwargs(hp: dict) -> dict:
    """PPO(...) keyword arguments; ``lin_<value>`` strings (learning_rate, clip_range) become
    linear schedules as in rl-zoo3."""
    out = {k: v for k, v in hp.items() if k not in RUN_KEYS}
    for key in ("learning_rate", "clip_range"):
        if isinstance(out.get(key), str) and out[key].startswith("lin_"):
            out[key] = linear_schedule(float(out[key][4:]))
    return out
