"""Observation/reward normalisation statistics as JSON data (never a pickle).

SB3 saves ``VecNormalize`` with :mod:`pickle`, and unpickling a file runs whatever code the file
names (a ``vecnormalize.pkl`` can call ``os.system`` as ``evaluate`` opens it). A policy
folder therefore holds ``normalization.json``: the running means, variances and counts, and the
settings ``VecNormalize`` needs, written with ``repr`` floats so a training resumed from it is bit
for bit the one that stopped. :func:`convert_pickle` turns an old ``vecnormalize.pkl`` into it,
for files whose source you trust (it has to unpickle once).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

NORMALIZATION = "normalization.json"
NORMALIZATION_LIMIT = 1 << 20   # bytes: the statistics of an observation vector fit in far less
LEGACY_PICKLE = "vecnormalize.pkl"
FORMAT = 1
_SETTINGS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon")


class NormalizationError(ValueError):
    """A normalisation file that is missing, damaged or does not fit the policy."""


@dataclass(frozen=True)
class ObsNormalizer:
    """What a trained policy needs to see observations as it saw them in training:
    ``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)`` (VecNormalize's formula)."""

    mean: np.ndarray
    var: np.ndarray
    clip_obs: float
    epsilon: float

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalised float32 observations [-] of raw observations ``obs`` [-]."""
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon),
                       -self.clip_obs, self.clip_obs).astype(np.float32)


def _rms(rms: Any) -> dict[str, Any]:
    return {"mean": np.asarray(rms.mean, float).tolist(), "var": np.asarray(rms.var, float).tolist(),
            "count": float(rms.count)}


def stats_of(vec_normalize: Any) -> dict[str, Any]:
    """The JSON-ready statistics and settings of an SB3 ``VecNormalize`` (floats kept exactly)."""
    if not vec_normalize.norm_obs:
        # SB3 keeps no observation statistics then; the file holds the identity (unused:
        # norm_obs false means the policy reads raw observations)
        n = int(np.prod(vec_normalize.observation_space.shape))
        obs_rms: dict[str, Any] = {"mean": [0.0] * n, "var": [1.0] * n, "count": 1.0}
    elif isinstance(vec_normalize.obs_rms, dict):
        raise NormalizationError("dict observations are not supported by this format yet")
    else:
        obs_rms = _rms(vec_normalize.obs_rms)
    out: dict[str, Any] = {"format": FORMAT, "obs_rms": obs_rms,
                           "ret_rms": _rms(vec_normalize.ret_rms)}
    for key in _SETTINGS:
        value = getattr(vec_normalize, key)
        out[key] = bool(value) if key.startswith("norm_") else float(value)
    return out


def write(vec_normalize: Any, path: Path) -> None:
    """Write ``vec_normalize``'s statistics to ``path`` as JSON (the caller makes it atomic)."""
    path.write_text(json.dumps(stats_of(vec_normalize), indent=1) + "\n")


def _vector(v: Any, what: str, shape: tuple[int, ...] | None) -> np.ndarray:
    try:
        arr = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise NormalizationError(f"{what} is not a list of numbers") from None
    if shape is not None and arr.shape != shape:
        raise NormalizationError(f"{what} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise NormalizationError(f"{what} holds NaN or inf")
    return arr


def read(path: Path, obs_shape: tuple[int, ...] | None = None) -> dict[str, Any]:
    """The statistics in ``path``, checked: finite, variances >= 0, counts > 0, positive clips,
    and (with ``obs_shape``) observation statistics of that shape. One
    :class:`NormalizationError` naming the file otherwise."""
    from microconveyor_env.safe_files import NotTextError, UnsafeFileError, read_text

    try:
        data = json.loads(read_text(path, NORMALIZATION_LIMIT))
    except NotTextError as exc:
        raise NormalizationError(f"{str(path)!r} is not readable JSON ({exc})") from None
    except UnsafeFileError as exc:
        raise NormalizationError(str(exc)) from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise NormalizationError(f"{str(path)!r} is not readable JSON ({exc})") from None
    try:
        return _checked(data, obs_shape)
    except NormalizationError as exc:
        raise NormalizationError(f"{str(path)!r}: {exc}") from None


def _checked(data: Any, obs_shape: tuple[int, ...] | None) -> dict[str, Any]:
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise NormalizationError(f"not a normalization file of format {FORMAT}")
    missing = [k for k in ("obs_rms", "ret_rms", *_SETTINGS) if k not in data]
    if missing:
        raise NormalizationError(f"missing {', '.join(missing)}")
    for key in ("obs_rms", "ret_rms"):
        rms = data[key]
        if not isinstance(rms, dict) or set(rms) != {"mean", "var", "count"}:
            raise NormalizationError(f"{key} must hold exactly mean, var and count")
        shape = (obs_shape if key == "obs_rms" else ())
        mean = _vector(rms["mean"], f"{key}.mean", shape)
        var = _vector(rms["var"], f"{key}.var", mean.shape)
        if np.any(var < 0):
            raise NormalizationError(f"{key}.var is negative")
        count = rms["count"]
        if not isinstance(count, (int, float)) or not math.isfinite(count) or count <= 0:
            raise NormalizationError(f"{key}.count must be a positive number")
    for key in ("clip_obs", "clip_reward", "gamma", "epsilon"):
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise NormalizationError(f"{key} must be a positive number, got {v!r}")
    for key in ("norm_obs", "norm_reward"):
        if not isinstance(data[key], bool):
            raise NormalizationError(f"{key} must be true or false, got {data[key]!r}")
    return dict(data)


def obs_normalizer(stats: dict[str, Any]) -> ObsNormalizer | None:
    """The inference-time observation normaliser of checked ``stats`` (None: obs not normalised)."""
    if not stats["norm_obs"]:
        return None
    rms = stats["obs_rms"]
    return ObsNormalizer(np.asarray(rms["mean"], float), np.asarray(rms["var"], float),
                         float(stats["clip_obs"]), float(stats["epsilon"]))


def restore(venv: Any, stats: dict[str, Any]) -> Any:
    """An SB3 ``VecNormalize`` around ``venv`` in exactly the state ``stats`` describes
    (training mode on; the per-env return accumulators start at 0, as after SB3's own load)."""
    from stable_baselines3.common.vec_env import VecNormalize

    vn = VecNormalize(venv, training=True, **{k: stats[k] for k in _SETTINGS})
    for key in ("obs_rms", "ret_rms") if stats["norm_obs"] else ("ret_rms",):
        rms, src = getattr(vn, key), stats[key]
        rms.mean = np.asarray(src["mean"], float).reshape(np.shape(rms.mean))
        rms.var = np.asarray(src["var"], float).reshape(np.shape(rms.var))
        rms.count = float(src["count"])
    return vn


def freeze_obs_stats(vec_normalize: Any) -> bool:
    """Stop ``vec_normalize`` updating its observation statistics (the reward statistics go on);
    True if it was updating them. The policy then sees every later observation through the same
    normalisation, which its last updates need: the fine corrections PPO makes near a target
    are smaller than the drift of still-moving statistics (docs/agents.md, "PPO on
    MicroConveyor-v1")."""
    if not vec_normalize.norm_obs:
        return False
    rms = vec_normalize.obs_rms
    items = list(rms.values()) if isinstance(rms, dict) else [rms]
    live = [r for r in items if not getattr(r, "frozen", False)]
    for r in live:
        r.update = _no_update
        r.frozen = True
    return bool(live)


def _no_update(*_: Any) -> None:
    """RunningMeanStd.update of frozen statistics."""


def convert_pickle(pickle_path: Path, out: Path) -> dict[str, Any]:
    """Convert a trusted SB3 ``vecnormalize.pkl`` to ``normalization.json`` at ``out``.

    **This unpickles ``pickle_path``, which runs any code it names**: use it only on files you
    made or whose source you trust. Returns the statistics written."""
    import pickle

    with open(pickle_path, "rb") as fh:
        vn = pickle.load(fh)  # noqa: S301 - explicit, documented trusted conversion
    if not hasattr(vn, "obs_rms") or not hasattr(vn, "ret_rms"):
        raise NormalizationError(f"{str(pickle_path)!r} does not hold VecNormalize statistics "
                                 f"(it holds a {type(vn).__name__})")
    stats = stats_of(vn)
    _checked(stats, None)
    out.write_text(json.dumps(stats, indent=1) + "\n")
    return stats
