"""What one run of the comparison (:func:`.compare.compare`) does: :class:`CompareSettings`, a frozen
settings object validated once when it is made, its defaults, and the env ids it runs on.

The comparison runs on the conveyor line's scene versions (``MicroConveyor-v0``,
``MicroConveyor-v1``): its open-loop methods search a plan of the line's firings per target and
its MPC re-plans them from the line's part state; and on the positioner (``MicroPositioner-v0``,
:mod:`.compare`): plans of a few firings and the one-step model-based controller.
:func:`check_env_id` refuses the other registered ids with the reason (the plane; the
goal-conditioned interface of a line version).
"""
from __future__ import annotations

import numbers
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from microconveyor_env.env_ids import DEFAULT_ENV_ID, REGISTRY
from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.core.randomisation import FACTOR_BOUNDS, MAX_ACTION_NOISE
from microconveyor_env.envs.core.versions import config_class

from ..mpc import MPCSettings
from ..mpc.control import MODELS as POSITIONER_MODELS
from ..openloop.search import METHODS
from .perturb import DIAGONAL, NOISE_LADDER, SPREAD_LADDER

# the MPC of the default comparison: episodes of the model before the first firing and per
# re-plan, small enough for the default `compare` to stay under 5 minutes on 2 cores (the stored
# run, docs/agents.md, uses 1000 and 300: `--mpc-budgets 1000,300`)
MPC_SETTINGS = MPCSettings(first_budget=300, replan_budget=100)
# the robust, adaptive MPC (CompareSettings(robust_mpc=...), `compare --robust-mpc`): each
# candidate scored over 8 copies under the goal level's noise sigma = 3e-3, friction and mass
# identified within +-10 % from the firings seen (agents.mpc); ~5x the nominal MPC's compute
ROBUST_MPC_SETTINGS = MPCSettings(first_budget=4000, replan_budget=2000, noise_copies=8,
                                  assumed_noise=3e-3, identify=True, factor_range=0.1)
MIN_BUDGET = 10      # episodes: the smallest open-loop budget per target
MAX_SPREAD = 1.0 - FACTOR_BOUNDS[0]   # r [-]: friction and mass factors stay in the env's bounds


GEOMETRIES = ("line", "positioner")   # the scenes the comparison has runners for


def check_env_id(env_id: str) -> str:
    """``env_id`` if the comparison runs on it (a scene version of the conveyor line, or the
    positioner); otherwise ValueError saying why not, in one sentence."""
    runs = [i for i, r in REGISTRY.items() if r.geometry in GEOMETRIES and r.base == i]
    reg = REGISTRY.get(env_id)
    if reg is None:
        raise ValueError(f"env id {env_id!r} is not registered: compare runs on "
                         f"{', '.join(runs)}")
    if reg.geometry not in GEOMETRIES:
        raise ValueError(f"compare runs on the conveyor line and the positioner "
                         f"({', '.join(runs)}): its DE and CMA-ES plans per target and its "
                         f"model-based controllers search those scenes' firings on their "
                         f"models, and none is defined for {env_id} (the {reg.geometry}); "
                         f"evaluate a policy there with `microconveyor evaluate --env {env_id}`")
    if reg.base != env_id:
        raise ValueError(f"{env_id} is {reg.base}'s scene with a goal-conditioned (Dict) "
                         f"observation, and compare's methods act on the scene, not on an "
                         f"observation: run compare with --env {reg.base}")
    return env_id


def _count(name: str, value: Any, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least:
        raise ValueError(f"{name} = {value!r} is invalid: must be an integer >= {least}")
    return int(value)


def _levels(name: str, values: Sequence[Any], most: float) -> tuple[float, ...]:
    out = tuple(float(v) for v in values)
    if not all(0.0 <= v <= most for v in out):   # NaN fails too
        raise ValueError(f"{name} = {list(values)!r} is invalid: every level must be in "
                         f"[0, {most:g}]")
    return out


def _path(value: str | Path | None) -> str | None:
    return None if value is None else os.fspath(value)


@dataclass(frozen=True)
class CompareSettings:
    """Every choice of one comparison, checked when made (ValueError naming the field).

    The scene: ``env_id`` (a line version, :func:`check_env_id`) and ``config``, its
    :class:`EnvConfig` with overrides (None: ``env_id``'s defaults; the policies must have been
    trained on its scene). The targets: ``n_targets`` [-] fixed targets drawn with ``seed`` [-]
    from the config's target range (``seed`` also seeds every search and episode).

    The methods: the open-loop ``methods`` (``"de"``, ``"cmaes"``), each at every budget of
    ``budgets`` [episodes per target, >= 10]; ``policy``, the closed-loop policy's folder (None:
    ``env_id``'s default shipped policy, :func:`agents.rl.artefacts.shipped.default_policy_name`:
    ``ppo_refined`` on MicroConveyor-v1; its row is named after its folder,
    :func:`.compare_rows.policy_row_name`); ``randomised_policy``, the PPO trained under
    randomisation (None: ``env_id``'s shipped ``ppo_randomised`` if there is one; ``""``: none); ``policy_seeds``,
    folders of PPO trained with other seeds on the same recipe (their IQM, nominal and
    perturbed); ``amortise_over`` [targets], over which PPO's training is amortised; ``mpc``,
    the MPC's settings (None: no MPC), ``robust_mpc`` a second, robust MPC's (e.g.
    :data:`ROBUST_MPC_SETTINGS`; None: none), both run by ``mpc_workers`` [-] processes (the
    results do not depend on them); ``mpc_prior``, a policy folder whose plan on the model seeds
    the searches (adds the method ``mpc_<its folder's name>``, e.g. ``mpc_ppo_refined``, with
    ``mpc``'s settings and seeds ``mpc_robust``).

    On the positioner: ``policy`` (None: its default shipped
    policy, ``dagger``, if there is one, else no policy row; ``""``: none); ``mpc_models``, the one-step controller's
    models, one row each (``"identified"``, ``"nominal"``, and ``"oracle"``, the reference that
    knows each episode's hidden factors: :class:`agents.mpc.OneStepSettings`); ``plan_firings`` [-],
    the firings of each open-loop plan. ``mpc``, ``robust_mpc``, ``mpc_prior``,
    ``mpc_workers``, ``randomised_policy`` and ``policy_seeds`` are the line's.

    The perturbation axes (:func:`.perturb.perturbation_levels`): ``noise_ladder``, execution
    noise σ [action units, <= 1]; ``spread_ladder``, model error r [-] (friction and mass factors
    uniform in [1 − r, 1 + r], r <= :data:`MAX_SPREAD`); ``diagonal``, (σ, r) pairs of both together;
    ``full_grid``: also every (σ, r) of the two ladders; each level replayed
    ``perturb_repeats`` [-] times per target. ``progress``: progress lines and bars on stderr.

    Sequences are kept as tuples, paths as strings."""

    env_id: str = DEFAULT_ENV_ID
    config: EnvConfig | None = None
    n_targets: int = field(default=100, metadata={
        "help": "number of fixed targets (drawn with --seed from the default range; default "
                "{default})", "flag": "--targets", "bounds": (1, 10_000)})
    seed: int = field(default=0, metadata={
        "help": "seed of the targets, the searches and the episodes (default {default})"})
    methods: Sequence[str] = field(default=("de", "cmaes"), metadata={
        "help": "open-loop methods: de, cmaes or both"})
    budgets: Sequence[int] = field(default=(1000,), metadata={
        "help": "episodes per target for DE and CMA-ES (comma list; default {default})"})
    policy: str | Path | None = None
    randomised_policy: str | Path | None = None
    policy_seeds: Sequence[str | Path] = field(default=(), metadata={
        "help": "policy folders of PPO trained with other seeds: their IQM and 95 % bootstrap "
                "interval, nominal and perturbed", "nargs": "+", "metavar": "DIR"})
    amortise_over: int = field(default=100, metadata={
        "help": "targets over which PPO's training is amortised in the chart",
        "bounds": (1, None)})
    mpc: MPCSettings | None = MPC_SETTINGS
    robust_mpc: MPCSettings | None = None
    mpc_prior: str | Path | None = None
    mpc_workers: int = field(default=2, metadata={
        "help": "processes for the MPC's episodes (results do not depend on it)",
        "flag": "--workers", "bounds": (1, 64)})
    noise_ladder: Sequence[float] = field(default=NOISE_LADDER, metadata={
        "help": "execution-noise axis σ [action units] (comma list)", "flag": "--noise"})
    spread_ladder: Sequence[float] = field(default=SPREAD_LADDER, metadata={
        "help": "model-error axis r [-]: friction and mass factors in [1-r, 1+r]",
        "flag": "--spread"})
    diagonal: Sequence[tuple[float, float]] = field(default=DIAGONAL, metadata={
        "help": "noise and model error together (default {default})", "metavar": "SIGMA:R,..."})
    full_grid: bool = field(default=False, metadata={
        "help": "also every (σ, r) combination of the two axes (the full grid; ~20 levels: long)",
        "flag": ("--full", "--full-grid")})
    perturb_repeats: int = field(default=1, metadata={
        "help": "perturbed replays per target and level", "flag": "--repeats",
        "bounds": (1, 1000)})
    progress: bool = True
    mpc_models: Sequence[str] = field(default=("identified", "nominal", "oracle"), metadata={
        "help": "positioner: the one-step model-based controller's models, one row each (comma "
                "list of identified, nominal, oracle; default all three; oracle knows each "
                "episode's hidden friction and mass: a reference row)", "metavar": "MODELS"})
    plan_firings: int = field(default=5, metadata={
        "help": "positioner: firings of each open-loop DE / CMA-ES plan", "bounds": (1, 24)})

    def __post_init__(self) -> None:
        check_env_id(self.env_id)
        if self.config is not None and not isinstance(self.config, config_class(self.env_id)):
            raise ValueError(f"config must be a {config_class(self.env_id).__name__} of "
                             f"{self.env_id}, got {type(self.config).__name__}")
        _count("n_targets", self.n_targets, 1)
        _count("seed", self.seed, 0)
        methods = tuple(self.methods)
        if not methods or not set(methods) <= set(METHODS) or len(set(methods)) < len(methods):
            raise ValueError(f"methods = {list(methods)!r} is invalid: one or more of "
                             f"{', '.join(METHODS)}, each once")
        budgets = tuple(_count("a budget", b, MIN_BUDGET) for b in self.budgets)
        if not budgets:
            raise ValueError("budgets is empty: give at least one budget [episodes per target]")
        _count("amortise_over", self.amortise_over, 1)
        _count("mpc_workers", self.mpc_workers, 1)
        _count("perturb_repeats", self.perturb_repeats, 1)
        _count("plan_firings", self.plan_firings, 1)
        models = tuple(self.mpc_models)
        if not set(models) <= set(POSITIONER_MODELS) or len(set(models)) < len(models):
            raise ValueError(f"mpc_models = {list(models)!r} is invalid: any of "
                             f"{', '.join(POSITIONER_MODELS)}, each once")
        for name in ("mpc", "robust_mpc"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, MPCSettings):
                raise ValueError(f"{name} must be MPCSettings or None, got "
                                 f"{type(value).__name__}")
        diagonal = tuple((float(a), float(b)) for a, b in self.diagonal)
        _levels("diagonal (sigma)", [a for a, _ in diagonal], MAX_ACTION_NOISE)
        _levels("diagonal (r)", [b for _, b in diagonal], MAX_SPREAD)
        for name in ("full_grid", "progress"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        normalised = {
            "methods": methods, "budgets": budgets, "diagonal": diagonal, "mpc_models": models,
            "noise_ladder": _levels("noise_ladder", self.noise_ladder, MAX_ACTION_NOISE),
            "spread_ladder": _levels("spread_ladder", self.spread_ladder, MAX_SPREAD),
            "policy": _path(self.policy), "randomised_policy": _path(self.randomised_policy),
            "mpc_prior": _path(self.mpc_prior),
            "policy_seeds": tuple(os.fspath(p) for p in self.policy_seeds)}
        for name, value in normalised.items():
            object.__setattr__(self, name, value)
