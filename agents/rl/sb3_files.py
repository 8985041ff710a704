"""Loading stable-baselines3 model zips without running code from them.

An SB3 ``model.zip`` holds the network weights (``*.pth``, which SB3 reads with
``torch.load(weights_only=True)``: tensors only) and a ``data`` JSON in which every value that is not
plain JSON (the policy class, the spaces, the learning-rate schedule, buffers) is a base64
cloudpickle. Unpickling those runs whatever code they name (issue 17: a crafted entry ran a shell
command on ``evaluate``). Here the ``data`` JSON is read as text, every pickled entry is *replaced*
through SB3's ``custom_objects`` by an object this module builds itself (so SB3 never unpickles
any), an entry this module does not know is refused, and the policy class a pickle *names* is read
with :mod:`pickletools` (which parses opcodes and executes nothing) and must be the expected one.
"""
from __future__ import annotations

import base64
import binascii
import io
import json
import math
import pickletools
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.safe_files import MiB, BoundedZip, UnsafeFileError, read_bytes

from .actor_net import ActorFileError, ActorNet

SERIALIZED = ":serialized:"


class ModelFileError(ValueError):
    """A model zip that is not a stable-baselines3 model of the expected kind."""


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


MODEL_FILE_LIMIT = 256 * MiB   # a model zip on disk
DATA_LIMIT = 16 * MiB          # its data JSON, inflated
WEIGHTS_LIMIT = 256 * MiB      # one weights entry (policy.pth ...), inflated
MODEL_TOTAL_LIMIT = 768 * MiB  # all entries together, inflated


def open_model(path: Path) -> BoundedZip:
    """The model zip at ``path``, read within limits: a regular file of at most
    :data:`MODEL_FILE_LIMIT` bytes whose entries have plain names and declared sizes within
    :data:`WEIGHTS_LIMIT` (:data:`MODEL_TOTAL_LIMIT` together), checked before any is
    inflated."""
    try:
        return BoundedZip(read_bytes(path, MODEL_FILE_LIMIT), repr(str(path)), WEIGHTS_LIMIT,
                          MODEL_TOTAL_LIMIT)
    except UnsafeFileError as exc:
        raise ModelFileError(f"{exc}; not a stable-baselines3 model zip") from None


def read_data(path: Path, zf: BoundedZip | None = None) -> dict[str, Any]:
    """The ``data`` JSON of the zip at ``path``, as plain JSON (nothing deserialised), its
    plain entries checked against :data:`DATA_KEYS` (:func:`check_data`)."""
    zf = zf or open_model(path)
    if "data" not in zf.infos:
        raise ModelFileError(f"{str(path)!r} is not a stable-baselines3 model zip (no data "
                             "entry)")
    if zf.infos["data"].file_size > DATA_LIMIT:
        raise ModelFileError(f"{str(path)!r}: its data entry would inflate to "
                             f"{zf.infos['data'].file_size:,} bytes (at most {DATA_LIMIT:,})")
    try:
        data = json.loads(zf.read("data").decode())
    except UnsafeFileError as exc:
        raise ModelFileError(str(exc)) from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ModelFileError(f"{str(path)!r}: its data entry is not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ModelFileError(f"{str(path)!r}: its data entry is not a JSON object")
    check_data(path, data)
    return data


def read_weights(path: Path, entry: str = "policy.pth",
                 zf: BoundedZip | None = None) -> dict[str, Any]:
    """The tensors of ``entry`` in the model zip at ``path``: read by torch with
    ``weights_only=True`` (tensors and plain containers only; a pickle naming anything else is
    refused), on the CPU; a ``{name: float tensor}`` mapping."""
    import pickle

    import torch

    zf = zf or open_model(path)
    try:
        raw = zf.read(entry)
    except UnsafeFileError as exc:
        raise ModelFileError(str(exc)) from None
    import warnings

    try:
        with warnings.catch_warnings():   # torch's notes on the pickle protocol: not the user's
            warnings.simplefilter("ignore")
            state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, ValueError, EOFError, OSError, KeyError,
            TypeError, AttributeError, IndexError, MemoryError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if "weights_only" in str(exc) or isinstance(exc, pickle.UnpicklingError):
            first = ("it holds Python objects other than tensors, which are not loaded "
                     "(that could run code)")
        raise ModelFileError(f"{str(path)!r}: {entry} is not a file of tensors ({first})") \
            from None
    if not isinstance(state, dict) or not all(
            isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in state.items()):
        raise ModelFileError(f"{str(path)!r}: {entry} is not a mapping of names to tensors")
    return state


def _int_in(lo: int, hi: int, none: bool = False) -> Callable[[Any], bool]:
    def ok(v: Any) -> bool:
        return (v is None and none) or (isinstance(v, int) and not isinstance(v, bool)
                                         and lo <= v <= hi)
    ok.__doc__ = f"an integer in [{lo}, {hi}]" + (" or null" if none else "")
    return ok


def _num_in(lo: float, hi: float, none: bool = False, words: tuple[str, ...] = ()
            ) -> Callable[[Any], bool]:
    def ok(v: Any) -> bool:
        if v is None:
            return none
        if isinstance(v, str):
            return v in words or any(v.startswith(w + "_") for w in words)
        return (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                and lo <= v <= hi)
    ok.__doc__ = (f"a number in [{lo:g}, {hi:g}]" + (" or null" if none else "")
                  + (f" or {'/'.join(words)}" if words else ""))
    return ok


def _flag(v: Any) -> bool:
    """true or false"""
    return isinstance(v, bool)


def _null(v: Any) -> bool:
    """null"""
    return v is None


def _text(v: Any) -> bool:
    """a short string or null"""
    return v is None or (isinstance(v, str) and len(v) <= 4096)


def _empty_list(v: Any) -> bool:
    """an empty list"""
    return v == []


def _widths(v: Any) -> bool:
    return (isinstance(v, list) and len(v) <= 16 and all(
        isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= 4096 for w in v))


def _net_arch(v: Any) -> bool:
    """a list of at most 16 widths in [1, 4096], or a dict of such lists (pi, vf, qf)"""
    if isinstance(v, dict):
        return set(v) <= {"pi", "vf", "qf"} and all(_widths(w) for w in v.values())
    return _widths(v)


POLICY_KWARGS: dict[str, Callable[[Any], bool]] = {
    "net_arch": _net_arch, "log_std_init": _num_in(-20.0, 20.0), "use_sde": _flag,
    "ortho_init": _flag, "squash_output": _flag, "full_std": _flag, "use_expln": _flag,
    "share_features_extractor": _flag, "normalize_images": _flag,
    "clip_mean": _num_in(0.0, 1e3), "n_critics": _int_in(1, 32), "n_quantiles": _int_in(1, 1000),
}
REPLAY_BUFFER_KWARGS: dict[str, Callable[[Any], bool]] = {
    "copy_info_dict": _flag, "n_sampled_goal": _int_in(1, 100),
    "goal_selection_strategy": lambda v: v in ("future", "final", "episode"),
    "handle_timeout_termination": _flag,
}


def _kwargs(allowed: dict[str, Callable[[Any], bool]]) -> Callable[[Any], bool]:
    def ok(v: Any) -> bool:
        return isinstance(v, dict) and all(k in allowed and allowed[k](x) for k, x in v.items())
    ok.__doc__ = f"a mapping of {', '.join(allowed) or 'nothing'} with valid values"
    return ok


COUNT = _int_in(0, 10**13)
# Every plain-JSON entry an SB3 (2.x) PPO/A2C/SAC/TQC/TD3 model zip of this package may hold,
# with the values allowed. A key not here, or a value outside its range, refuses the model.
# Sizes that SB3 would allocate from (``n_envs``, ``buffer_size``, network widths) are bounded.
DATA_KEYS: dict[str, Callable[[Any], bool]] = {
    "verbose": _int_in(0, 2), "seed": _int_in(-(2**63), 2**63 - 1, none=True),
    "num_timesteps": COUNT, "_total_timesteps": COUNT, "_num_timesteps_at_start": COUNT,
    "_episode_num": COUNT, "_n_updates": COUNT, "_stats_window_size": _int_in(1, 10**6),
    "start_time": _num_in(0.0, 1e30), "_current_progress_remaining": _num_in(-1.0, 2.0),
    "tensorboard_log": _text, "use_sde": _flag, "sde_sample_freq": _int_in(-1, 10**9),
    "n_envs": _int_in(1, 1024), "n_steps": _int_in(1, 10**6), "batch_size": _int_in(1, 10**7),
    "n_epochs": _int_in(1, 10**4), "gamma": _num_in(0.0, 1.0), "gae_lambda": _num_in(0.0, 1.0),
    "ent_coef": _num_in(0.0, 1e3, words=("auto",)), "vf_coef": _num_in(0.0, 1e3),
    "max_grad_norm": _num_in(0.0, 1e9), "normalize_advantage": _flag,
    "target_kl": _num_in(0.0, 1e3, none=True), "clip_range_vf": _num_in(0.0, 1e3, none=True),
    "learning_rate": _num_in(0.0, 10.0), "buffer_size": _int_in(1, 10**7),
    "learning_starts": COUNT, "tau": _num_in(0.0, 1.0), "gradient_steps": _int_in(-1, 10**4),
    "optimize_memory_usage": _flag, "target_update_interval": _int_in(1, 10**9),
    "target_entropy": _num_in(-1e3, 1e3, words=("auto",)), "use_sde_at_warmup": _flag,
    "top_quantiles_to_drop_per_net": _int_in(0, 1000), "policy_delay": _int_in(1, 10**3),
    "target_policy_noise": _num_in(0.0, 1e3), "target_noise_clip": _num_in(0.0, 1e3),
    "batch_norm_stats": _empty_list, "batch_norm_stats_target": _empty_list,
    "actor_batch_norm_stats": _empty_list, "actor_batch_norm_stats_target": _empty_list,
    "critic_batch_norm_stats": _empty_list, "critic_batch_norm_stats_target": _empty_list,
    "policy_kwargs": _kwargs(POLICY_KWARGS), "replay_buffer_kwargs": _kwargs(
        REPLAY_BUFFER_KWARGS), "rollout_buffer_kwargs": _kwargs({}),
    # buffers and state SB3 stores as pickles (replaced, never unpickled) or as null
    "_last_obs": _null, "_last_episode_starts": _null, "_last_original_obs": _null,
    "ep_info_buffer": _null, "ep_success_buffer": _null, "action_noise": _null,
    # this package's training phases (agents.rl.phases): armed once, saved with the model
    "restart_pending": _flag, "shift_pending": _flag,
}
# entries that may hold a pickle (replaced by custom_objects, never unpickled)
PICKLED_KEYS = frozenset({
    "policy_class", "observation_space", "action_space", "learning_rate", "lr_schedule",
    "clip_range", "clip_range_vf", "_last_obs", "_last_episode_starts", "_last_original_obs",
    "ep_info_buffer", "ep_success_buffer", "rollout_buffer_class", "replay_buffer_class",
    "train_freq", "target_entropy", "action_noise", "target_policy_noise", "target_noise_clip",
    "ent_coef", "policy_kwargs"})


def check_data(path: Path, data: dict[str, Any]) -> None:
    """Refuse a model whose ``data`` holds an entry not in :data:`DATA_KEYS` (or, pickled, not
    in :data:`PICKLED_KEYS`) or a plain value outside what :data:`DATA_KEYS` allows."""
    for key, value in data.items():
        if isinstance(value, dict) and SERIALIZED in value:
            if key not in PICKLED_KEYS:
                raise ModelFileError(f"{str(path)!r}: its data entry {key!r} holds a pickled "
                                     "Python object this loader does not know; it is not "
                                     "unpickled (that could run code), so the model is refused")
            continue
        check = DATA_KEYS.get(key)
        if check is None:
            raise ModelFileError(f"{str(path)!r}: its data entry {key!r} is not one a "
                                 "stable-baselines3 model of this package holds; refusing the "
                                 "model")
        if not check(value):
            shown = repr(value)
            shown = shown if len(shown) <= 80 else shown[:77] + "..."
            raise ModelFileError(f"{str(path)!r}: its data entry {key!r} = {shown} is invalid "
                                 f"(must be {check.__doc__ or 'valid'})")


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


ACTIVATION_MODULE = "torch.nn.modules.activation."


def _activation(path: Path, data: dict[str, Any]) -> tuple[str | None, dict[str, Any]]:
    """The activation a model's ``policy_kwargs`` names (None: the algorithm's default) and its
    plain policy kwargs. A pickled ``policy_kwargs`` (SB3 pickles it when it holds a class) is
    read with :mod:`pickletools` only: the classes it names must be ``torch.nn`` activations of
    :data:`~agents.rl.hyperparams.ACTIVATIONS` (at most one) or ``torch.optim`` optimizers
    (irrelevant to acting)."""
    from .hyperparams import ACTIVATIONS

    entry = data.get("policy_kwargs") or {}
    if not (isinstance(entry, dict) and SERIALIZED in entry):
        return None, dict(entry)
    try:
        names = pickled_globals(entry)
    except (ValueError, binascii.Error, TypeError) as exc:
        raise ModelFileError(f"{str(path)!r}: its policy_kwargs entry is not a readable "
                             f"pickle ({exc})") from None
    acts = [n[len(ACTIVATION_MODULE):] for n in names if n.startswith(ACTIVATION_MODULE)]
    other = [n for n in names if not n.startswith((ACTIVATION_MODULE, "torch.optim."))]
    if other or len(set(acts)) > 1 or not set(acts) <= set(ACTIVATIONS):
        raise ModelFileError(f"{str(path)!r}: its policy_kwargs name {names}; only one torch.nn "
                             f"activation ({', '.join(ACTIVATIONS)}) and torch.optim classes "
                             "are understood, so the model is refused")
    if data.get("use_sde"):
        raise ModelFileError(f"{str(path)!r}: a gSDE policy with pickled policy_kwargs: whether "
                             "it squashes its output cannot be read without unpickling")
    return (acts[0] if acts else None), {}


def flat_obs(observation_space: Any) -> tuple[int, tuple[str, ...] | None]:
    """The flattened observation size and, for a Dict space, its keys in order."""
    from gymnasium import spaces

    if isinstance(observation_space, spaces.Dict):
        keys = tuple(observation_space.spaces)
        return sum(int(np.prod(observation_space[k].shape or ())) for k in keys), keys
    return int(np.prod(observation_space.shape)), None


def load_actor(path: Path, algo: str, observation_space: Any, action_space: Any) -> ActorNet:
    """The deterministic actor of the model zip at ``path`` (an ``algo`` model for these
    spaces), rebuilt from its ``policy.pth`` tensors (:class:`~.actor_net.ActorNet`): no SB3
    model, env, critic or buffer is built, and no pickle is loaded."""
    zf = open_model(path)
    data = read_data(path, zf)
    check_spaces(path, data, observation_space, action_space, "the env")
    if data.get("policy_class") is not None:
        custom_objects(path, {"policy_class": data["policy_class"]}, algo, observation_space,
                       action_space)   # the class it names must be the algorithm's policy
    activation, kwargs = _activation(path, data)
    squash = bool(data.get("use_sde")) and bool(kwargs.get("squash_output"))
    state = read_weights(path, "policy.pth", zf)
    obs_dim, keys = flat_obs(observation_space)
    try:
        return ActorNet(algo, state, obs_dim, action_space.low, action_space.high, keys,
                        activation, squash)
    except ActorFileError as exc:
        raise ModelFileError(f"{str(path)!r}: policy.pth {exc}") from None


def actor_of_model(model: Any) -> ActorNet:
    """The deterministic actor of a live SB3 model (a copy of its actor's tensors), as
    :func:`load_actor` builds it from a file: one forward pass for both."""
    algo = next((name for name in ALGOS for cls in type(model).__mro__
                 if cls.__name__.lower() == name), None)
    if algo is None:
        raise ValueError(f"no actor layout for a {type(model).__name__} model")
    policy = model.policy
    obs_dim, keys = flat_obs(model.observation_space)
    act = getattr(policy, "activation_fn", None)
    return ActorNet(algo, {k: v.detach().clone() for k, v in policy.state_dict().items()},
                    obs_dim, model.action_space.low, model.action_space.high, keys,
                    act.__name__ if act is not None else None,
                    bool(getattr(policy, "squash_output", False)) and algo in ("ppo", "a2c"))
