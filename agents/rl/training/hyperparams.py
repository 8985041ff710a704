"""Hyperparameters from ``configs/<algo>.yml`` (rl-zoo3's format, keyed by env id).

An entry holds what rl-zoo3 reads (``python -m rl_zoo3.train --conf-file FILE`` runs it as it
is). Keys only this package's trainer reads (:data:`PACKAGE_KEYS`, the run phases of
:mod:`.phases`), which rl-zoo3 would hand to the algorithm and the algorithm refuse, go in the
file's :data:`PACKAGE_SECTION` section, keyed by env id like the entries::

    MicroConveyor-v1:
      n_envs: 256
      ...
    microconveyor:            # read by `microconveyor train` only
      MicroConveyor-v1:
        exploration_restart: {at: 0.667, log_std: -2.0}

:func:`load` merges an env's package keys into its entry. A file of your own may also keep
them in the entry itself (then rl-zoo3 cannot run that entry).
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable
from importlib import resources
from typing import Any

import yaml

from microconveyor_env.env_ids import DEFAULT_ENV_ID

ENV_ID = DEFAULT_ENV_ID  # what `train` trains on unless told
# keys only this package's trainer reads (rl-zoo3 would pass them to the algorithm)
PACKAGE_KEYS = ("exploration_restart", "exploration_shift", "freeze_obs_stats_at")
# the section of a config file holding them, per env id (rl-zoo3 reads only its --env's entry)
PACKAGE_SECTION = "microconveyor"
CONFIG_LIMIT = 1 << 20   # bytes of a config file read
# keys the trainer handles itself (the rest go to PPO(...))
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "vec_env_wrapper",
            *PACKAGE_KEYS)


def number_in(name: str, val: Any, lo: float = -math.inf, hi: float = math.inf, *,
              what: str = "a number", closed_hi: bool = False) -> float:
    """A recipe value as a float: a finite number (a bool is not one) in ``(lo, hi)`` (``(lo,
    hi]`` with ``closed_hi``); otherwise a ValueError naming ``name``."""
    ok = (not isinstance(val, bool) and isinstance(val, (int, float)) and math.isfinite(val)
          and lo < val and (val <= hi if closed_hi else val < hi))
    if not ok:
        raise ValueError(f"{name} must be {what} in ({lo:g}, {hi:g}{']' if closed_hi else ')'}"
                         f", got {val!r}")
    return float(val)


def load(path: str | None = None, env_id: str = ENV_ID, algo: str = "ppo") -> dict:
    """The hyperparameters of ``env_id`` from ``path`` (default: the shipped
    ``configs/<algo>.yml``): its entry with its keys of the :data:`PACKAGE_SECTION` section
    merged in, and the ``dict(...)`` strings (``policy_kwargs``, ``normalize``,
    ``replay_buffer_kwargs``) parsed as rl-zoo3 writes them (as data: nothing is evaluated)."""
    if path is None:
        try:
            text = (resources.files("microconveyor_env.configs") / f"{algo}.yml").read_text()
        except FileNotFoundError:
            raise ValueError(f"no shipped config for {algo!r} (configs/{algo}.yml)") from None
    else:
        from microconveyor_env.safe_files import UnsafeFileError, read_text

        try:   # a config file may come from someone else: a regular file within bounds
            text = read_text(path, CONFIG_LIMIT, follow_symlinks=True)
        except UnsafeFileError as exc:
            raise ValueError(f"--conf-file: {exc}") from None
    data = yaml.safe_load(text) or {}
    where = path or f"configs/{algo}.yml"
    if not isinstance(data, dict):
        raise ValueError(f"{where} is not a mapping of env ids to hyperparameters")
    package = data.pop(PACKAGE_SECTION, None) or {}
    if env_id not in data:
        raise ValueError(f"{where} has no entry for {env_id!r} (it has "
                         f"{', '.join(map(str, data)) or 'none'}): give the env id of one of "
                         "them (--env) or add an entry")
    hp = dict(data[env_id])
    hp.update(_package_keys(package, env_id, hp, where))
    for key in ("policy_kwargs", "normalize", "replay_buffer_kwargs"):
        if isinstance(hp.get(key), str):
            hp[key] = _eval_dict(hp[key])
    if hp.get("normalize") is True:
        hp["normalize"] = {}
    return hp


def _package_keys(section: Any, env_id: str, entry: dict, where: str) -> dict:
    """``env_id``'s keys of a file's :data:`PACKAGE_SECTION` section (checked: only
    :data:`PACKAGE_KEYS`, none also in the entry itself)."""
    if not isinstance(section, dict):
        raise ValueError(f"{where}: {PACKAGE_SECTION} must map env ids to keys, got {section!r}")
    keys = section.get(env_id) or {}
    if not isinstance(keys, dict):
        raise ValueError(f"{where}: {PACKAGE_SECTION}.{env_id} must be a mapping, got {keys!r}")
    other = sorted(set(keys) - set(PACKAGE_KEYS))
    if other:
        raise ValueError(f"{where}: {PACKAGE_SECTION}.{env_id} holds only "
                         f"{', '.join(PACKAGE_KEYS)}; {', '.join(other)} belong in the entry")
    twice = sorted(set(keys) & set(entry))
    if twice:
        raise ValueError(f"{where}: {', '.join(twice)} given both in the {env_id} entry and in "
                         f"{PACKAGE_SECTION}.{env_id}")
    return dict(keys)


def split_package_keys(hp: dict) -> tuple[dict, dict]:
    """``hp`` as (the rl-zoo3 entry, its :data:`PACKAGE_KEYS`): what a config file writes in
    the entry and in its :data:`PACKAGE_SECTION` section."""
    return ({k: v for k, v in hp.items() if k not in PACKAGE_KEYS},
            {k: v for k, v in hp.items() if k in PACKAGE_KEYS})


def normalize_kwargs(hp: dict) -> dict | None:
    """VecNormalize's keyword arguments from a recipe's ``normalize`` (``true`` or ``{}``: the
    defaults; absent, null or ``false``: no normalisation, None)."""
    norm = hp.get("normalize")
    if norm is None or norm is False:
        return None
    if norm is True:
        return {}
    if not isinstance(norm, dict):
        raise ValueError(f"normalize must be true, false or a mapping of VecNormalize's "
                         f"arguments, got {norm!r}")
    return norm


def changed_keys(old: dict, new: dict) -> list[str]:
    """Top-level keys whose values differ between two configs (compared as sorted JSON)."""
    keys = sorted(set(old) | set(new))
    return [k for k in keys if json.dumps(old.get(k), sort_keys=True, default=str)
            != json.dumps(new.get(k), sort_keys=True, default=str)]


def linear_schedule(value: float) -> Callable[[float], float]:
    """rl-zoo3's ``lin_<value>``: decays linearly from ``value`` to 0 over the run."""
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * value
    return schedule


# torch.nn activation classes a config may name as ``nn.<Name>`` (nothing else is resolved)
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "Mish")


def _eval_dict(text: str) -> dict:
    """rl-zoo3's ``dict(key=value, ...)`` strings, parsed as data: keyword arguments whose values
    are literals (numbers, strings, booleans, None, lists, tuples, dicts), nested ``dict(...)``
    or ``nn.<Activation>``. Nothing is evaluated: any other expression is a ValueError."""
    import ast

    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ValueError(f"{text!r} is not a dict(...) expression ({exc.msg})") from None
    value = _node_value(tree, text)
    if not isinstance(value, dict):
        raise ValueError(f"{text!r} is not a dict(...)")
    return value


def _node_value(node: Any, text: str) -> Any:
    import ast

    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict":
        if node.args or any(k.arg is None for k in node.keywords):
            raise ValueError(f"{text!r}: dict(...) takes keyword arguments only")
        return {k.arg: _node_value(k.value, text) for k in node.keywords}
    if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
            and node.value.id == "nn" and node.attr in ACTIVATIONS):
        import torch.nn as nn

        return getattr(nn, node.attr)
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_node_value(e, text) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.Dict):
        if any(k is None for k in node.keys):
            raise ValueError(f"{text!r}: ** in a dict literal is not allowed")
        return {_node_value(k, text): _node_value(v, text) for k, v in zip(node.keys, node.values, strict=True)}
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise ValueError(f"{text!r}: {ast.unparse(node)!r} is not a literal, dict(...) or "
                         f"nn.<{'|'.join(ACTIVATIONS)}>; config files are data and nothing in "
                         "them is evaluated") from None


# replay buffers a config may name (rl-zoo3 writes the class name)
REPLAY_BUFFERS = ("HerReplayBuffer", "ReplayBuffer", "DictReplayBuffer")


def algo_kwargs(hp: dict) -> dict:
    """The algorithm's keyword arguments (PPO(...), SAC(...), TQC(...)): ``lin_<value>``
    strings (learning_rate, clip_range) become linear schedules as in rl-zoo3, a named
    ``replay_buffer_class`` the SB3 class, a ``train_freq`` list a tuple. A deep copy: SB3
    writes into the dicts it is given (SAC adds ``use_sde`` to ``policy_kwargs``), and ``hp``
    is what the run's config hash and metadata record."""
    import copy

    out = copy.deepcopy({k: v for k, v in hp.items() if k not in RUN_KEYS})
    for key in ("learning_rate", "clip_range"):
        if isinstance(out.get(key), str) and out[key].startswith("lin_"):
            out[key] = linear_schedule(float(out[key][4:]))
    name = out.get("replay_buffer_class")
    if name is not None:
        if name not in REPLAY_BUFFERS:
            raise ValueError(f"replay_buffer_class {name!r}: one of {', '.join(REPLAY_BUFFERS)}")
        import stable_baselines3.common.buffers as buffers
        from stable_baselines3 import HerReplayBuffer

        out["replay_buffer_class"] = (HerReplayBuffer if name == "HerReplayBuffer"
                                      else getattr(buffers, name))
    if isinstance(out.get("train_freq"), list):
        out["train_freq"] = tuple(out["train_freq"])
    return out
