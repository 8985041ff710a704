"""Model-predictive control (MPC) with the simulator as the model.

Before every firing the controller observes the part (position, velocity, simulated time, how
many actuators have fired: :class:`~microconveyor_env.envs.PartState`), searches the remaining
firings on the **nominal** model from that state (DE or CMA-ES, :func:`..openloop.target.
solve_target` with ``start=``), fires the first of them on the real part, and repeats. The real
part may differ from the model (friction, mass, execution noise: the env's per-episode
randomisation); each re-plan starts from where the part really is, so errors of earlier firings
are corrected by later ones. The last firing can only be planned, not corrected.

Budgets are in episodes of the model: ``first_budget`` for the plan before the first firing,
``replan_budget`` for each later one. A re-plan is warm-started from the remainder of the
previous plan (DE: one member of the start population; CMA-ES: the start mean), so with an exact
model it keeps that plan unless it finds a better one. Everything is seeded: an MPC episode is
deterministic given its seeds (``tests/agents/test_mpc.py``).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, PartState
from microconveyor_env.envs.versions import nominal

from ..openloop.search import METHODS, check_budget, minimize
from ..openloop.target import MISS, Rollouts, solve_target


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


Transition = tuple[PartState, np.ndarray, PartState]  # observed before, commanded, observed after
ID_GRID = 9          # identification: candidates per factor and pass
ID_PASSES = 2        # a coarse grid over the prior range, then a finer one around its best
ID_SCALES = (10e-6, 1e-3)  # m, m/s: position and velocity residuals are counted in these units
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
        self._id_env: Any = None
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

    def identify(self, history: list[Transition]) -> tuple[float, float]:
        """The (friction, mass) factors [-] under which the model best reproduces the observed
        firings of ``history``: least squares of the position and velocity residuals after each
        firing (in units of :data:`ID_SCALES`) over a grid of the prior range, refined once."""
        from microconveyor_env.envs import MicroConveyorVectorEnv

        r = self.settings.factor_range
        g = ID_GRID
        if self._id_env is None:
            cfg = dataclasses.replace(self.rollouts.config, action_noise=0.0)
            self._id_env = MicroConveyorVectorEnv(g * g, config=cfg)
        env = self._id_env
        lo_f = lo_m = 1.0 - r
        span = 2.0 * r
        best = self.factors
        for _ in range(ID_PASSES):
            ff, mf = (np.array(m).ravel() for m in np.meshgrid(
                np.linspace(lo_f, lo_f + span, g), np.linspace(lo_m, lo_m + span, g),
                indexing="ij"))
            cost = np.zeros(g * g)
            for before, action, after in history:
                starts = [dataclasses.replace(before, friction_factor=float(a),
                                              mass_factor=float(b))
                          for a, b in zip(ff, mf, strict=True)]
                env.reset(seed=0, options={"state": starts})
                env.step(np.repeat(action[None].astype(np.float32), g * g, axis=0))
                cost += ((env.x - after.position_m) / ID_SCALES[0]) ** 2
                cost += ((env.v - after.velocity_m_s) / ID_SCALES[1]) ** 2
            i = int(np.argmin(cost))
            best = (float(ff[i]), float(mf[i]))
            step = span / (g - 1)
            span = 2.0 * step  # the next pass: +-1 cell around the best, finer
            lo_f = min(max(best[0] - step, 1.0 - r), 1.0 + r - span)
            lo_m = min(max(best[1] - step, 1.0 - r), 1.0 + r - span)
        return best

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
                if s.identify:
                    self.factors = self.identify(history)
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


def _episodes(config: EnvConfig, model: EnvConfig | None, settings: MPCSettings | None,
              targets: np.ndarray, seeds: np.ndarray, index: np.ndarray,
              prior: str | None = None) -> list[MPCEpisode]:
    """Episodes ``index`` (global numbers, for the search seeds) of :func:`mpc_rollout`."""
    policy = None
    if prior is not None:
        from ..rl.artefacts.policy_files import load_policy

        policy = load_policy(prior)
    ctl = MPC(model or nominal(config), settings, policy)
    env = MicroConveyorEnv(config=config)
    return [ctl.run(env, float(tg), int(sd), search_seed=ctl.settings.seed + 1000 * int(i))
            for tg, sd, i in zip(targets, seeds, index, strict=True)]


def _episodes_task(task: tuple[Any, ...]) -> list[MPCEpisode]:
    """:func:`_episodes` of one task tuple (a supervised worker's function)."""
    return _episodes(*task)


def _lost_episodes(task: tuple[Any, ...], why: str) -> list[MPCEpisode]:
    """The episodes of a batch whose worker died twice: failed, error NaN, no compute."""
    targets = task[3]
    return [MPCEpisode(float(t), float("nan"), "worker_died", False, float("nan"), 0, 0, 0.0)
            for t in targets]


class MPCRollout:
    """A rollout function ``(config, targets, seed) -> dict`` as :mod:`agents.experiments.perturb`
    runs them: episode ``i`` is the single env of ``config`` seeded ``seed + i`` (the same episode
    as sub-env ``i`` of the batched env), controlled by an :class:`MPC` planning on ``model``
    (default: ``config`` with randomisation off), its searches seeded ``settings.seed + 1000 i``.
    ``workers`` [-] processes share the targets (started once, on the first call, with
    ``spawn``: numba's thread pool does not survive a fork; the results do not depend on the
    number of workers; a worker ends when this process does, however it ends); :meth:`close`
    (or ``with``) stops them. The dict also holds the compute
    per target: ``episodes`` (of the model) and ``wall_time_s`` (planning)."""

    def __init__(self, settings: MPCSettings | None = None, model: EnvConfig | None = None,
                 workers: int = 1, prior: str | None = None) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers = {workers!r} is invalid: must be an integer >= 1")
        self.settings, self.model, self.workers = settings, model, workers
        self.prior = None if prior is None else str(prior)
        self._pool: Any = None
        self.worker_deaths = 0   # pools broken by a dead worker so far

    def __call__(self, config: EnvConfig, targets: np.ndarray, seed: int) -> dict:
        tg = np.asarray(targets, float)
        index = np.arange(tg.size)
        seeds = seed + index
        k = min(self.workers, tg.size)
        if k <= 1:
            eps = _episodes(config, self.model, self.settings, tg, seeds, index, self.prior)
        else:
            if self._pool is None:
                import multiprocessing as mp
                from concurrent.futures import ProcessPoolExecutor

                from ..rl.training.parallel import exit_with_parent

                # a worker ends with its parent (killed or not), instead of waiting for tasks
                self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                                 initializer=exit_with_parent)
            parts = np.array_split(index, k)
            tasks = [(config, self.model, self.settings, tg[p], seeds[p], p, self.prior)
                     for p in parts]
            eps = [e for batch in self._run_batches(tasks) for e in batch]
        out: dict[str, Any] = {
            "targets_m": tg,
            "error_m": np.array([e.error_m for e in eps]),
            "outcome": np.array([e.outcome for e in eps], dtype=object),
            "time_s": np.array([e.time_s for e in eps]),
            "firings": np.array([e.firings for e in eps]),
            "episodes": np.array([e.episodes for e in eps]),
            "wall_time_s": np.array([e.wall_time_s for e in eps])}
        if config.randomised:  # what the env drew for episode i (seed + i), as rollout() reports
            out["friction_factor"] = np.array([e.friction_factor for e in eps])
            out["mass_factor"] = np.array([e.mass_factor for e in eps])
        return out

    def _run_batches(self, tasks: list[tuple[Any, ...]]) -> list[list[MPCEpisode]]:
        """Each batch of episodes on the pool. When a worker dies, the pool is broken for every
        batch not yet finished: those batches run again, each in a supervised process of its
        own (:func:`..rl.parallel.run_local`), and a batch whose process dies again counts as
        failed episodes (outcome ``"worker_died"``, error NaN) while the others stand."""
        from concurrent.futures.process import BrokenProcessPool

        done: list[list[MPCEpisode] | None] = [None] * len(tasks)
        try:   # a worker that died between calls breaks the pool at submit already
            futures = [self._pool.submit(_episodes, *t) for t in tasks]
        except BrokenProcessPool:
            futures = []
        for i, f in enumerate(futures):
            try:
                done[i] = f.result()
            except BrokenProcessPool:
                pass
        redo = [i for i, batch in enumerate(done) if batch is None]
        if redo:
            from ..rl.training.parallel import Died, run_local

            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None   # started again at the next call
            self.worker_deaths += 1
            again = run_local(_episodes_task, [tasks[i] for i in redo], self.workers,
                              died=lambda task, err: Died(_lost_episodes(task, str(err))))
            for i, batch in zip(redo, again, strict=True):
                done[i] = batch
        return [batch or [] for batch in done]

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> MPCRollout:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def mpc_rollout(settings: MPCSettings | None = None, model: EnvConfig | None = None,
                workers: int = 1, prior: str | None = None) -> MPCRollout:
    """:class:`MPCRollout` (``settings``, ``model``, ``workers``; ``prior``: a policy folder
    whose plan on the model seeds every search, loaded in each worker as data)."""
    return MPCRollout(settings, model, workers, prior)
