"""A policy folder, loaded as data and checked as a unit.

A policy folder holds ``model.zip`` (stable-baselines3), ``normalization.json`` (observation
statistics) and ``metadata.json`` (algorithm, env id and env kwargs, hyperparameters, evaluation
and the sha256 of the other two files). The env id and kwargs name the scene the policy was
trained in (:func:`policy_scene`); evaluating it in another scene (other actuators, surface,
targets, tolerance, ...: :func:`~microconveyor_env.envs.scene_differences`) is refused, never
silently done. Per-episode randomisation and runtime knobs are not the scene: a policy may be
tested under perturbations. Loading it runs no code from any of them (:mod:`.sb3_files`,
:mod:`.normalization`), and every part must agree with the others: the algorithm the zip's keys
identify with the one the metadata names, the zip's spaces with the env's, the statistics' shape
with the observations, the files with their recorded hashes. A disagreement is one
:class:`PolicyError` naming the file and the mismatch.

A policy of the plane (``MicroConveyor2D-v0``) is loaded the same way: its scene is a
:class:`~microconveyor_env.envs.plane.config.PlaneEnvConfig` made from its env kwargs, and the
model's shapes are checked against the plane env's spaces.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, env_config, scene_differences
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.versions import FIRST_ENV_ID, PLANE_ENV_IDS, check_env_id, nominal, \
    scene_config
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.presets import PresetError

from . import normalization
from .checkpoint import META, MODEL, CheckpointError, read_meta, verify_files
from .normalization import NORMALIZATION, NormalizationError, ObsNormalizer
from .actor_net import ActorNet, load_actor
from .sb3_files import ALGOS, ModelFileError, algo_of, check_spaces, open_model, read_data

AnyConfig = EnvConfig | PlaneEnvConfig
__all__ = ["FIRST_ENV_ID", "PLANE_ENV_IDS", "Policy", "PolicyError", "load_policy",
           "policy_scene", "policy_env_kwargs", "read_policy_meta", "check_scene"]


class PolicyError(ValueError):
    """A policy path that cannot be loaded or does not fit the env."""


@dataclass
class Policy:
    """A loaded policy: its deterministic actor (:class:`~.actor_net.ActorNet`, rebuilt from the
    saved tensors), its observation normaliser (None: raw observations), its metadata and the
    folder it came from."""

    actor: ActorNet
    normalizer: ObsNormalizer | None
    metadata: dict[str, Any]
    path: Path
    # the scene it was trained in, randomisation off (None: unknown, no metadata)
    config: AnyConfig | None = None

    @property
    def env_id(self) -> str:
        return str(self.metadata.get("env_id", FIRST_ENV_ID))

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic actions in [-1, 1]^k (k = 3 in 1-D, 5 in the plane) for a batch of raw
        observations of the Box env (a policy trained on the goal-conditioned env gets them as
        its Dict observations).

        Each row is computed on its own, so a row's action does not depend on the batch it came
        in: torch's CPU kernels round float32 products differently by batch size on some CPUs
        (AVX-512: up to ~2e-7 in action units between a batch of 64 and single rows), which
        would make a target's result depend on how many targets were evaluated together and
        MPC's plan from a policy (one state at a time) differ from the policy's own episode.
        A policy whose metadata says ``inference: "portable"`` is computed in float64 with the
        same bits on every CPU (:meth:`~.actor_net.ActorNet.predict_portable`)."""
        obs = np.asarray(obs)
        if obs.ndim < 2:
            raise ValueError(f"act takes a batch of observations (n, d), got shape {obs.shape}")
        if not len(obs):
            return np.zeros((0, *self.actor.low.shape), np.float32)
        return np.concatenate([self._act_rows(obs[i:i + 1]) for i in range(len(obs))])

    def _act_rows(self, obs: np.ndarray) -> np.ndarray:
        if self.actor.obs_keys is not None:
            from microconveyor_env.envs.line.goal import goal_observations

            return self.actor.predict(goal_observations(obs))
        if self.normalizer is not None:
            obs = self.normalizer(obs)
        if self.metadata.get("inference") == "portable":
            return self.actor.predict_portable(obs)
        return self.actor.predict(obs)


def _locate(path: Path) -> tuple[Path, Path]:
    folder, model_file = (path, path / MODEL) if path.is_dir() else (path.parent, path)
    if not model_file.is_file():
        raise PolicyError(f"no policy at {str(path)!r}: expected a folder with {MODEL}, "
                          f"{NORMALIZATION} and {META}, or a model .zip")
    return folder, model_file


def _metadata(folder: Path) -> dict[str, Any]:
    if not (folder / META).exists():
        return {}
    try:
        meta = read_meta(folder)
        if "files" in meta:
            verify_files(folder, meta)
    except CheckpointError as exc:
        raise PolicyError(str(exc)) from None
    return meta


def _spaces(config: AnyConfig, env_id: str) -> tuple[Any, Any]:
    """The spaces of ``env_id``'s single env (its registered entry point) on ``config``."""
    import importlib

    from microconveyor_env.env_ids import ENTRY_POINTS

    module, name = ENTRY_POINTS[env_id].split(":")
    env = getattr(importlib.import_module(module), name)(config=config)
    return env.observation_space, env.action_space


def _normalizer(folder: Path, model_file: Path, meta: dict[str, Any],
                obs_shape: tuple[int, ...]) -> ObsNormalizer | None:
    # beside the model, or where convert-stats writes it on rl-zoo3's layout (beside its
    # vecnormalize.pkl, in the folder named after the model zip)
    for path in (folder / NORMALIZATION, folder / model_file.stem / NORMALIZATION):
        if path.is_file():
            try:
                return normalization.obs_normalizer(normalization.read(path, obs_shape))
            except NormalizationError as exc:
                raise PolicyError(str(exc)) from None
    for pkl in (folder / normalization.LEGACY_PICKLE,
                folder / model_file.stem / normalization.LEGACY_PICKLE):  # rl-zoo3's layout
        if pkl.is_file():
            raise PolicyError(
                f"{str(pkl)!r} is a pickle: loading it can run any code it names, so it is not "
                f"loaded. If you trust where it came from, convert it once with `microconveyor "
                f"convert-stats {pkl}` (writes {NORMALIZATION} beside it)")
    if "hyperparams" in meta and not (meta["hyperparams"] or {}).get("normalize"):
        return None  # the metadata says the policy was trained on raw observations
    raise PolicyError(f"{str(folder)!r} has no {NORMALIZATION}: a policy trained on normalised "
                      f"observations acts blindly without it. If it was trained on raw "
                      f"observations, say so in {META}: {{\"hyperparams\": {{\"normalize\": null}}}}")


def read_policy_meta(path: str | Path) -> dict[str, Any]:
    """The checked metadata of the policy at ``path`` (folder or model zip; {}: none)."""
    return _metadata(_locate(Path(path))[0])


def policy_env_kwargs(meta: dict[str, Any]) -> dict[str, Any]:
    """The env kwargs a policy was trained with (``env_kwargs``; older metadata: the
    hyperparameters' ``env_kwargs``)."""
    kw = meta.get("env_kwargs")
    if kw is None:
        kw = (meta.get("hyperparams") or {}).get("env_kwargs") or {}
    if not isinstance(kw, dict):
        raise PolicyError(f"env_kwargs in the metadata must be a mapping, got {kw!r}")
    return dict(kw)


def policy_scene(meta: dict[str, Any], where: str = "metadata") -> AnyConfig:
    """The config of the env a policy was trained on: ``scene_config(env_id, **env_kwargs)``
    (an :class:`EnvConfig`, or the plane's :class:`PlaneEnvConfig`)."""
    env_id = str(meta.get("env_id", FIRST_ENV_ID))
    kwargs = policy_env_kwargs(meta)
    if "path" in kwargs:
        raise PolicyError(f"{where}: env_kwargs name a file ('path'); a policy's scene is "
                          "its env id and field values")
    try:
        return scene_config(check_env_id(env_id), **kwargs)
    except (ParameterError, PresetError) as exc:
        raise PolicyError(f"{where}: the env the policy was trained on cannot be made ({exc})") \
            from None


def check_scene(trained: AnyConfig, asked: AnyConfig, meta: dict[str, Any], where: str) -> None:
    """PolicyError when ``asked`` is another scene than the one the policy was trained in."""
    diff = scene_differences(trained, asked)
    if diff:
        fields = "; ".join(f"{k}: trained {a!r}, asked {b!r}" for k, (a, b) in diff.items())
        raise PolicyError(f"{where}: the policy was trained on {meta.get('env_id', FIRST_ENV_ID)}"
                          f" with env kwargs {policy_env_kwargs(meta)}, and the env asked for "
                          f"differs in {fields}. Evaluating a policy on another scene is refused; "
                          "give the policy's own --env/--env-kwargs/--preset (or none)")


def load_policy(path: str | Path, config: AnyConfig | None = None) -> Policy:
    """The policy at ``path`` (a policy folder, or a model zip with its files beside it), checked
    as a unit, for the env ``config`` (default: the scene it was trained in, from its metadata,
    with per-episode randomisation off;
    a policy without metadata: MicroConveyor-v0's defaults; a MicroConveyor2D-v0 policy: its
    :class:`PlaneEnvConfig`). A ``config`` of another scene than the policy's is refused
    (:func:`check_scene`)."""
    folder, model_file = _locate(Path(path))
    meta = _metadata(folder)
    try:
        zf = open_model(model_file)   # read once, within its limits
        data = read_data(model_file, zf)
    except ModelFileError as exc:
        raise PolicyError(f"{exc}; not a stable-baselines3 model") from None
    algo = algo_of(data)
    if meta.get("algo") and algo is not None and meta["algo"] != algo:
        raise PolicyError(f"{str(folder / META)!r} says {str(meta['algo']).upper()}, but "
                          f"{str(model_file)!r} is an {algo.upper()} model")
    if algo is None:
        raise PolicyError(f"{str(model_file)!r} is not a model of a kind this loader knows "
                          f"(stable-baselines3 {', '.join(a.upper() for a in ALGOS)})")
    trained = policy_scene(meta, repr(str(folder / META))) if meta else None
    if trained is not None and config is not None:
        check_scene(trained, config, meta, repr(str(folder / META)))
    if trained is not None:
        trained = nominal(trained)
    cfg = config or trained or env_config(FIRST_ENV_ID)
    env_id = str(meta.get("env_id", FIRST_ENV_ID))
    try:
        obs_space, act_space = _spaces(cfg, env_id)
    except (ParameterError, PresetError) as exc:
        raise PolicyError(f"{str(folder / META)!r}: the env the policy was trained on cannot be "
                          f"made ({exc})") from None
    try:
        check_spaces(model_file, data, obs_space, act_space, env_id)
        normalizer = _normalizer(folder, model_file, meta, obs_space.shape)
        actor = load_actor(model_file, algo, obs_space, act_space, zf)
    except ModelFileError as exc:
        raise PolicyError(str(exc)) from None
    return Policy(actor, normalizer, meta, folder, trained)
