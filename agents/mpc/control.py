"""Model-predictive control of one episode on any scene planners serve, with the simulator as
the model: before every firing, observe the part (:meth:`agents.planning.Scene.observed`),
update the model's friction and mass factors from the firings seen (optional), plan on the model
from that state, fire the plan's first firing on the real part, and repeat until the episode
ends (or, on the positioner, until no firing is predicted to bring the part closer: it then rests
where it is, outcome ``rest``). The loop is :class:`MPC`; what plans is chosen by the settings:

* :class:`MPCSettings`, the line's receding horizon (:class:`HorizonPlanner`): the remaining
  firings searched on the **nominal** model from the observed state (DE or CMA-ES,
  :func:`..openloop.target.solve_target` with ``start=``). The real part may differ from the
  model (friction, mass, execution noise: the env's per-episode randomisation); each re-plan
  starts from where the part really is, so errors of earlier firings are corrected by later
  ones; the last firing can only be planned, not corrected. Budgets are in episodes of the
  model: ``first_budget`` for the plan before the first firing, ``replan_budget`` for each later
  one. A re-plan is warm-started from the remainder of the previous plan (DE: one member of the
  start population; CMA-ES: the start mean), so with an exact model it keeps that plan unless it
  finds a better one. A prior policy's plan on the model may seed every search; robust plans
  are scored over noisy copies (:func:`agents.planning.robust_cost`); the factors may be
  identified from the firings seen (:class:`.identification.Identifier`).
* :class:`OneStepSettings`, the positioner's one-step controller (:class:`OneStepPlanner`):
  its firings each run the part to rest, so a one-step search is a whole plan. From the
  observed state it fires a grid of candidate firings on the model
  (:meth:`agents.planning.PositionerScene.candidates`: every actuator the aim can pick, aimed
  at exactly, ``frequencies`` × ``strokes`` across the action ranges). A candidate whose model
  part detaches (or runs out of time) is refused, and so are its ``margin`` neighbours in
  frequency and stroke: a margin from detachment for the execution noise; the nearest few are
  fired again with the model's friction and mass ``check_factor`` higher and lower, and one that
  detaches there is passed over: a margin for the model's error (the mass sets detachment on
  its own). Of the rest, the one whose predicted rest is nearest the target fires. Its model
  (``model=``): ``"nominal"``; ``"identified"``, the effective friction factor fitted online
  (:class:`.identification.FrictionFit`); ``"oracle"``, the episode's true factors read from the
  env: a reference for the others, never a method.

It acts only through the env's API: ``reset``, ``step`` and the saved state without its hidden
factors and noise. Everything is seeded: an episode is deterministic given its seeds. Many
episodes on worker processes: :mod:`.harness`.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, PartState

from ..openloop.newton import newton_plan
from ..openloop.search import METHODS, check_budget, minimize
from ..openloop.target import solve_target
from ..planning import MISS, PositionerScene, Scene, robust_cost, scene_of
from ..planning.rest_expert import MIN_GAIN   # a step below this does not bring a part closer [m]
from .identification import FrictionFit, Identifier


# the line's re-planners: a black-box search (DE, CMA-ES), or minimum-norm Gauss-Newton on the
# remaining plan from the prior's (or the previous) plan
PLANNERS = (*METHODS, "newton")
NEWTON_ACCEPT = 0.04   # [-] the newton MPC stops once the plan rests this share of the tolerance
                       # from the target (2 µm of v1's 50 µm)


@dataclass(frozen=True)
class MPCSettings:
    """``method``: ``"de"`` or ``"cmaes"`` (a black-box search over the remaining firings), or
    ``"newton"`` (the remaining plan of the prior policy, or of the previous plan, moved by
    minimum-norm Gauss-Newton on the model until the part rests on the target:
    :func:`agents.openloop.newton.newton_plan`; needs a prior); ``first_budget`` /
    ``replan_budget`` [episodes of the model] for the first plan and each re-plan; ``seed`` [-] of the searches (re-plan ``k``
    of target ``i`` uses ``seed + 1000 i + k``); ``warm_start``: start each re-plan from the
    previous plan's remainder.

    Robustness (both off by default): ``noise_copies`` K [-] and ``assumed_noise`` σ [action
    units]: each candidate plan is scored by the mean of its capped error over K copies
    executed with noise σ (the same K draws for every candidate of a search: common random
    numbers), so the search prefers plans that hold under noise (a budget buys budget / K
    candidates); ``identify``: before each re-plan, estimate this episode's friction and mass
    factors from the firings seen so far (the commanded action and the observed states before
    and after each), over factors in [1 − ``factor_range``, 1 + ``factor_range``], and plan on
    the model with those factors."""

    method: str = "de"
    first_budget: int = 1000
    replan_budget: int = 300
    seed: int = 0
    warm_start: bool = True
    noise_copies: int = 1
    assumed_noise: float = 0.0
    identify: bool = False
    factor_range: float = 0.1

    def __post_init__(self) -> None:
        if self.method not in PLANNERS:
            raise ValueError(f"MPC method = {self.method!r} is invalid: must be one of "
                             f"{PLANNERS}")
        k = self.noise_copies
        if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= 1000:
            raise ValueError(f"MPC noise_copies = {k!r} is invalid: must be an integer in "
                             "[1, 1000]")
        check_budget(self.first_budget, 5 * k)
        check_budget(self.replan_budget, 5 * k)
        if not (isinstance(self.assumed_noise, (int, float)) and 0.0 <= self.assumed_noise <= 1.0):
            raise ValueError(f"MPC assumed_noise = {self.assumed_noise!r} is invalid: must be a "
                             "sigma in [0, 1] action units")
        if self.method == "newton" and k > 1:
            raise ValueError("the newton MPC plans on the nominal copy: noise_copies must be 1")
        if (k > 1) != (self.assumed_noise > 0):
            raise ValueError("MPC noise_copies > 1 and assumed_noise > 0 go together (a robust "
                             "plan averages its cost over noisy copies)")
        if not (isinstance(self.factor_range, (int, float)) and 0.0 < self.factor_range <= 0.9):
            raise ValueError(f"MPC factor_range = {self.factor_range!r} is invalid: must be in "
                             "(0, 0.9]")

    @property
    def robust(self) -> bool:
        """Plans are scored over noisy copies (:attr:`noise_copies` draws of
        :attr:`assumed_noise`)."""
        return self.noise_copies > 1


MODELS = ("nominal", "identified", "oracle")   # the one-step controller's models
SEARCHES = ("map", "model")
CORNER_CHUNK = 4   # candidates whose four corners are fired at once, nearest first   # where the one-step controller ranks its candidates


@dataclass(frozen=True)
class OneStepSettings:
    """``model``: ``"nominal"``, ``"identified"`` or ``"oracle"`` (module docstring: the one-step controller);
    ``frequencies``, ``strokes`` [-]: candidate values evenly spaced over the frequency and
    stroke actions' range [-1, 1] (the env maps them log-uniformly onto its frequency range and
    linearly onto its stroke range); ``margin`` [-]: grid cells in frequency and stroke around a
    candidate whose model part detaches that are refused too; ``factor_range`` R [-] and
    ``factor_points`` [-]: the identified friction factor's grid over [1 − R, 1 + R];
    ``prior_width`` [-]: the fit's prior standard deviation of that factor around 1;
    ``residual_m`` [m]: the rest residual that weighs as much as one prior width;
    ``check_factor`` δ [-] and ``check_best`` [-]: the nearest ``check_best`` candidates are
    fired again with the model's friction and mass factors times 1 ± δ (four corners), and one
    that detaches under any is passed over (0: no check), a margin for the model's error.
    ``search``: ``"map"`` ranks the candidates on the scene's firing map (the nominal model
    tabulated once; a candidate in a cell the map does not trust counts as one that detaches)
    and fires only the ``check_best`` nearest on the full model with the model's factors, twice
    (:meth:`OneStepPlanner.choose`); ``"model"`` fires every candidate on the full model."""

    model: str = "identified"
    frequencies: int = 41
    strokes: int = 6
    margin: int = 1
    factor_range: float = 0.3
    factor_points: int = 61
    prior_width: float = 0.1
    residual_m: float = 2e-6
    check_factor: float = 0.1
    check_best: int = 16
    search: str = "map"

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"model = {self.model!r} is invalid: must be one of {MODELS}")
        if self.search not in SEARCHES:
            raise ValueError(f"search = {self.search!r} is invalid: must be one of {SEARCHES}")
        for name, least in (("frequencies", 2), ("strokes", 2), ("margin", 0),
                            ("factor_points", 3), ("check_best", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} = {v!r} is invalid: must be an integer >= {least}")
        for name in ("factor_range", "check_factor"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 0.9) or (
                    name == "factor_range" and v == 0.0):
                raise ValueError(f"{name} = {v!r} is invalid: must be in "
                                 f"{'(0' if name == 'factor_range' else '[0'}, 0.9]")
        for name in ("prior_width", "residual_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 < v < math.inf):
                raise ValueError(f"{name} = {v!r} is invalid: must be a positive number")


@dataclass
class MPCEpisode:
    """One controlled episode (SI units): the outcome as the env reports it, the firings as
    fired (execution noise included), and the compute: model ``episodes`` searched and
    ``wall_time_s`` [s] of planning."""

    target_m: float
    error_m: float
    outcome: str
    success: bool
    time_s: float
    firings: int
    episodes: int
    wall_time_s: float
    friction_factor: float = 1.0
    mass_factor: float = 1.0
    estimated_factors: tuple[float, float] = (1.0, 1.0)
    frequency_hz: list[float] = field(default_factory=list)
    stroke_m: list[float] = field(default_factory=list)
    delay_s: list[float] = field(default_factory=list)


class HorizonPlanner:
    """The line's receding horizon (module docstring): plans the remaining firings on ``model``
    (an :class:`EnvConfig`, randomisation off) with ``settings``, seeded by ``prior`` (a policy,
    ``act(obs) -> actions``) if given. :meth:`next` fires the first of its plan."""

    def __init__(self, model: EnvConfig, settings: MPCSettings, prior: Any = None) -> None:
        if model.randomised:
            raise ValueError("the MPC's model must be nominal (randomisation off); perturb the "
                             "real env instead")
        self.model = model
        self.settings = s = settings
        # the planning model: nominal, or (identify / robust) the same scene whose factors a
        # start state may set and whose copies draw execution noise of the assumed sigma
        r = s.factor_range
        self.planning = dataclasses.replace(
            model, action_noise=float(s.assumed_noise),
            friction_factor_range=(1.0 - r, 1.0 + r) if s.identify else (1.0, 1.0),
            mass_factor_range=(1.0 - r, 1.0 + r) if s.identify else (1.0, 1.0))
        self.rollouts = scene_of(self.planning).rollouts()
        self.prior = prior
        self._prior_env: MicroConveyorEnv | None = None
        self.spent = 0   # model episodes searched
        self._last: np.ndarray | None = None

    def identifier(self) -> Identifier | None:
        """The fit of the factors the settings ask for (None: plan on the nominal factors)."""
        s = self.settings
        return Identifier(self.planning, s.factor_range) if s.identify else None

    def reset(self) -> None:
        """A new episode: no plan to warm-start from."""
        self._last = None

    def next(self, state: PartState, k: int, seed: int,
             factors: tuple[float, float]) -> np.ndarray:
        """The firing to fire now (float32 ``(3,)``): the first of the plan from ``state``
        (the ``k``-th re-plan, its search seeded ``seed``) on the model with ``factors``."""
        s = self.settings
        warm = self._last[1:] if (self._last is not None and s.warm_start) else None
        plan, used = self.plan(state, s.first_budget if k == 0 else s.replan_budget, seed,
                               warm, factors)
        self.spent += used
        self._last = plan
        return plan[0].astype(np.float32)

    def plan(self, state: PartState, budget: int, seed: int, warm: np.ndarray | None = None,
             factors: tuple[float, float] = (1.0, 1.0)) -> tuple[np.ndarray, int]:
        """The best remaining plan ``(n_actuators - fired, 3)`` from ``state`` within ``budget``
        model episodes, and the episodes used."""
        s = self.settings
        kw: dict[str, Any] = {}
        if s.identify:
            state = dataclasses.replace(state, friction_factor=factors[0],
                                        mass_factor=factors[1])
        used = 0
        if self.prior is not None:  # the policy's plan on the model, if it beats the warm start
            prior = self.prior_plan(state)
            warm, used = self._better(state, warm, prior)
        if s.method == "newton":
            if warm is None or not len(warm):
                raise ValueError("the newton MPC re-plans from a plan: give it a prior policy")
            n = len(warm)
            plan, eps = newton_plan(self.rollouts, np.clip(np.asarray(warm, float), -1.0, 1.0),
                                    state.target_m, max(1, (budget - used) // (3 * n + 2)),
                                    accept_m=NEWTON_ACCEPT * self.model.tolerance, start=state)
            return plan, eps + used
        if warm is not None and len(warm):
            kw["x0"] = np.clip(np.asarray(warm, float).ravel(), -1.0, 1.0)
        if not s.robust:
            r = solve_target(state.target_m, s.method, budget - used, seed,
                             rollouts=self.rollouts, start=state, **kw)
            return r.plan, r.episodes + used
        plan, eps = self._robust_plan(state, budget - used, seed, kw)
        return plan, eps + used

    def prior_plan(self, state: PartState) -> np.ndarray:
        """The remaining firings the prior policy fires from ``state`` on the model (closed loop,
        without noise); firings it never reaches (the part delivered first) repeat its last."""
        if self._prior_env is None:
            cfg = dataclasses.replace(self.rollouts.config, action_noise=0.0)
            self._prior_env = MicroConveyorEnv(config=cfg)
        env = self._prior_env
        obs, _ = env.reset(seed=0, options={"state": state})
        acts: list[np.ndarray] = []
        n = self.model.n_actuators - state.fired
        while len(acts) < n:
            a = np.clip(np.asarray(self.prior.act(obs[None]), float).reshape(-1, 3)[0], -1, 1)
            acts.append(a)
            obs, _, term, trunc, _ = env.step(a.astype(np.float32))
            if term or trunc:
                break
        acts += [acts[-1]] * (n - len(acts))
        return np.array(acts)

    def _better(self, state: PartState, warm: np.ndarray | None,
                prior: np.ndarray) -> tuple[np.ndarray, int]:
        """Of the warm start and the prior's plan, the one closer to the target on the model
        (one episode each, the same draw), and the episodes spent."""
        if warm is None or not len(warm):
            return prior, 0
        plans = np.stack([np.asarray(warm, float), prior]).astype(np.float32).astype(float)
        r = self.rollouts.run(plans, state.target_m, seed=0, start=state)
        c = np.where(r.rest, np.nan_to_num(r.abs_error_m, nan=MISS), MISS)
        return plans[int(np.argmin(c))], 2

    def _robust_plan(self, state: PartState, budget: int, seed: int,
                     kw: dict[str, Any]) -> tuple[np.ndarray, int]:
        k = self.settings.noise_copies
        n = self.model.n_actuators - state.fired
        tol = self.model.tolerance
        copies = (np.random.default_rng(seed).integers(0, 2**31 - 1, k)).tolist()

        def cost(X: np.ndarray) -> np.ndarray:
            plans = np.repeat(X.reshape(-1, n, 3).astype(np.float32).astype(float), k, axis=0)
            r = self.rollouts.run(plans, state.target_m, seed=copies * (len(plans) // k),
                                  start=state)
            return robust_cost(r.abs_error_m, r.rest, tol).reshape(-1, k).mean(axis=1)

        res = minimize(self.settings.method, cost, [(-1.0, 1.0)] * (3 * n), budget // k, seed,
                       **kw)
        return res.x.reshape(n, 3).astype(np.float32).astype(float), res.episodes * k


def dilate(bad: np.ndarray, margin: int) -> np.ndarray:
    """``bad`` (..., F, H) grown by ``margin`` cells along F and H."""
    out = bad.copy()
    for _ in range(margin):
        grown = out.copy()
        grown[..., 1:, :] |= out[..., :-1, :]
        grown[..., :-1, :] |= out[..., 1:, :]
        grown[..., 1:] |= out[..., :-1]
        grown[..., :-1] |= out[..., 1:]
        out = grown
    return out


def with_factors(state: Any, friction: float, mass: float = 1.0) -> Any:
    """``state`` on a model part with these friction and mass factors [-]."""
    return dataclasses.replace(state, friction_factor=float(friction), mass_factor=float(mass))


class OneStepPlanner:
    """The positioner's one-step controller (module docstring) on ``scene`` with ``settings``:
    :meth:`predict` fires every candidate on the model, :meth:`choose` picks one."""

    def __init__(self, scene: PositionerScene, settings: OneStepSettings) -> None:
        self.scene = scene
        self.settings = settings
        self.model = scene.firing_model()
        self.map = scene.map_model() if settings.search == "map" else None

    @property
    def spent(self) -> int:
        """Full-model firings so far (the identification's included; the map's queries are
        not firings)."""
        return self.model.firings

    def identifier(self) -> FrictionFit | None:
        return FrictionFit(self.model, self.settings) \
            if self.settings.model == "identified" else None

    def reset(self) -> None:
        pass

    def next(self, state: Any, k: int, seed: int,
             factors: tuple[float, float]) -> np.ndarray | None:
        return self.choose(state, factors)

    def predict(self, state: Any, factors: tuple[float, float] = (1.0, 1.0)
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate from ``state`` (observed): the actions ``(A, F, H, 3)``, the
        predicted rests [m] ``(A, F, H)`` and whether each is allowed (rests, and no neighbour
        within the margin detaches). With ``search="model"`` on the full model with
        ``factors``; with ``"map"`` on the firing map (nominal; untrusted counts as detaching)."""
        s = self.settings
        acts, n_aims = self.scene.candidates(state.position_m, s.frequencies, s.strokes)
        if self.map is not None:
            x, _, ok = self.map.rests(state.position_m, acts)
        else:
            x, ok = self.model.rests(with_factors(state, *factors), acts)
        shape = (n_aims, s.frequencies, s.strokes)
        allowed = ~dilate(~ok.reshape(shape), s.margin)
        return acts.reshape(*shape, 3), x.reshape(shape), allowed

    def _confirm(self, state: Any, flat: np.ndarray, order: np.ndarray,
                 factors: tuple[float, float]) -> np.ndarray:
        """The rests [m] of the candidates ``flat[order]`` on the full model with ``factors``
        (inf where the model part does not come to rest)."""
        x, ok = self.model.rests(with_factors(state, *factors), flat[order])
        return np.where(ok, x, np.inf)

    def ranked(self, state: Any, factors: tuple[float, float] = (1.0, 1.0)
               ) -> tuple[np.ndarray, np.ndarray]:
        """The candidates (actions ``(N, 3)``) nearest the target first, at most ``check_best``
        of them and only those predicted to bring the part closer, and their predicted rests [m]
        on the full model with ``factors`` (for ``search="model"`` all of them).

        On the map (``search="map"``) the ``check_best`` nearest on the map are fired on the
        full model; the map's displacements are then scaled by the median ratio of the full
        model's to the map's over those (the model's factors stretch or shorten every slide
        alike to within a few per cent), the candidates re-ranked, and the ``check_best``
        nearest of that ranking not yet fired are fired too: the answer is always the full
        model's."""
        s = self.settings
        acts, x, allowed = self.predict(state, factors)
        flat = acts.reshape(-1, 3)
        target, now = state.target_m, abs(state.position_m - state.target_m)
        x = np.where(allowed, x, np.inf).ravel()
        order = np.argsort(np.abs(x - target), kind="stable")[:s.check_best]
        order = order[np.isfinite(x[order])]
        if self.map is None:
            order = order[np.abs(x[order] - target) < now - MIN_GAIN]
            return flat[order], x[order]
        if not order.size:
            return flat[:0], x[:0]
        full = self._confirm(state, flat, order, factors)
        step_map, step_full = x[order] - state.position_m, full - state.position_m
        usable = np.isfinite(full) & (np.abs(step_map) > 1e-6)
        if usable.any():
            ratio = float(np.median(step_full[usable] / step_map[usable]))
            scaled = state.position_m + ratio * (x - state.position_m)
            more = np.argsort(np.abs(scaled - target), kind="stable")
            more = more[np.isfinite(scaled[more]) & ~np.isin(more, order)][:s.check_best]
            if more.size:
                order = np.concatenate([order, more])
                full = np.concatenate([full, self._confirm(state, flat, more, factors)])
        by = np.argsort(np.abs(full - target), kind="stable")[:s.check_best]
        by = by[np.abs(full[by] - target) < now - MIN_GAIN]
        return flat[order[by]], full[by]

    def choose(self, state: Any, factors: tuple[float, float] = (1.0, 1.0)) -> np.ndarray | None:
        """The firing (action ``(3,)`` float32) whose predicted rest from ``state`` is nearest
        its target (:meth:`ranked`), or None when no allowed candidate is predicted to bring
        the part closer. With ``check_factor`` δ > 0, the ``check_best`` nearest are fired
        again on the model with its friction and mass factors each times 1 − δ or 1 + δ (the
        four corners), and the nearest that rests under all four is chosen (the nearest of all
        if none does)."""
        s = self.settings
        best, _ = self.ranked(state, factors)
        if not len(best):
            return None
        if s.check_factor > 0.0:
            f, m = factors
            d = s.check_factor
            corners = [(f * a, m * b) for a in (1.0 - d, 1.0 + d) for b in (1.0 - d, 1.0 + d)]
            for lo in range(0, len(best), CORNER_CHUNK):   # in order: the first that holds
                few = best[lo:lo + CORNER_CHUNK]
                states = [with_factors(state, a, b) for a, b in corners for _ in few]
                _, ok = self.model.rests(states, np.tile(few, (len(corners), 1)))
                every = ok.reshape(len(corners), len(few)).all(axis=0)
                if every.any():
                    return few[int(np.argmax(every))]
        return best[0]


class MPC:
    """The controller on the scene of ``model`` (:func:`agents.planning.scene_of`; on the line
    a nominal :class:`EnvConfig`, on the positioner its config, whose randomisation the model
    does not use) with ``settings`` (:class:`MPCSettings`: the receding horizon, seeded by the
    policy ``prior`` if given; :class:`OneStepSettings`: the one-step controller; default: the
    scene's). :meth:`run` controls one episode of a real env."""

    def __init__(self, model: Any, settings: MPCSettings | OneStepSettings | None = None,
                 prior: Any = None) -> None:
        self.scene: Scene = scene_of(model)
        self.planner: HorizonPlanner | OneStepPlanner
        if isinstance(self.scene, PositionerScene):
            self.settings = settings or OneStepSettings()
            if not isinstance(self.settings, OneStepSettings):
                raise ValueError("the positioner's controller takes OneStepSettings")
            self.planner = OneStepPlanner(self.scene, self.settings)
        else:
            self.settings = settings or MPCSettings()
            if not isinstance(self.settings, MPCSettings):
                raise ValueError("the line's MPC takes MPCSettings")
            self.planner = HorizonPlanner(model, self.settings, prior)
        self.model = model
        self.identifier = self.planner.identifier()
        self.oracle = getattr(self.settings, "model", None) == "oracle"
        self.seed = int(getattr(self.settings, "seed", 0))
        self.factors: tuple[float, float] = (1.0, 1.0)  # friction, mass: the model's now

    def run(self, env: Any, target_m: float, seed: int,
            search_seed: int | None = None) -> MPCEpisode:
        """Control one episode of ``env`` (reset with ``seed`` towards ``target_m`` [m]); the
        searches are seeded from ``search_seed`` (default: the settings' seed). ``episodes``
        counts the model's episodes (the one-step controller's: its firings)."""
        base = self.seed if search_seed is None else int(search_seed)
        planner, fit = self.planner, self.identifier
        env.reset(seed=int(seed), options={"target": float(target_m)})
        true = (env.friction_factor, env.mass_factor)
        planner.reset()
        if fit is not None:
            fit.reset()
        self.factors = true if self.oracle else (1.0, 1.0)
        start = planner.spent
        wall, k = 0.0, 0
        fired: dict[str, list[float]] = {key: [] for key in self.scene.firing_keys}
        before: Any = None
        action: np.ndarray | None = None
        info: dict[str, Any] = {}
        while True:
            state = self.scene.observed(env.get_state())
            t0 = time.perf_counter()
            if fit is not None and before is not None:
                fit.add((before, np.asarray(action, float), state))
                self.factors = fit.factors()
            action = planner.next(state, k, base + k, self.factors)
            wall += time.perf_counter() - t0
            if action is None:   # nothing brings it closer: it rests where it is
                info = {"position_error_m": state.position_m - state.target_m,
                        "outcome": "rest", "is_success": False, "sim_time_s": state.time_s}
                break
            before = state
            _, _, term, trunc, info = env.step(action)
            for key, values in fired.items():
                values.append(float(info[key]))
            k += 1
            if term or trunc:
                break
        return MPCEpisode(
            target_m=float(target_m), error_m=float(info["position_error_m"]),
            outcome=str(info["outcome"]), success=bool(info["is_success"]),
            time_s=float(info["sim_time_s"]), firings=k, episodes=planner.spent - start,
            wall_time_s=wall, friction_factor=true[0], mass_factor=true[1],
            estimated_factors=self.factors, frequency_hz=fired["frequency_hz"],
            stroke_m=fired["stroke_m"], delay_s=fired.get("delay_s", []))
