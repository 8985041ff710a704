"""DAgger: a policy network that imitates a model-based expert on the states it visits itself,
saved as a policy folder that loads as data like every trained policy.

Three experts, one per scene, picked by :func:`agents.mpc.experts.expert_for` (their settings:
``configs/dagger.yml``, keyed by env id):

* MicroPositioner-v0: the one-step model-based search (:class:`~agents.mpc.experts.
  BatchExpert`): every reachable actuator, frequency and stroke from where the part rests,
  ranked on the scene's firing map (the nominal model tabulated once) and its choice confirmed
  on the full nominal model; it sees where the part rests and the target, never the episode's
  friction, mass or noise;
* MicroConveyor2D-v0/-v1 (the plane): the same one-step search around every actuator the aim
  can pick (:func:`agents.planning.plane.labeller`), ranked on the plane's firing map and
  confirmed on the full nominal model, each stroke started once the part has come to rest;
* MicroConveyor-v1 (the 1-D conveyor), from the simulator alone (the recipe): the staged expert
  (:class:`~agents.mpc.staged.StagedExpert`): each of the first firings has its stroke and delay
  fixed and its frequency aimed on the nominal model so that the part rests on the target, or,
  for a target beyond that firing's reach, its strongest frequency carrying the part on: one
  family of plans, continuous in the target;
* MicroConveyor-v1 with ``seed_policy``: model-predictive control seeded by a policy
  (:class:`~agents.mpc.experts.SeededExpert`): the seed policy's firing, its last firing re-aimed
  on the nominal model so that the part rests on the target (the recipe's ``seeded`` settings).

With ``requests`` (a list of tolerances [m]) the policy is **request-conditioned**: each round's
episodes are spread over batched envs, one per requested tolerance (the env ends an episode when
the part rests within it), the student reads the observation and the request's feature
(:func:`agents.rl.artefacts.policy_files.request_feature`), and the labels are the scene's
expert's (``request_slack``: its slack at most that fraction of the request). The folder's
metadata names the range trained over (``request``), and the loaded policy acts for the
tolerance of the env it is evaluated in.

Each round plays ``episodes`` episodes at once on the batched env (round 0 with the expert
acting, later rounds with the policy), asks the expert what it would fire from every state
visited, adds those pairs to the data set, and fits the policy network to the whole set (mean
squared error on the action: Adam over ``epochs`` passes, or full-batch L-BFGS in float64 for
``fit_iterations``, as ``refine`` fits: a conveyor's far landings move by tens of µm per 10^-3
action units of the last firing). Ross,
Gordon and Bagnell's DAgger (2011): the policy learns the expert's answers on its own mistakes,
which behaviour cloning from the expert's episodes alone never shows it.

The network is SB3 PPO's actor (``MlpPolicy``, tanh, ``net_arch``), trained in place inside a PPO
model with observation normalisation (VecNormalize's formula, statistics of the first round's
data, frozen), so the result is an ordinary PPO policy folder: ``model.zip``,
``normalization.json`` and ``metadata.json`` (``trained_by: "dagger"``, the expert, every
round's figures), which ``evaluate``, ``compare`` and ``video`` load as data
(:mod:`agents.rl.artefacts.policy_files`). It acts in one forward pass.
"""
from __future__ import annotations

import dataclasses
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from microconveyor_env.envs.line.config import EnvConfig
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.env_ids import GOAL_ENV_IDS
from microconveyor_env.envs.core.versions import check_env_id, scene_config, vector_class

from ..mpc.experts import SEARCHES, expert_for
from ..planning import PositionerScene, scene_of
from .student import Student

ENV_ID = "MicroPositioner-v0"   # the dataclass defaults are the positioner's recipe
# the positioner's per-episode randomisation: the level its policy is meant to hold
TRAIN_KWARGS = {"action_noise": 3e-3, "friction_factor_range": (0.95, 1.05),
                "mass_factor_range": (0.95, 1.05)}
FITS = ("adam", "lbfgs")
KEEPS = ("last", "best")   # which round's fit the policy folder holds
# an expert's answers for a batch: (actions (M, components) float32, whether each has one, whether each
# was corrected by the model rather than taken from a seed; None: not that kind of expert)
Labels = tuple[np.ndarray, np.ndarray, "np.ndarray | None"]
# label(observations, the batched env, which sub-envs are still in their episode) -> Labels
Labeller = Callable[[np.ndarray, Any, np.ndarray], Labels]


@dataclass(frozen=True)
class DaggerSettings:
    """One DAgger run. ``env_id``: a positioner, a 1-D conveyor or the plane (Box observations), with
    ``env_kwargs`` (``gym.make`` overrides, SI; default: :data:`TRAIN_KWARGS`); ``seed`` [-];
    ``rounds`` [-] (round 0: the expert acts); ``episodes`` [-] per round; ``net_arch`` [-]
    hidden layer widths.

    The fit after each round: ``fit`` ``"adam"`` (``epochs`` [-] passes over the whole data set
    in batches of ``batch_size`` [-], ``learning_rate`` [-] multiplied by ``lr_decay`` [-] after
    every round) or ``"lbfgs"`` (full batch in float64, ``fit_iterations`` [-]).

    ``keep``: which fit the policy folder holds: ``"last"`` the last round's, or ``"best"`` the
    one whose episodes went best (each fit is scored by the next round's episodes, which it
    plays itself, and the last fit by one more round of ``episodes`` without labels; the highest
    share within the tolerance, then the lower median error), as Ross, Gordon and Bagnell return
    the best policy of the rounds on validation episodes.

    The positioner's expert (:class:`~agents.mpc.experts.BatchExpert`): ``frequencies``,
    ``strokes`` [-] its candidate grid, ``margin`` [-] grid cells from detachment, ``slack_m``
    [m] how much farther a gentler firing may land, ``heavier`` [-] the heavier part it checks,
    ``search`` where it ranks the candidates: ``"map"`` on the scene's firing map, its choice
    confirmed on the full model, or ``"model"`` every candidate fired on the full model (the
    same rule, a few times slower).
    The plane's expert (:func:`agents.planning.plane.labeller`): the same grid, ``margin``,
    ``slack_m`` and ``heavier`` around every actuator the aim can pick, ranked on the plane's
    firing map and confirmed on the full model; ``lookahead``: a landing outside the tolerance
    is scored by what one more firing could reach from it (off: by its own distance), for parts
    resting within ``lookahead_within_m`` [m] of their target (farther ones: by the landing's
    own distance; None: every part).
    The conveyor's experts: with no ``seed_policy`` the staged expert
    (:class:`~agents.mpc.staged.StagedExpert`), else the seeded one
    (:class:`~agents.mpc.experts.SeededExpert`) of ``seed_policy``, a shipped policy's name for
    ``env_id`` or a policy folder; ``newton_iterations`` [-] and ``accept_m``
    [m] of the re-aimed last firing.

    ``requests`` [m]: the requested tolerances a request-conditioned policy is trained over
    (module docstring; each round's ``episodes`` split evenly among them; None: the env's own
    tolerance, no request input); ``request_slack`` [-]: the expert's ``slack_m`` at most this
    fraction of each request (None: ``slack_m`` for every request)."""

    env_id: str = ENV_ID
    env_kwargs: dict[str, Any] = field(default_factory=lambda: dict(TRAIN_KWARGS))
    seed: int = field(default=0, metadata={"help": "training seed", "bounds": (0, 2**31 - 1)})
    rounds: int = field(default=20, metadata={
        "help": "DAgger rounds (round 0: the expert acts; later: the policy; default: the "
                "recipe's, 5 on MicroConveyor-v1, 20 on MicroPositioner-v0, 16 on "
                "MicroConveyor2D-v1)", "bounds": (1, 1000)})
    episodes: int = field(default=256, metadata={
        "help": "episodes per round, played at once on the batched env (default: the recipe's, "
                "256; 128 on MicroConveyor2D-v1)", "bounds": (1, 100000)})
    net_arch: tuple[int, ...] = (128, 128)
    fit: str = "adam"
    epochs: int = 30
    batch_size: int = 256
    learning_rate: float = 1e-3
    lr_decay: float = 0.85
    fit_iterations: int = 1000
    frequencies: int = 81
    strokes: int = 11
    margin: int = 4
    slack_m: float = 5e-6
    heavier: float = 0.1
    search: str = "map"
    lookahead: bool = False
    lookahead_within_m: float | None = None
    keep: str = "last"
    seed_policy: str | None = field(default=None, metadata={
        "help": "MicroConveyor-v1: a policy that seeds the expert, a shipped policy's name (e.g. "
                "ppo_refined) or a policy folder, with the recipe's seeded settings (default: "
                "none, the staged expert built from the simulator alone)", "metavar": "NAME|PATH"})
    newton_iterations: int = 6
    accept_m: float = 2e-6
    requests: tuple[float, ...] | None = field(default=None, metadata={
        "help": "train a request-conditioned policy over these requested tolerances [m] (e.g. "
                "5e-6 10e-6 20e-6 50e-6): each round's episodes spread over them, the request "
                "an input of the policy (default: none, the env's own tolerance)",
        "nargs": "+", "metavar": "M"})
    request_slack: float | None = 0.5

    def __post_init__(self) -> None:
        check_env_id(self.env_id)
        self._check_requests()
        if self.env_id in GOAL_ENV_IDS:
            raise ValueError(f"{self.env_id} has Dict observations; DAgger trains on the Box "
                             "env of the same scene (MicroConveyor-v1)")
        for name, least in (("seed", 0), ("rounds", 1), ("episodes", 1), ("epochs", 1),
                            ("batch_size", 1), ("frequencies", 2), ("strokes", 2),
                            ("margin", 0), ("fit_iterations", 1), ("newton_iterations", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} = {v!r} is invalid: must be an integer >= {least}")
        if not self.net_arch or any(not isinstance(w, int) or w < 1 for w in self.net_arch):
            raise ValueError(f"net_arch = {self.net_arch!r} is invalid: positive widths")
        for name, allowed in (("fit", FITS), ("keep", KEEPS), ("search", SEARCHES)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} = {getattr(self, name)!r} is invalid: must be one of "
                                 f"{allowed}")
        for name in ("learning_rate", "lr_decay"):
            v = getattr(self, name)
            if not (isinstance(v, float) and 0.0 < v <= 1.0) or v == 1.0 and name != "lr_decay":
                raise ValueError(f"{name} = {v!r} is invalid: must be in (0, 1)")
        if not isinstance(self.lookahead, bool):
            raise ValueError(f"lookahead = {self.lookahead!r} is invalid: true or false")
        within = self.lookahead_within_m
        if within is not None and not (isinstance(within, float) and 0.0 < within < 1.0):
            raise ValueError(f"lookahead_within_m = {within!r} is invalid: must be in (0, 1) m "
                             "(None: every part)")
        if not (isinstance(self.heavier, float) and 0.0 <= self.heavier <= 1.0):
            raise ValueError(f"heavier = {self.heavier!r} is invalid: must be in [0, 1]")
        for name in ("slack_m", "accept_m"):
            v = getattr(self, name)
            if not (isinstance(v, float) and 0.0 <= v < 1e-3):
                raise ValueError(f"{name} = {v!r} is invalid: must be in [0, 1e-3) m")
        if self.seed_policy is not None and not (isinstance(self.seed_policy, str)
                                                 and self.seed_policy):
            raise ValueError(f"seed_policy = {self.seed_policy!r} is invalid: a shipped "
                             "policy's name or a policy folder")

    def _check_requests(self) -> None:
        if self.requests is not None:
            req = tuple(self.requests)
            if (not req or any(isinstance(t, bool) or not isinstance(t, (int, float))
                               or not 0.0 < t < 1e-3 for t in req)
                    or list(req) != sorted(set(req))):
                raise ValueError(f"requests = {self.requests!r} is invalid: increasing "
                                 "tolerances in (0, 1e-3) m")
            if len(req) > self.episodes:
                raise ValueError(f"requests: {len(req)} tolerances for {self.episodes} episodes "
                                 "a round: at least one episode each")
            object.__setattr__(self, "requests", tuple(float(t) for t in req))
        rs = self.request_slack
        if rs is not None and not (isinstance(rs, float) and 0.0 < rs <= 1.0):
            raise ValueError(f"request_slack = {rs!r} is invalid: must be in (0, 1]")

    def config(self) -> PositionerConfig | EnvConfig | PlaneEnvConfig:
        cfg = scene_config(self.env_id, **self.env_kwargs)
        if isinstance(cfg, (PositionerConfig, PlaneEnvConfig)):
            if self.seed_policy is not None:
                raise ValueError(f"seed_policy: {self.env_id}'s expert is not seeded by a policy")
            return cfg
        if not isinstance(cfg, EnvConfig):
            raise ValueError(f"{self.env_id} is not a scene DAgger has an expert for "
                             "(MicroPositioner-v0, MicroConveyor-v1, MicroConveyor2D-v0/-v1)")
        return cfg


def recipe(env_id: str, **overrides: Any) -> DaggerSettings:
    """The settings of ``env_id``'s recipe (``configs/dagger.yml``) with ``overrides`` (any
    :class:`DaggerSettings` field; ``env_kwargs`` replaces the recipe's). A recipe's ``seeded``
    entry holds the settings that replace its own when ``overrides`` name a ``seed_policy``
    (the expert seeded by that policy)."""
    check_env_id(env_id)
    data = yaml.safe_load((resources.files("microconveyor_env.configs") / "dagger.yml")
                          .read_text()) or {}
    if env_id not in data:
        raise ValueError(f"configs/dagger.yml has no recipe for {env_id!r} (it has "
                         f"{', '.join(map(str, data))}): DAgger's experts plan "
                         "MicroPositioner-v0, MicroConveyor-v1 and MicroConveyor2D-v1")
    entry = dict(data[env_id])
    seeded = entry.pop("seeded", None) or {}
    if overrides.get("seed_policy") is not None:
        entry.update(seeded)
    names = {f.name for f in dataclasses.fields(DaggerSettings)}
    unknown = sorted((set(entry) | set(seeded)) - names)
    if unknown:
        raise ValueError(f"configs/dagger.yml, {env_id}: unknown keys {unknown}")
    for key in ("net_arch", "requests"):
        if entry.get(key) is not None:
            entry[key] = tuple(entry[key])
    if "env_kwargs" in entry:
        entry["env_kwargs"] = {k: tuple(v) if isinstance(v, list) else v
                               for k, v in (entry["env_kwargs"] or {}).items()}
    return DaggerSettings(**{**entry, "env_id": env_id, **overrides})


def seed_policy_path(s: DaggerSettings) -> Path:
    """The folder of ``s.seed_policy``: an existing path as given, else a shipped policy of
    ``s.env_id`` by that name."""
    from ..rl.artefacts.shipped import shipped_path

    assert s.seed_policy is not None
    given = Path(s.seed_policy)
    if given.exists():
        return given
    shipped = shipped_path(s.seed_policy, s.env_id)
    return shipped if (shipped / "model.zip").is_file() else given


def make_expert(s: DaggerSettings, cfg: Any) -> tuple[Labeller, dict[str, Any]]:
    """The expert of ``cfg``'s scene as ``label(obs, venv)`` and its description for the
    metadata."""
    if isinstance(cfg, PlaneEnvConfig):
        return expert_for(cfg, s).label, {
            "kind": "one-step model-based on the plane, nominal model, ranked on the plane's "
                    "firing map and confirmed on the full model, the gentlest firing within "
                    "the slack of the nearest",
            "frequencies": s.frequencies, "strokes": s.strokes, "margin": s.margin,
            "slack_m": s.slack_m, "heavier": s.heavier, "lookahead": s.lookahead,
            "lookahead_within_m": s.lookahead_within_m}
    if isinstance(scene_of(cfg), PositionerScene):
        return expert_for(cfg, s).label, {
            "kind": "one-step model-based, nominal model, the gentlest firing within the "
                    "slack of the nearest",
            "frequencies": s.frequencies, "strokes": s.strokes, "margin": s.margin,
            "slack_m": s.slack_m, "heavier": s.heavier, "search": s.search}
    if s.seed_policy is None:
        from ..mpc.staged import STAGES, StagedExpert

        staged = StagedExpert(cfg, iterations=s.newton_iterations, accept_m=s.accept_m)
        return staged.label, {
            "kind": "staged family from the simulator alone: the first firings' strokes and "
                    "delays fixed, each frequency aimed on the nominal model (Newton) or, for a "
                    "target beyond that firing's reach, its strongest carrying the part on",
            "stages": [list(st) for st in STAGES],
            "newton_iterations": s.newton_iterations, "accept_m": s.accept_m}
    from ..rl.artefacts.checkpoint import sha256
    from ..rl.artefacts.policy_files import (PolicyError, load_policy, policy_scene,
                                            read_policy_meta)
    from microconveyor_env.envs.core.versions import scene_differences

    folder = seed_policy_path(s)
    meta = read_policy_meta(folder)
    diff = scene_differences(policy_scene(meta), cfg) if meta else {"metadata": ("none", "")}
    if diff:
        raise PolicyError(f"seed policy {str(folder)!r} was trained in another scene than "
                          f"{s.env_id} with the env kwargs given (differs in "
                          f"{', '.join(sorted(diff))}): give a seed policy of this scene")
    policy = load_policy(folder, config=cfg)
    return expert_for(cfg, s, policy.act).label, {
        "kind": "model-predictive control seeded by a policy: its firings, its last firing "
                "re-aimed by Gauss-Newton on the nominal model",
        "seed_policy": s.seed_policy, "seed_policy_env_id": policy.env_id,
        "seed_policy_model_sha256": sha256(policy.path / "model.zip"),
        "newton_iterations": s.newton_iterations, "accept_m": s.accept_m}


def no_firing(venv: Any) -> np.ndarray:
    """The action a sub-env the expert has no firing for fires: the weakest firing, of a far
    actuator on a line (actions ``[1, -1, -1]``), of the nearest actuator with no delay on the
    plane (``[0, 0, -1, -1, -1]``)."""
    if isinstance(venv.config, PlaneEnvConfig):
        from ..planning.plane import NO_LABEL

        return NO_LABEL
    return np.array([1.0, -1.0, -1.0], np.float32)


def _distance(info: dict[str, Any]) -> np.ndarray:
    """Each part's distance to its target [m] from a batched env's info: the plane's Euclidean
    ``distance_m``, a line's ``|position_error_m|``."""
    if "distance_m" in info:
        return np.asarray(info["distance_m"], float)
    return np.abs(np.asarray(info["position_error_m"], float))


def _play(venv: Any, label: Labeller, act: Any, seed: int,
          feature: float | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """One episode per sub-env: ``act(obs)`` fires (None: the expert); every state visited
    before a firing is labelled with the expert's action. Returns (observations, labels,
    figures of the episodes). ``feature``: a request's, appended to each observation the
    policy reads and the data set holds (None: the observation alone)."""
    def aug(o: np.ndarray) -> np.ndarray:
        if feature is None:
            return o
        return np.concatenate([o, np.full((len(o), 1), feature, o.dtype)], axis=1)

    n = venv.num_envs
    none = no_firing(venv)
    obs, _ = venv.reset(seed=seed)
    done = np.zeros(n, bool)
    err = np.zeros(n)
    outcome = np.empty(n, dtype=object)
    X, Y = [], []
    firings = corrected = 0
    seeded = False
    while not done.all():
        live = ~done
        lab, ok, fixed = label(obs, venv, live)
        keep = live & ok
        X.append(aug(obs[keep].copy()))
        Y.append(lab[keep])
        if fixed is not None:
            seeded = True
            corrected += int((fixed & live).sum())
        a = lab.copy() if act is None else np.asarray(act(aug(obs)), np.float32)
        if act is None:
            a[~ok] = none
        obs, _, term, trunc, info = venv.step(a)
        firings += int(live.sum())
        end = live & (term | trunc)
        err[end] = _distance(info)[end]
        outcome[end] = info["outcome"][end]
        done |= end
    hit = (outcome == "rest") & (err <= venv.config.tolerance)
    fig = {"episodes": n, "firings": firings, "success_rate": float(hit.mean()),
           "median_abs_error_m": float(np.median(err)),
           "detach_rate": float(np.mean(outcome == "detached")), "_err": err}
    if seeded:   # how many labels the model re-aimed rather than took from the seed
        fig["labels_corrected"] = corrected
    return np.concatenate(X), np.concatenate(Y), fig


@dataclass
class _Requests:
    """The batched envs a round plays (one per requested tolerance, or the env's own), each with
    its expert and the feature the student reads (None: no request input)."""

    venvs: list[Any]
    labels: list[Labeller]
    features: list[float | None]

    def play(self, act: Any, seed: int,
             label: Labeller | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        """:func:`_play` on every env (``label``: instead of each env's expert), their data
        together and their figures pooled (with ``requests``: also each request's)."""
        out = [_play(v, label or lab, act, seed + k * 100_003, f)
               for k, (v, lab, f) in enumerate(zip(self.venvs, self.labels, self.features,
                                                   strict=True))]
        figs = [o[2] for o in out]
        errs = [f.pop("_err") for f in figs]
        if len(figs) == 1 and self.features[0] is None:   # the env's own tolerance
            return out[0][0], out[0][1], figs[0]
        n = sum(f["episodes"] for f in figs)
        fig = {"episodes": n, "firings": sum(f["firings"] for f in figs),
               "success_rate": sum(f["success_rate"] * f["episodes"] for f in figs) / n,
               "median_abs_error_m": float(np.median(np.concatenate(errs))),
               "detach_rate": sum(f["detach_rate"] * f["episodes"] for f in figs) / n}
        if any("labels_corrected" in f for f in figs):
            fig["labels_corrected"] = sum(f.get("labels_corrected", 0) for f in figs)
        if self.features[0] is not None:
            fig["per_request"] = [{"tolerance_m": float(v.config.tolerance),
                                   **{k: f[k] for k in ("episodes", "success_rate",
                                                        "median_abs_error_m", "detach_rate")}}
                                  for v, f in zip(self.venvs, figs, strict=True)]
        return (np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out]), fig)


def _requests(s: DaggerSettings, cfg: Any) -> tuple[_Requests, list[dict[str, Any]]]:
    """The envs and experts of a run (:class:`_Requests`) and the experts' descriptions."""
    from ..rl.artefacts.policy_files import request_feature

    single = dataclasses.replace(cfg, num_threads=1)
    if s.requests is None:
        label, meta = make_expert(s, cfg)
        return _Requests([vector_class(s.env_id)(s.episodes, config=single)], [label],
                         [None]), [meta]
    k = len(s.requests)
    counts = [s.episodes // k + (i < s.episodes % k) for i in range(k)]
    venvs, labels, metas = [], [], []
    for t, n in zip(s.requests, counts, strict=True):
        sk = s if s.request_slack is None else dataclasses.replace(
            s, slack_m=min(s.slack_m, s.request_slack * t))
        label, meta = make_expert(sk, dataclasses.replace(cfg, tolerance=t))
        venvs.append(vector_class(s.env_id)(n, config=dataclasses.replace(single, tolerance=t)))
        labels.append(label)
        metas.append({"tolerance_m": t, **meta})
    return _Requests(venvs, labels, [request_feature(t) for t in s.requests]), metas


def _keep_best(s: DaggerSettings, envs: Any, student: Student, fits: list[list[Any]],
               rounds: list[dict]) -> dict[str, Any]:
    """Put the best of the rounds' fits into ``student`` (``keep="best"``, :class:`DaggerSettings`)
    and return which: fit ``r`` is scored by round ``r + 1``'s episodes, the last fit by one
    more round without labels."""
    import torch

    def nothing(obs: np.ndarray, venv: Any, live: np.ndarray) -> Labels:
        return (np.zeros((len(obs), len(venv.conveyor.components)), np.float32),
                np.zeros(len(obs), bool), None)

    if not isinstance(envs, _Requests):   # one batched env, the env's own tolerance
        envs = _Requests([envs], [nothing], [None])
    _, _, last = envs.play(student.act, s.seed * 1_000_003 + s.rounds * s.episodes, nothing)
    scores = [*(f for f in rounds[1:]), last]
    best = max(range(len(fits)), key=lambda r: (scores[r]["success_rate"],
                                                -scores[r]["median_abs_error_m"], r))
    with torch.no_grad():
        for p, v in zip(student.params, fits[best], strict=True):
            p.copy_(v)
    return {"round": best, "success_rate": scores[best]["success_rate"],
            "median_abs_error_m": scores[best]["median_abs_error_m"],
            "episodes": scores[best]["episodes"],
            "last_fit_success_rate": last["success_rate"]}


def dagger(out: str | Path, s: DaggerSettings | None = None, progress: Any = print,
           command: str | None = None) -> dict:
    """Train by DAgger (module docstring) into the new policy folder ``out``; returns its
    metadata. ``progress(line)`` is told each round's figures; ``command``: the command line
    that ran it (recorded in the metadata). ``out`` is checked and held before any work (an
    empty name, an existing non-empty folder, a file, a symbolic link, an unwritable place or
    another writer of it: one ValueError) and written at the end at once
    (:class:`agents.rl.artefacts.folders.NewPolicyFolder`)."""
    from ..rl.artefacts.folders import NewPolicyFolder

    with NewPolicyFolder(out) as folder:
        student, meta = _train(s or DaggerSettings(), progress, command)
        student.save(folder, meta)
    return meta


def _train(s: DaggerSettings, progress: Any, command: str | None) -> tuple[Student, dict]:
    """The DAgger rounds of :func:`dagger`: the fitted student and the folder's metadata."""
    import torch

    cfg = s.config()
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    envs, expert_metas = _requests(s, cfg)
    venv = envs.venvs[0]
    expert_meta = expert_metas[0] if s.requests is None else {
        **{k: v for k, v in expert_metas[0].items() if k not in ("tolerance_m", "slack_m")},
        "slack_m": {str(m["tolerance_m"]): m["slack_m"] for m in expert_metas}}
    student = Student(s, cfg)
    X = np.zeros((0, venv.conveyor.obs_dim + (s.requests is not None)), np.float32)
    Y = np.zeros((0, len(venv.conveyor.components)), np.float32)
    rounds, steps = [], 0
    within = (f"±{cfg.tolerance * 1e6:.0f} µm" if s.requests is None else
              "each request (" + "/".join(f"{t * 1e6:g}" for t in s.requests) + " µm)")
    fits: list[list[Any]] = []   # each round's fitted parameters (keep="best")
    for r in range(s.rounds):
        xr, yr, fig = envs.play(None if r == 0 else student.act,
                                s.seed * 1_000_003 + r * s.episodes)
        steps += fig["firings"]
        X, Y = np.concatenate([X, xr]), np.concatenate([Y, yr])
        if r == 0:
            if not len(X):
                raise ValueError("the expert allowed no firing from any state of round 0 (every "
                                 "candidate refused: a margin of as many cells as the "
                                 f"{s.frequencies} x {s.strokes} grid spans?); give a finer "
                                 "grid or a smaller margin")
            student.set_stats(X)   # the observation statistics of the expert's own states
        loss = student.fit(X, Y)
        if s.keep == "best":
            fits.append([p.detach().clone() for p in student.params])
        fig.update(round=r, acting="expert" if r == 0 else "policy", samples=int(len(X)),
                   loss=loss, wall_time_s=time.perf_counter() - t0)
        rounds.append(fig)
        progress(f"round {r} ({fig['acting']} acting): {fig['success_rate']:.0%} within "
                 f"{within}, median {fig['median_abs_error_m'] * 1e6:.1f} µm, "
                 f"detached {fig['detach_rate']:.0%}; {len(X):,} samples, fit RMS "
                 f"{np.sqrt(loss):.4f} action units, "
                 f"{fig['wall_time_s']:.0f} s")
    kept = None
    if s.keep == "best":
        kept = _keep_best(s, envs, student, fits, rounds)
        progress(f"kept the fit of round {kept['round']}: {kept['success_rate']:.0%} within "
                 f"{within}, median "
                 f"{kept['median_abs_error_m'] * 1e6:.1f} µm on the episodes it played")
    wall = time.perf_counter() - t0
    env_kwargs = {k: list(v) if isinstance(v, tuple) else v for k, v in s.env_kwargs.items()}
    # portable inference: an episode of many firings amplifies torch's CPU-specific float32
    # rounding into other trajectories, so the policy is evaluated with the same bits everywhere
    meta: dict[str, Any] = {"format": 2, "env_id": s.env_id, "algo": "ppo", "trained_by": "dagger",
            "inference": "portable",
            "env_kwargs": env_kwargs, "seed": s.seed, "steps": int(steps),
            "wall_time_s": wall, "hyperparams": {**dataclasses.asdict(s), "env_kwargs":
                                                  env_kwargs},
            "expert": expert_meta, "kept_fit": kept,
            "command": command, "rounds": rounds, "machine": {"cpu_count": os.cpu_count(),
                                          "processor": platform.processor()},
            "note": "A policy network trained by DAgger to imitate a model-based expert on the "
                    "nominal model (it never sees an episode's friction, mass or noise), in "
                    "the scene of env_id with env_kwargs; one forward pass per firing."}
    if s.requests is not None:
        from ..rl.artefacts.policy_files import REQUEST_REFERENCE_M

        meta["request"] = {"tolerance_m": [min(s.requests), max(s.requests)],
                           "feature": "log_ratio", "reference_m": REQUEST_REFERENCE_M}
        meta["hyperparams"]["requests"] = list(s.requests)
        meta["note"] += (" Request-conditioned: it reads the requested tolerance (the env's "
                         "tolerance) as one more input, within request.tolerance_m.")
    return student, meta
