"""A policy folder, loaded as data and checked as a unit.

A policy folder holds ``model.zip`` (stable-baselines3), ``normalization.json`` (observation
statistics) and ``metadata.json``. The env id and kwargs name the scene the policy was
trained in (:func:`policy_scene`); evaluating it in another scene (other actuators, surface,
targets, tolerance, ...: :func:`~microconveyor_env.envs.scene_differences`) is refused, never
silently done. Per-episode randomisation and runtime knobs are not the scene: a policy may be
tested under perturbations. Loading it runs no code from any of them (:mod:`.sb3_files`,
:mod:`.normalization`), and every part must agree with the others: the algorithm the zip's keys
identify with the one the metadata names, the zip's spaces with the env's, the actor's layers
with the ``net_arch`` the zip and the metadata describe, the statistics' shape with the
observations, the files with their recorded hashes. A disagreement is one :class:`PolicyError`
naming the file and the mismatch.

The keys of ``metadata.json`` the loader reads:

* ``files``: ``{name: sha256}`` of every file the loader reads besides the metadata itself:
  the model zip and, unless the policy reads raw observations, ``normalization.json``
  (:func:`required_files`). A folder is checked whole: metadata without ``files``, or whose
  ``files`` leave out a file the policy needs, is refused.
* ``env_id`` and ``env_kwargs``: the env the policy was trained on. Without them (or without a
  ``metadata.json`` at all: a plain SB3 zip) nothing says which env that was, and the caller
  must name it (``--env`` on the command line, ``env_id=``/``config=`` of :func:`load_policy`).
  Where the ``hyperparams`` repeat them (``hyperparams.env_id``, ``hyperparams.env_kwargs``),
  they must agree.
* ``algo``: the **model format**, the stable-baselines3 algorithm whose zip layout and actor the
  file holds (``ppo``, ``a2c``, ``sac``, ``tqc``, ``td3``); checked against the zip's own keys.
* ``trained_by``: the **method** that fitted the network when it is not ``algo``'s own training
  (``"dagger"``: imitation of a planner, :mod:`agents.imitation`, written in PPO's format);
  absent: trained by ``algo``. It says how to read ``hyperparams``: a training recipe of
  ``algo`` (:mod:`agents.rl.training.hyperparams`, where an absent ``normalize`` means raw
  observations), or the method's own settings.
* ``hyperparams``: ``normalize`` null or false says the policy reads raw observations (then no
  ``normalization.json`` is needed); ``net_arch`` and ``policy_kwargs.net_arch`` are compared
  with the actor's layers.
* ``inference``: how the actor is computed: absent, torch's float32 forward pass;
  ``"portable"``, the fixed-order float64 one (:meth:`~.actor_net.ActorNet.predict_portable`).
  Any other value is refused (:data:`INFERENCE`).

* ``request``: present, the policy is **request-conditioned**: it takes the placement's requested
  tolerance (the env config's ``tolerance`` [m], where the env ends an episode once the part
  rests within it) as one more input. ``{"tolerance_m": [lo, hi], "feature": "log_ratio",
  "reference_m": r}``: the range of requests it was trained over [m], and its input
  ``log(tolerance / r)``, appended to each observation (and normalised with it). Loaded for a
  config, such a policy acts for that config's tolerance (:func:`bind_request`); a tolerance
  outside the trained range is refused, and within it the tolerance is not part of the scene
  :func:`check_scene` compares. A policy without the key acts on the observation alone.

A policy of the plane (``MicroConveyor2D-v0``) is loaded the same way: its scene is a
:class:`~microconveyor_env.envs.plane.config.PlaneEnvConfig` made from its env kwargs, and the
model's shapes are checked against the plane env's spaces.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, scene_differences
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.env_ids import ALL_ENV_IDS, PLANE_ENV_IDS, base_id
from microconveyor_env.envs.core.versions import check_env_id, config_class, nominal, scene_config
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.presets import PresetError

from . import normalization
from .checkpoint import META, MODEL, CheckpointError, read_meta, verify_files
from .normalization import NORMALIZATION, NormalizationError, ObsNormalizer
from .actor_net import ActorFileError, ActorNet, check_net_arch, load_actor
from .sb3_files import ALGOS, ModelFileError, algo_of, check_spaces, open_model, read_data

AnyConfig = EnvConfig | PlaneEnvConfig
__all__ = ["PLANE_ENV_IDS", "INFERENCE", "Policy", "PolicyError", "load_policy", "bind_request",
           "request_meta", "request_feature", "request_range", "REQUEST_REFERENCE_M",
           "policy_scene", "policy_env_id", "policy_env_kwargs", "read_policy_meta",
           "check_scene", "reads_raw_observations", "required_files", "with_request"]

INFERENCE = ("portable",)   # the values of the metadata's ``inference`` (absent: float32)
REQUEST_FEATURES = ("log_ratio",)   # the values of the metadata's ``request.feature``
REQUEST_REFERENCE_M = 50e-6   # [m] the request whose feature is 0 (the scenes' default tolerance)


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
    # the scene it was trained in, randomisation off (None: unknown)
    config: AnyConfig | None = None
    # the env it was trained on, its per-episode randomisation included (for a policy without
    # metadata: the env the caller named); what evaluate() runs by default
    trained_config: AnyConfig | None = None
    # the env id the caller named for a policy whose metadata names none
    named_env_id: str | None = None
    # a request-conditioned policy's request: the tolerance [m] it acts for (bind_request)
    request_m: float | None = None

    @property
    def env_id(self) -> str:
        """The env id the policy was trained on (its metadata's, else the one its loader was
        told); ValueError when neither says."""
        env_id = self.metadata.get("env_id") or self.named_env_id
        if not env_id:
            raise PolicyError(f"{str(self.path)!r}: no env id (its metadata names none)")
        return str(env_id)

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
        if self.metadata.get("request") is not None:
            if self.request_m is None:
                raise PolicyError(f"{str(self.path)!r} is request-conditioned and was given no "
                                  "request: bind it to a config (bind_request)")
            feature = request_feature(self.request_m, self.metadata["request"])
            obs = np.concatenate([obs, np.full((len(obs), 1), feature, obs.dtype)], axis=1)
        if self.actor.obs_keys is not None:
            from microconveyor_env.envs.line.goal import goal_observations

            return self.actor.predict(goal_observations(obs))
        if self.normalizer is not None:
            obs = self.normalizer(obs)
        try:
            if self.metadata.get("inference") == "portable":
                return self.actor.predict_portable(obs)
            return self.actor.predict(obs)
        except ActorFileError as exc:
            raise PolicyError(f"{str(self.path)!r}: {exc}") from None


def request_meta(meta: dict[str, Any], where: str = "metadata") -> dict[str, Any] | None:
    """The metadata's ``request`` checked (module docstring; None: not request-conditioned)."""
    req = meta.get("request")
    if req is None:
        return None
    rng = req.get("tolerance_m") if isinstance(req, dict) else None
    ok = (isinstance(rng, list) and len(rng) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in rng)
          and 0.0 < rng[0] <= rng[1] < 1.0)
    if not ok or req.get("feature") not in REQUEST_FEATURES or not (
            isinstance(req.get("reference_m"), (int, float)) and 0.0 < req["reference_m"] < 1.0):
        raise PolicyError(f"{where}: request must be {{\"tolerance_m\": [lo, hi] (0 < lo <= hi "
                          f"< 1 m), \"feature\": one of {list(REQUEST_FEATURES)}, "
                          f"\"reference_m\": r (0 < r < 1 m)}}, got {req!r}")
    return req


def request_range(meta: dict[str, Any]) -> tuple[float, float] | None:
    """The requested tolerances [m] a request-conditioned policy was trained over (None: the
    policy takes no request)."""
    req = request_meta(meta)
    return None if req is None else (float(req["tolerance_m"][0]), float(req["tolerance_m"][1]))


def request_feature(tolerance_m: float, request: dict[str, Any] | None = None) -> float:
    """The input a request-conditioned policy reads for the requested ``tolerance_m`` [m]:
    ``log(tolerance_m / reference_m)`` (``request``: the metadata's ``request``; default
    reference :data:`REQUEST_REFERENCE_M`)."""
    ref = REQUEST_REFERENCE_M if request is None else float(request["reference_m"])
    return float(np.log(float(tolerance_m) / ref))


def _check_request(meta: dict[str, Any], tolerance_m: float, where: str) -> None:
    lohi = request_range(meta)
    if lohi is None:
        return
    lo, hi = lohi
    if not lo * (1 - 1e-9) <= tolerance_m <= hi * (1 + 1e-9):
        raise PolicyError(f"{where}: the policy was trained for requested tolerances in "
                          f"[{lo * 1e6:g}, {hi * 1e6:g}] µm; the env asks for "
                          f"{tolerance_m * 1e6:g} µm (its tolerance). Give a tolerance in that "
                          "range")


def bind_request(policy: Any, config: Any) -> Any:
    """``policy`` acting for ``config``'s requested tolerance (its ``tolerance`` [m]): a
    request-conditioned :class:`Policy` (module docstring) bound to it, PolicyError when it is
    outside the range the policy was trained over; any other actor as it is."""
    if not isinstance(policy, Policy) or policy.metadata.get("request") is None:
        return policy
    tol = float(config.tolerance)
    _check_request(policy.metadata, tol, repr(str(policy.path / META)))
    return policy if policy.request_m == tol else dataclasses.replace(policy, request_m=tol)


def _locate(path: Path) -> tuple[Path, Path]:
    folder, model_file = (path, path / MODEL) if path.is_dir() else (path.parent, path)
    if not model_file.is_file():
        raise PolicyError(f"no policy at {str(path)!r}: expected a folder with {MODEL}, "
                          f"{NORMALIZATION} and {META}, or a model .zip")
    return folder, model_file


def _metadata(folder: Path) -> dict[str, Any]:
    """The folder's metadata, its ``files`` verified ({}: no metadata.json)."""
    path = folder / META
    if not (path.exists() or path.is_symlink()):
        return {}
    try:
        meta = read_meta(folder)
        verify_files(folder, meta)   # a folder is checked whole: no files listed, refused
    except CheckpointError as exc:
        raise PolicyError(f"{exc}; a policy folder's {META} lists every file the loader reads "
                          "with its sha256 (files)") from None
    where = repr(str(path))
    if meta.get("inference") is not None and meta["inference"] not in INFERENCE:
        raise PolicyError(f"{where}: inference {meta['inference']!r} is not one this loader "
                          f"knows (absent: float32, or {', '.join(map(repr, INFERENCE))})")
    trained_by = meta.get("trained_by")
    if trained_by is not None and not (isinstance(trained_by, str) and trained_by):
        raise PolicyError(f"{where}: trained_by must name the training method, got "
                          f"{trained_by!r}")
    hp = meta.get("hyperparams")
    if hp is not None and not isinstance(hp, dict):
        raise PolicyError(f"{where}: hyperparams must be a mapping, got {type(hp).__name__}")
    hp_id = (hp or {}).get("env_id")
    if meta.get("env_id") is not None and hp_id is not None and hp_id != meta["env_id"]:
        raise PolicyError(f"{where}: env_id {meta['env_id']!r} and hyperparams.env_id "
                          f"{hp_id!r} disagree: which env the policy was trained on is unclear")
    policy_env_kwargs(meta, where)   # the top level and the hyperparams agree
    return meta


def reads_raw_observations(meta: dict[str, Any]) -> bool:
    """Whether the metadata says the policy reads raw observations (no ``normalization.json``):
    ``hyperparams.normalize`` null or false, or, for a policy trained by its algorithm's own
    recipe (no ``trained_by`` other than ``algo``), a recipe without ``normalize`` (a recipe's
    default: no normalisation). A policy fitted by another method (``trained_by: "dagger"``)
    reads normalised observations unless its ``hyperparams.normalize`` says otherwise."""
    hp = meta.get("hyperparams")
    if not isinstance(hp, dict):
        return False
    if "normalize" in hp:
        return hp["normalize"] is None or hp["normalize"] is False
    return meta.get("trained_by", meta.get("algo")) == meta.get("algo")


def required_files(meta: dict[str, Any], model: str = MODEL) -> tuple[str, ...]:
    """The files a policy folder's ``files`` must list for the loader: the model zip
    (``model``) and, unless :func:`reads_raw_observations`, ``normalization.json``."""
    return (model,) if reads_raw_observations(meta) else (model, NORMALIZATION)


def _no_stats(folder: Path) -> PolicyError:
    return PolicyError(f"{str(folder)!r} has no {NORMALIZATION}: a policy trained on normalised "
                       f"observations acts blindly without it. If it was trained on raw "
                       f"observations, say so in {META}: {{\"hyperparams\": {{\"normalize\": "
                       "null}}")


def _check_listed(folder: Path, model_file: Path, meta: dict[str, Any]) -> None:
    """PolicyError unless the metadata's ``files`` list every file the policy needs (their
    hashes are verified by :func:`_metadata`)."""
    listed = meta["files"]
    for name in required_files(meta, model_file.name):
        if name in listed:
            continue
        if name == NORMALIZATION and not (folder / name).is_file():
            _refuse_pickle(folder, model_file)
            raise _no_stats(folder)
        raise PolicyError(f"{str(folder / META)!r} does not list {name} in files (with its "
                          f"sha256): a policy folder is checked whole, every file it needs "
                          f"recorded")
    if reads_raw_observations(meta) and NORMALIZATION not in listed \
            and (folder / NORMALIZATION).exists():
        raise PolicyError(f"{str(folder / META)!r} says the policy reads raw observations, "
                          f"but {str(folder / NORMALIZATION)!r} lies beside it, unlisted: which "
                          "observations the policy reads is unclear")


def _spaces(config: AnyConfig, env_id: str) -> tuple[Any, Any]:
    """The spaces of ``env_id``'s single env (its registered entry point) on ``config``."""
    import importlib

    from microconveyor_env.env_ids import ENTRY_POINTS

    module, name = ENTRY_POINTS[env_id].split(":")
    env = getattr(importlib.import_module(module), name)(config=config)
    return env.observation_space, env.action_space


def _normalizer(folder: Path, model_file: Path, meta: dict[str, Any],
                obs_shape: tuple[int, ...]) -> ObsNormalizer | None:
    # with metadata: the listed file beside the model (_check_listed); without: beside the
    # model, or where convert-stats writes it on rl-zoo3's layout (beside its vecnormalize.pkl,
    # in the folder named after the model zip)
    places = ((folder / NORMALIZATION,) if meta else
              (folder / NORMALIZATION, folder / model_file.stem / NORMALIZATION))
    if meta and NORMALIZATION not in meta["files"]:
        return None   # the metadata says the policy reads raw observations
    for path in places:
        if path.is_file():
            try:
                return normalization.obs_normalizer(normalization.read(path, obs_shape))
            except NormalizationError as exc:
                raise PolicyError(str(exc)) from None
    _refuse_pickle(folder, model_file)
    raise _no_stats(folder)


def _refuse_pickle(folder: Path, model_file: Path) -> None:
    """PolicyError naming convert-stats when the statistics lie beside the model as a pickle."""
    for pkl in (folder / normalization.LEGACY_PICKLE,
                folder / model_file.stem / normalization.LEGACY_PICKLE):  # rl-zoo3's layout
        if pkl.is_file():
            raise PolicyError(
                f"{str(pkl)!r} is a pickle: loading it can run any code it names, so it is not "
                f"loaded. If you trust where it came from, convert it once with `microconveyor "
                f"convert-stats {pkl}` (writes {NORMALIZATION} beside it)")


def read_policy_meta(path: str | Path) -> dict[str, Any]:
    """The checked metadata of the policy at ``path`` (folder or model zip; {}: none)."""
    return _metadata(_locate(Path(path))[0])


def policy_env_kwargs(meta: dict[str, Any], where: str = "metadata") -> dict[str, Any]:
    """The env kwargs a policy was trained with (``env_kwargs``; older metadata: the
    hyperparameters' ``env_kwargs``); PolicyError when both are given and disagree."""
    kw = meta.get("env_kwargs")
    hp = meta.get("hyperparams")
    hp_kw = hp.get("env_kwargs") if isinstance(hp, dict) else None
    if kw is not None and hp_kw is not None and kw != hp_kw:
        raise PolicyError(f"{where}: env_kwargs {kw!r} and hyperparams.env_kwargs {hp_kw!r} "
                          "disagree: which env the policy was trained on is unclear")
    if kw is None:
        kw = hp_kw or {}
    if not isinstance(kw, dict):
        raise PolicyError(f"env_kwargs in the metadata must be a mapping, got {kw!r}")
    return dict(kw)


def _naming(where: str) -> str:
    return (f"{where}: nothing says which env the policy was trained on; name it: --env ID on "
            "the command line, or load_policy(path, env_id=ID) (or config=) in Python")


def policy_env_id(meta: dict[str, Any], where: str = "metadata") -> str:
    """The registered env id the metadata names; PolicyError when it names none."""
    env_id = meta.get("env_id")
    if env_id is None:
        raise PolicyError(_naming(f"{where} names no env_id"))
    try:
        return check_env_id(str(env_id))
    except ParameterError as exc:
        raise PolicyError(f"{where}: {exc}") from None


def policy_scene(meta: dict[str, Any], where: str = "metadata") -> AnyConfig:
    """The config of the env a policy was trained on: ``scene_config(env_id, **env_kwargs)``
    (an :class:`EnvConfig`, or the plane's :class:`PlaneEnvConfig`), per-episode randomisation
    included; PolicyError when the metadata names no env id."""
    env_id = policy_env_id(meta, where)
    kwargs = policy_env_kwargs(meta, where)
    if "path" in kwargs:
        raise PolicyError(f"{where}: env_kwargs name a file ('path'); a policy's scene is "
                          "its env id and field values")
    try:
        return scene_config(env_id, **kwargs)
    except (ParameterError, PresetError) as exc:
        raise PolicyError(f"{where}: the env the policy was trained on cannot be made ({exc})") \
            from None


def check_scene(trained: AnyConfig, asked: AnyConfig, meta: dict[str, Any], where: str) -> None:
    """PolicyError when ``asked`` is another scene than the one the policy was trained in."""
    diff = scene_differences(trained, asked)
    if set(diff) == {"tolerance"}:
        a, b = diff["tolerance"]
        raise PolicyError(f"{where}: the policy was trained for a tolerance of ±{a * 1e6:g} µm "
                          f"and does not take the requested tolerance as an input (asked "
                          f"±{b * 1e6:g} µm); use a request-conditioned policy (its metadata "
                          "names a 'request', e.g. the shipped dagger_request of "
                          "MicroPositioner-v0 and MicroConveyor2D-v1), or a model-based method "
                          "(--method mpc or de)")
    if diff:
        fields = "; ".join(f"{k}: trained {a!r}, asked {b!r}" for k, (a, b) in diff.items())
        raise PolicyError(f"{where}: the policy was trained on {meta.get('env_id', '?')}"
                          f" with env kwargs {policy_env_kwargs(meta)}, and the env asked for "
                          f"differs in {fields}. Evaluating a policy on another scene is refused; "
                          "give the policy's own --env/--env-kwargs/--preset (or none)")


def _env_id_of(config: AnyConfig, where: str) -> str:
    """The registered scene version whose defaults make ``config``'s scene (or the only one of
    its config class)."""
    ids = [i for i in ALL_ENV_IDS if base_id(i) == i and config_class(i) is type(config)]
    same = [i for i in ids if not scene_differences(scene_config(i), config)]
    if len(same) == 1 or len(ids) == 1:
        return (same or ids)[0]
    raise PolicyError(_naming(f"{where}, and the config given is the scene of "
                              f"{' or '.join(same or ids)}"))


def load_policy(path: str | Path, config: AnyConfig | None = None,
                env_id: str | None = None) -> Policy:
    """The policy at ``path`` (a policy folder, or a model zip with its files beside it), checked
    as a unit, for the env ``config`` (default: the scene it was trained in, from its metadata;
    a MicroConveyor2D policy: its :class:`PlaneEnvConfig`). A ``config`` of another scene than
    the policy's is refused (:func:`check_scene`).

    A policy whose metadata names no env id (a folder without ``metadata.json``: a plain SB3
    zip) is refused unless the caller names it: ``env_id`` (its registered defaults, or
    ``config`` as the scene), or ``config`` alone (the env id whose defaults make that scene).
    An ``env_id`` of another scene version than the metadata's is refused."""
    folder, model_file = _locate(Path(path))
    meta = _metadata(folder)
    where = repr(str(folder / META))
    if meta:
        _check_listed(folder, model_file, meta)
    try:
        if env_id is not None:
            check_env_id(env_id)
    except ParameterError as exc:
        raise PolicyError(str(exc)) from None
    try:
        zf = open_model(model_file)   # read once, within its limits
        data = read_data(model_file, zf)
    except ModelFileError as exc:
        raise PolicyError(f"{exc}; not a stable-baselines3 model") from None
    algo = algo_of(data)
    if meta.get("algo") and algo is not None and meta["algo"] != algo:
        raise PolicyError(f"{where} says {str(meta['algo']).upper()}, but "
                          f"{str(model_file)!r} is an {algo.upper()} model")
    if algo is None:
        raise PolicyError(f"{str(model_file)!r} is not a model of a kind this loader knows "
                          f"(stable-baselines3 {', '.join(a.upper() for a in ALGOS)})")
    named = env_id
    if meta.get("env_id") is not None:
        env_id = policy_env_id(meta, where)
    elif env_id is None:
        if config is None:
            raise PolicyError(_naming(f"{where} names no env_id" if meta else
                                      f"{str(folder)!r} has no {META}"))
        env_id = _env_id_of(config, f"{str(folder)!r} has no {META}" if not meta else
                            f"{where} names no env_id")
    trained = policy_scene({**meta, "env_id": env_id}, where) if meta else None
    request = request_meta(meta, where)
    if trained is not None and config is not None:
        check_scene(trained, _as_scene(config, trained, meta, where),
                    {**meta, "env_id": env_id}, where)
    if named is not None and base_id(named) != base_id(env_id):
        raise PolicyError(f"{where}: the policy was trained on {env_id}, not {named}; "
                          "evaluating a policy on another env is refused")
    cfg = config or trained or _scene(env_id, where)
    try:
        obs_space, act_space = _spaces(cfg, env_id)
    except (ParameterError, PresetError) as exc:
        raise PolicyError(f"{where}: the env the policy was trained on cannot be "
                          f"made ({exc})") from None
    try:
        if request is not None:
            obs_space = with_request(obs_space)
        check_spaces(model_file, data, obs_space, act_space, env_id)
        normalizer = _normalizer(folder, model_file, meta, obs_space.shape)
        actor = load_actor(model_file, algo, obs_space, act_space, zf)
    except ModelFileError as exc:
        raise PolicyError(str(exc)) from None
    _check_actor(actor, meta, where)
    trained_full = trained if trained is not None else cfg
    policy = Policy(actor, normalizer, meta, folder, nominal(trained_full), trained_full,
                    None if meta.get("env_id") else env_id)
    return bind_request(policy, cfg)


def with_request(observation_space: Any) -> Any:
    """A Box observation space with one more entry, unbounded: a request-conditioned policy's
    input (the observation, then the request's feature)."""
    from gymnasium import spaces

    if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
        raise PolicyError("a request-conditioned policy reads Box observations (a vector)")
    low = np.append(observation_space.low, -np.inf).astype(observation_space.dtype)
    high = np.append(observation_space.high, np.inf).astype(observation_space.dtype)
    return spaces.Box(low, high, dtype=observation_space.dtype)


def _as_scene(config: AnyConfig, trained: AnyConfig, meta: dict[str, Any],
              where: str) -> AnyConfig:
    """``config`` as the scene :func:`check_scene` compares with ``trained``: for a
    request-conditioned policy, a request within its trained range is not the scene (its
    tolerance taken as trained); PolicyError outside the range."""
    if request_meta(meta, where) is None:
        return config
    _check_request(meta, float(config.tolerance), where)
    return dataclasses.replace(config, tolerance=trained.tolerance)


def _scene(env_id: str, where: str) -> AnyConfig:
    try:
        return scene_config(env_id)
    except (ParameterError, PresetError) as exc:
        raise PolicyError(f"{where}: {env_id} cannot be made ({exc})") from None


def _check_actor(actor: ActorNet, meta: dict[str, Any], where: str) -> None:
    """The actor against what the metadata says of it: its hidden widths against
    ``hyperparams.net_arch`` and ``hyperparams.policy_kwargs.net_arch``, and portable
    inference's needs (Box observations, a Tanh or ReLU network)."""
    hp = meta.get("hyperparams") or {}
    sources = {"hyperparams.net_arch": hp.get("net_arch")}
    if isinstance(hp.get("policy_kwargs"), dict):
        sources["hyperparams.policy_kwargs.net_arch"] = hp["policy_kwargs"].get("net_arch")
    try:
        for name, net_arch in sources.items():
            if net_arch is not None:
                check_net_arch(actor, net_arch, f"{where}'s {name}")
    except ActorFileError as exc:
        raise PolicyError(f"the model zip {exc}") from None
    if meta.get("inference") == "portable" and (
            actor.obs_keys is not None or actor.activation not in ("Tanh", "ReLU")):
        raise PolicyError(f"{where}: portable inference takes Box observations and a Tanh or "
                          f"ReLU network, not a {actor.activation} network"
                          + (" on Dict observations" if actor.obs_keys is not None else ""))
