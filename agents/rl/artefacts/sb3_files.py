"""Loading stable-baselines3 model zips without running code from them.

An SB3 ``model.zip`` holds the network weights (``*.pth``, read here by torch with
``weights_only=True``: tensors only) and a ``data`` JSON in which every value that is not plain
JSON (the policy class, the spaces, the learning-rate schedule, buffers) is a base64
cloudpickle; unpickling one runs whatever code it names. Here the zip is read within byte limits
(:func:`open_model`), the ``data`` JSON is read as text and checked against an allowlist
(:mod:`.model_data`), and no pickle is ever loaded:

* to **evaluate**, only the actor is rebuilt from the ``policy.pth`` tensors
  (:func:`load_actor`, :mod:`.actor_net`); the policy class a pickle *names* is read with
  :mod:`pickletools` (which parses opcodes and executes nothing) and must be the algorithm's;
* to **resume a training**, SB3 loads the model with every pickled entry *replaced* through its
  ``custom_objects`` by an object built here (:func:`safe_load`).
"""
from __future__ import annotations

import base64
import binascii
import io
import json
import pickletools
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.safe_files import UnsafeFileError, read_bytes

from .model_zip import (
    MODEL_FILE_LIMIT,
    SERIALIZED,
    ModelFileError,
    check_data,
    open_model,
    read_data,
    read_weights,
)

__all__ = ["SERIALIZED", "ModelFileError", "check_data", "open_model", "read_data",
           "read_weights", "safe_load", "check_spaces", "algo_of", "pickled_globals",
           "custom_objects"]


# algorithm -> (keys its data JSON always has, the policy classes its pickle may name: for
# Box observations, and MultiInputPolicy for Dict ones). Checked in this order: PPO's keys
# include A2C's, TQC's SAC's.
ALGOS: dict[str, tuple[frozenset[str], tuple[str, ...]]] = {
    "ppo": (frozenset({"n_epochs", "clip_range", "n_steps", "batch_size"}),
            ("stable_baselines3.common.policies.ActorCriticPolicy",
             "stable_baselines3.common.policies.MultiInputActorCriticPolicy")),
    "a2c": (frozenset({"n_steps", "normalize_advantage"}),
            ("stable_baselines3.common.policies.ActorCriticPolicy",)),
    "tqc": (frozenset({"top_quantiles_to_drop_per_net", "target_entropy", "buffer_size"}),
            ("sb3_contrib.tqc.policies.TQCPolicy", "sb3_contrib.tqc.policies.MultiInputPolicy")),
    "sac": (frozenset({"target_entropy", "tau", "buffer_size"}),
            ("stable_baselines3.sac.policies.SACPolicy",
             "stable_baselines3.sac.policies.MultiInputPolicy")),
    "td3": (frozenset({"policy_delay", "target_policy_noise"}),
            ("stable_baselines3.td3.policies.TD3Policy",
             "stable_baselines3.td3.policies.MultiInputPolicy")),
}


def algo_of(data: dict[str, Any]) -> str | None:
    """The algorithm a model's ``data`` keys identify (a key of :data:`ALGOS`), or None."""
    for algo, (keys, _) in ALGOS.items():
        if keys <= set(data):
            return algo
    return None


def pickled_globals(entry: dict[str, Any]) -> list[str]:
    """The ``module.name`` globals a serialized entry's pickle refers to, read with
    :mod:`pickletools` (parses the opcodes; runs nothing). Raises on a damaged pickle."""
    raw = base64.b64decode(entry[SERIALIZED].encode(), validate=True)
    found: list[str] = []
    strings: list[str] = []
    memo: dict[int, str | None] = {}
    last: str | None = None           # the string the previous opcode pushed, if any
    for op, arg, _ in pickletools.genops(raw):
        pushed: str | None = None
        if op.name in ("SHORT_BINUNICODE", "BINUNICODE", "UNICODE", "BINUNICODE8"):
            pushed = str(arg)
        elif op.name == "MEMOIZE":
            memo[len(memo)] = last
            pushed = last
        elif op.name in ("BINPUT", "LONG_BINPUT", "PUT") and isinstance(arg, int):
            memo[arg] = last
            pushed = last
        elif op.name in ("BINGET", "LONG_BINGET", "GET") and isinstance(arg, int):
            pushed = memo.get(arg)
        elif op.name == "GLOBAL":
            found.append(str(arg).replace(" ", "."))
        elif op.name == "STACK_GLOBAL":
            if len(strings) < 2:
                raise ValueError("STACK_GLOBAL without its module and name")
            found.append(f"{strings[-2]}.{strings[-1]}")
        if pushed is not None and op.name not in ("MEMOIZE", "BINPUT", "LONG_BINPUT", "PUT"):
            strings.append(pushed)
        last = pushed
    return found


def _shape_of(entry: Any) -> tuple[int, ...] | None:
    """A space's shape from the readable ``_shape`` SB3 writes beside the pickle (e.g. '[6]')."""
    try:
        return tuple(int(v) for v in json.loads(str(entry["_shape"]).replace("(", "[")
                                                .replace(")", "]").replace(",]", "]")))
    except (KeyError, TypeError, ValueError, json.JSONDecodeError):
        return None


def _dict_shapes(entry: Any) -> dict[str, tuple[int, ...]] | None:
    """A Dict space's ``{key: shape}`` from the readable ``spaces`` SB3 writes beside the
    pickle (e.g. "{'achieved_goal': Box(-10.0, 10.0, (1,), float32), ...}")."""
    import re

    text = entry.get("spaces") if isinstance(entry, dict) else None
    if not isinstance(text, str):
        return None
    found = re.findall(r"'(\w+)': Box\([^()]*\(([\d, ]*)\)", text)
    return {k: tuple(int(v) for v in dims.split(",") if v.strip()) for k, dims in found} or None


def check_spaces(path: Path, data: dict[str, Any], observation_space: Any, action_space: Any,
                 env_name: str) -> None:
    """Refuse a model whose observation or action shapes are not those of the spaces given (a
    Dict observation space: the same keys with the same shapes)."""
    from gymnasium import spaces

    obs_entry = data.get("observation_space")
    if isinstance(observation_space, spaces.Dict):
        want_obs: Any = {k: sp.shape for k, sp in observation_space.spaces.items()}
        got_obs: Any = _dict_shapes(obs_entry)
    else:
        want_obs, got_obs = observation_space.shape, _shape_of(obs_entry)
    got_act = _shape_of(data.get("action_space"))
    if got_obs is None or got_act is None:
        raise ModelFileError(f"{str(path)!r} does not state its observation and action shapes")
    if got_obs != want_obs or got_act != action_space.shape:
        raise ModelFileError(f"{str(path)!r} was trained for observations {got_obs} and actions "
                             f"{got_act}; {env_name} has {want_obs} and {action_space.shape}")


def custom_objects(path: Path, data: dict[str, Any], algo: str, observation_space: Any,
                   action_space: Any, **given: Any) -> dict[str, Any]:
    """Replacements for every pickled entry of ``data``, so that SB3's ``load`` unpickles none:
    the spaces given, fresh buffers (SB3 rebuilds them at the next ``learn``), default schedules
    and training settings (they only matter to a resumed training, which passes its own in
    ``given``: ``learning_rate``, ``clip_range``, ``replay_buffer_class``, ...). Unknown pickled
    entries and a policy class other than the algorithm's are refused."""
    from gymnasium import spaces
    from stable_baselines3.common.buffers import (DictReplayBuffer, DictRolloutBuffer,
                                                  ReplayBuffer, RolloutBuffer)
    from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit

    _, policy_names = ALGOS[algo]
    is_dict = isinstance(observation_space, spaces.Dict)
    known: dict[str, Any] = {
        "observation_space": observation_space, "action_space": action_space,
        "learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": 0.2,
        "clip_range_vf": None, "_last_obs": None, "_last_episode_starts": None,
        "_last_original_obs": None, "ep_info_buffer": None, "ep_success_buffer": None,
        "rollout_buffer_class": DictRolloutBuffer if is_dict else RolloutBuffer,
        "rollout_buffer_kwargs": {}, "replay_buffer_class":
            DictReplayBuffer if is_dict else ReplayBuffer, "replay_buffer_kwargs": {},
        "action_noise": None,
        "target_policy_noise": None, "target_noise_clip": None, "ent_coef": None,
        # off-policy training settings: they only matter to a resumed training
        "train_freq": TrainFreq(1, TrainFrequencyUnit.STEP), "use_sde_at_warmup": False,
        # TQC stores it as a numpy scalar; SAC's "auto" value
        "target_entropy": -float(np.prod(action_space.shape)),
    }
    unknown = set(given) - set(known)
    if unknown:
        raise ValueError(f"custom_objects: unknown entries {sorted(unknown)}")
    known.update(given)
    out: dict[str, Any] = {}
    for key, value in data.items():
        if not (isinstance(value, dict) and SERIALIZED in value):
            continue
        if key == "policy_class":
            try:
                names = pickled_globals(value)
            except (ValueError, binascii.Error, TypeError) as exc:
                raise ModelFileError(f"{str(path)!r}: its policy_class entry is not a readable "
                                     f"pickle ({exc})") from None
            if len(names) != 1 or names[0] not in policy_names:
                raise ModelFileError(f"{str(path)!r}: its policy_class names {names or 'nothing'}, "
                                     f"not {' or '.join(policy_names)} ({algo.upper()}'s "
                                     "policy); refusing to load it")
            out[key] = _policy_class(names[0])
        elif key in known:
            out[key] = known[key]
        else:
            raise ModelFileError(f"{str(path)!r}: its data entry {key!r} holds a pickled Python "
                                 "object this loader does not know; it is not unpickled (that "
                                 "could run code), so the model is refused")
    # plain-JSON settings that belong to the buffer class above (HER's goal_selection_strategy,
    # copy_info_dict, ...) go with it
    if "replay_buffer_kwargs" in data:
        out["replay_buffer_kwargs"] = known["replay_buffer_kwargs"]
    return out


def _policy_class(dotted: str) -> Any:
    import importlib

    module, name = dotted.rsplit(".", 1)
    return getattr(importlib.import_module(module), name)


def algo_class(algo: str) -> Any:
    """The SB3 (or sb3-contrib) algorithm class of ``algo``."""
    if algo == "tqc":
        from sb3_contrib import TQC

        return TQC
    import stable_baselines3 as sb3

    return getattr(sb3, algo.upper())


def _weights_free_load(path: Path) -> io.BytesIO:
    return io.BytesIO(read_bytes(path, MODEL_FILE_LIMIT))


def safe_load(path: Path, algo: str, observation_space: Any, action_space: Any,
              cls: Any = None, env: Any = None, load_kwargs: dict[str, Any] | None = None,
              **given: Any) -> Any:
    """``cls.load(path)`` (default: SB3's class of ``algo``) with every pickled entry replaced
    (see :func:`custom_objects`) and the weights read by torch with ``weights_only=True``; on
    CPU, around ``env`` if given, with ``load_kwargs`` set on the model. For resuming a training
    (it builds the whole model: critics, optimizer, buffers); evaluation needs only the actor
    (:func:`load_actor`). The zip is read once, within :func:`open_model`'s limits, and its data
    entries checked (:func:`check_data`) before SB3 sees it. Shape mismatches of the network
    raise :class:`ModelFileError`."""
    zf = open_model(path)
    data = read_data(path, zf)
    found = algo_of(data)
    if found != algo:
        raise ModelFileError(f"{str(path)!r} is {'an unknown kind of' if found is None else 'a'} "
                             f"{(found or 'model').upper()} model, not {algo.upper()}")
    objs = custom_objects(path, data, algo, observation_space, action_space, **given)
    try:
        raw = _weights_free_load(path)
        return (cls or algo_class(algo)).load(raw, env=env, device="cpu", custom_objects=objs,
                                              **(load_kwargs or {}))
    except UnsafeFileError as exc:
        raise ModelFileError(str(exc)) from None
    except (RuntimeError, ValueError, KeyError, OSError, zipfile.BadZipFile) as exc:
        raise ModelFileError(f"{str(path)!r} could not be loaded as {algo.upper()} "
                             f"({type(exc).__name__}: {str(exc).splitlines()[0]})") from None
