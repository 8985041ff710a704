"""Reading a stable-baselines3 model zip as data: within byte limits, its ``data`` JSON checked
against an allowlist, its tensors read weights-only.

The zip is read whole from a regular file of bounded size and its entries' declared sizes are
checked before any is inflated (:func:`open_model`). SB3 writes a model's settings into ``data``: plain JSON for numbers, flags and small mappings, a
base64 pickle for anything else. Before a model is used, every plain entry is checked here
against :data:`DATA_KEYS` (the entries an SB3 2.x PPO, A2C, SAC, TQC or TD3 model of this
package holds, each with its type and range), and every pickled entry must be one of
:data:`PICKLED_KEYS` (they are replaced, never unpickled: :mod:`.sb3_files`). Sizes SB3 would
allocate from (``n_envs``, ``buffer_size``, network widths, ``n_critics``) are bounded, so a
file cannot ask a resumed training for gigabytes; evaluation builds none of it anyway
(:mod:`.actor_net`).
"""
from __future__ import annotations

import io
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from microconveyor_env.safe_files import MiB, BoundedZip, UnsafeFileError, read_bytes

SERIALIZED = ":serialized:"


class ModelFileError(ValueError):
    """A model zip that is not a stable-baselines3 model of the expected kind."""


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
    "start_time": _num_in(0.0, 1e30), "_current_progress_remaining": _num_in(-1e13, 1.0),
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
    # this package's training phases (agents.rl.training.phases): armed once, saved with the model
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
