"""Model-predictive control (MPC) of one episode, with the simulator as the model.

Before every firing the controller observes the part (position, velocity, simulated time, how
many actuators have fired: :class:`~microconveyor_env.envs.PartState`), searches the remaining
firings on the **nominal** model from that state (DE or CMA-ES, :func:`..openloop.target.
solve_target` with ``start=``), fires the first of them on the real part, and repeats: a
receding horizon that ends with the episode. The real part may differ from the model (friction,
mass, execution noise: the env's per-episode randomisation); each re-plan starts from where the
part really is, so errors of earlier firings are corrected by later ones. The last firing can only
be planned, not corrected.

Budgets are in episodes of the model: ``first_budget`` for the plan before the first firing,
``replan_budget`` for each later one. A re-plan is warm-started from the remainder of the
previous plan (DE: one member of the start population; CMA-ES: the start mean), so with an exact
model it keeps that plan unless it finds a better one. A prior policy's plan on the model may
seed every search; robust plans are scored over noisy copies; the model's friction and mass
factors may be identified from the firings seen (:mod:`.identification`). Everything is seeded:
an MPC episode is deterministic given its seeds. Many episodes on worker processes:
:mod:`.harness`.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, PartState

from ..openloop.search import METHODS, check_budget, minimize
from ..openloop.target import MISS, Rollouts, solve_target
from .identification import Identifier, Transition


@dataclass(frozen=True)
class MPCSettings:
    """``method`` (``"de"`` or ``"cmaes"``); ``first_budget`` / ``replan_budget`` [episodes of
    the model] for the first plan and each re-plan; ``seed`` [-] of the searches (re-plan ``k``
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
        if self.method not in METHODS:
            raise ValueError(f"MPC method = {self.method!r} is invalid: must be one of {METHODS}")
        k = self.noise_copies
        if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= 1000:
            raise ValueError(f"MPC noise_copies = {k!r} is invalid: must be an integer in "
                             "[1, 1000]")
        check_budget(self.first_budget, 5 * k)
        check_budget(self.replan_budget, 5 * k)
        if not (isinstance(self.assumed_noise, (int, float)) and 0.0 <= self.assumed_noise <= 1.0):
            raise ValueError(f"MPC assumed_noise = {self.assumed_noise!r} is invalid: must be a "
                             "sigma in [0, 1] action units")
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


def observed(state: PartState) -> PartState:
    """What the controller sees of a part: its kinematic state, never the episode's hidden
    randomisation (friction and mass factors, noise)."""
    return PartState(state.position_m, state.velocity_m_s, state.time_s, state.fired,
                     state.target_m)


TIE_BREAK = 0.1      # robust cost: weight of the smooth term beyond the cap (agents.experiments.reach)


class MPC:
    """The controller: plans on ``model`` (an :class:`EnvConfig`, randomisation off: the nominal
    model) with ``settings``. :meth:`run` controls one episode of a real env."""

    def __init__(self, model: EnvConfig, settings: MPCSettings | None = None,
                 prior: Any = None) -> None:
        if model.randomised:
            raise ValueError("the MPC's model must be nominal (randomisation off); perturb the "
                             "real env instead")
        self.model = model
        self.settings = s = settings or MPCSettings()
        # the planning model: nominal, or (identify / robust) the same scene whose factors a
        # start state may set and whose copies draw execution noise of the assumed sigma
        r = s.factor_range
        planning = dataclasses.replace(
            model, action_noise=float(s.assumed_noise),
            friction_factor_range=(1.0 - r, 1.0 + r) if s.identify else (1.0, 1.0),
            mass_factor_range=(1.0 - r, 1.0 + r) if s.identify else (1.0, 1.0))
        self.rollouts = Rollouts(planning)
        self.prior = prior  # a policy (act(obs) -> actions) whose plan seeds every search
        self._prior_env: MicroConveyorEnv | None = None
        self.identifier = Identifier(planning, r) if s.identify else None
        self.factors: tuple[float, float] = (1.0, 1.0)  # friction, mass: the current estimate

    def plan(self, state: PartState, budget: int, seed: int,
             warm: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """The best remaining plan ``(n_actuators - fired, 3)`` from ``state`` within ``budget``
        model episodes, and the episodes used."""
        s = self.settings
        kw: dict[str, Any] = {}
        if s.identify:
            state = dataclasses.replace(state, friction_factor=self.factors[0],
                                        mass_factor=self.factors[1])
        used = 0
        if self.prior is not None:  # the policy's plan on the model, if it beats the warm start
            prior = self.prior_plan(state)
            warm, used = self._better(state, warm, prior)
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
            e = np.where(r.rest, np.nan_to_num(r.abs_error_m, nan=MISS), MISS)
            c = np.minimum(e, 10 * tol) + TIE_BREAK * tol * np.log1p(e / tol)
            return c.reshape(-1, k).mean(axis=1)

        res = minimize(self.settings.method, cost, [(-1.0, 1.0)] * (3 * n), budget // k, seed,
                       **kw)
        return res.x.reshape(n, 3).astype(np.float32).astype(float), res.episodes * k

    def run(self, env: MicroConveyorEnv, target_m: float, seed: int,
            search_seed: int | None = None) -> MPCEpisode:
        """Control one episode of ``env`` (reset with ``seed`` towards ``target_m`` [m]); the
        searches are seeded from ``search_seed`` (default: the settings' seed)."""
        s = self.settings
        base = s.seed if search_seed is None else int(search_seed)
        env.reset(seed=int(seed), options={"target": float(target_m)})
        ff, mf = env.friction_factor, env.mass_factor
        self.factors = (1.0, 1.0)
        history: list[Transition] = []
        plan: np.ndarray | None = None
        episodes, wall, k = 0, 0.0, 0
        fired: dict[str, list[float]] = {"frequency_hz": [], "stroke_m": [], "delay_s": []}
        while True:
            state = observed(env.get_state())
            t0 = time.perf_counter()
            if history:
                history[-1] = (history[-1][0], history[-1][1], state)
                if self.identifier is not None:
                    self.factors = self.identifier.fit(history)
            warm = plan[1:] if (plan is not None and s.warm_start) else None
            plan, used = self.plan(state, s.first_budget if k == 0 else s.replan_budget,
                                   base + k, warm)
            wall += time.perf_counter() - t0
            episodes += used
            action = plan[0].astype(np.float32)
            history.append((state, action.astype(float), state))
            _, _, term, trunc, info = env.step(action)
            for key in fired:
                fired[key].append(float(info[key]))
            k += 1
            if term or trunc:
                break
        return MPCEpisode(
            target_m=float(target_m), error_m=float(info["position_error_m"]),
            outcome=str(info["outcome"]), success=bool(info["is_success"]),
            time_s=float(info["sim_time_s"]), firings=k, episodes=episodes, wall_time_s=wall,
            friction_factor=ff, mass_factor=mf, estimated_factors=self.factors,
            frequency_hz=fired["frequency_hz"], stroke_m=fired["stroke_m"],
            delay_s=fired["delay_s"])
