"""Open-loop plans for MicroConveyor-v0: solve one target, replay a plan.

A *plan* is the env's own action for every firing, in order: an ``(n_actuators, 3)`` array in
[-1, 1] (frequency, stroke, delay; decoded as the env decodes them, :mod:`microconveyor_env.envs.core.actions`).
It is played without looking at the part, and scored by the env itself (final position, outcome,
``is_success``) on :class:`~microconveyor_env.envs.MicroConveyorVectorEnv`, a whole batch of
plans per call.

* :func:`solve_target` searches the plan for one target (DE or CMA-ES, :mod:`.search`) with a
  budget of episodes: cost = |final error| [m] for a part at rest, ``MISS + min(|error|, MISS)``
  otherwise (detached, out of time).
* :func:`replay` plays a fixed plan (or a batch of plans) in any env config, e.g. a perturbed one.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from collections.abc import Sequence
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorVectorEnv, PartState
from microconveyor_env.envs.core.actions import constants as action_constants, decode
from microconveyor_env.envs.core.episodes import PlanActor, run_episodes

from .search import TARGET_BUDGET, SearchResult, minimize

MISS = 1.0  # m: base cost of an episode that does not end at rest (detached, max_time, ...)


@dataclass
class Replay:
    """Per-episode outcomes of a batch of plans (arrays over the batch, SI units):
    ``error_m`` signed final x - target [m], ``outcome`` (``rest``, ``detached``, ``max_time``,
    ``too_many_events``), ``success`` (at rest within the config's tolerance), ``time_s`` the
    simulated time at the end [s]."""

    target_m: np.ndarray
    error_m: np.ndarray
    outcome: np.ndarray
    success: np.ndarray
    time_s: np.ndarray

    @property
    def abs_error_m(self) -> np.ndarray:
        return np.abs(self.error_m)

    @property
    def rest(self) -> np.ndarray:
        return self.outcome == "rest"

    @property
    def final_position_m(self) -> np.ndarray:
        return self.target_m + self.error_m


class Rollouts:
    """Batched open-loop episodes of whole plans on one :class:`EnvConfig` (envs cached by batch
    size); ``episodes`` counts every episode played."""

    def __init__(self, config: EnvConfig | None = None) -> None:
        self.config: EnvConfig = config or EnvConfig.from_yaml()
        self._envs: dict[int, MicroConveyorVectorEnv] = {}
        self.episodes = 0

    def run(self, plans: np.ndarray, target: float | np.ndarray, seed: int | Sequence[int] = 0,
            same_episode: bool = True, start: PartState | None = None) -> Replay:
        """Play ``plans`` ``(B, n_actuators, 3)`` towards ``target`` [m] (scalar or per plan).
        Resets with ``seed`` [-]: ``same_episode`` gives every plan the episode of that seed
        (the same start, the same randomisation: common random numbers for a fair comparison);
        otherwise plan ``i`` gets seed ``seed + i`` (independent episodes, as for replays under
        perturbation); a sequence gives plan ``i`` seed ``seed[i]``. ``start``: every episode
        starts from this part state instead (its target
        is the one played; ``target`` is ignored) and the plans hold the remaining firings,
        ``(B, n_actuators - start.fired, 3)``."""
        plans = np.asarray(plans, dtype=float)
        n = self.config.n_actuators - (0 if start is None else start.fired)
        if plans.ndim != 3 or plans.shape[1:] != (n, 3):
            raise ValueError(f"plans must have shape (batch, {n}, 3), got {plans.shape}")
        b = plans.shape[0]
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = MicroConveyorVectorEnv(b, config=self.config,
                                                         autoreset_mode="SameStep")
        if not isinstance(seed, (int, np.integer)):
            seeds = [int(x) for x in seed]
            if len(seeds) != b:
                raise ValueError(f"{len(seeds)} seeds for {b} plans")
        else:
            seeds = [int(seed)] * b if same_episode else [int(seed) + i for i in range(b)]
        if start is None:
            targets = np.broadcast_to(np.asarray(target, float), (b,)).copy()
        else:
            targets = np.full(b, float(start.target_m))
        ep = run_episodes(env, PlanActor(plans), seeds,
                          {"target": target} if start is None else {"state": start}, max_steps=n)
        self.episodes += b
        f = ep.final
        outcome = np.where(ep.ended, f["outcome"], "moving").astype(object)
        return Replay(targets, f["position_error_m"], outcome, f["is_success"], f["sim_time_s"])


def replay(plan: np.ndarray, target_m: float, config: EnvConfig | None = None,
           copies: int = 1, seed: int = 0) -> Replay:
    """Play one plan ``(n_actuators, 3)`` (or a batch ``(B, n_actuators, 3)``) towards
    ``target_m`` [m] in ``config`` (default: the env's defaults). ``copies`` [-] repeats a single
    plan; copy ``i`` is reset with seed ``seed + i``, so a config with per-episode
    randomisation gives each copy its own episode."""
    plans = np.asarray(plan, dtype=float)
    if plans.ndim == 2:
        plans = np.repeat(plans[None], int(copies), axis=0)
    return Rollouts(config).run(plans, target_m, seed=seed, same_episode=False)


def decode_plan(plan: np.ndarray, config: EnvConfig) -> dict[str, list[float]]:
    """The plan's firings in SI units: ``frequency_hz``, ``stroke_m``, ``delay_s`` (lists)."""
    AC = action_constants(config)
    rows = [decode(float(a[0]), float(a[1]), float(a[2]), AC) for a in np.asarray(plan, float)]
    return {"frequency_hz": [r[0] for r in rows], "stroke_m": [r[1] for r in rows],
            "delay_s": [r[2] for r in rows]}


@dataclass
class TargetResult:
    """The best open-loop plan found for one target (SI units; see :func:`solve_target`).

    ``plan``: ``(n_actuators, 3)`` actions in [-1, 1] (float32 values, exactly as played);
    ``firings``: the same in SI units; ``error_m``: signed final x - target [m];
    ``history_episodes`` / ``history_best_abs_error_m``: after each generation, the episodes
    used so far and the best |error| [m] of a part at rest so far (None: none at rest yet)."""

    target_m: float
    method: str
    seed: int
    budget: int
    episodes: int
    plan: np.ndarray
    firings: dict[str, list[float]]
    final_position_m: float
    error_m: float
    abs_error_m: float
    outcome: str
    success: bool
    sim_time_s: float
    wall_time_s: float
    tolerance_m: float
    history_episodes: list[int] = field(default_factory=list)
    history_best_abs_error_m: list[float | None] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["plan"] = self.plan.tolist()
        return d


def solve_target(target_m: float, method: str = "de", budget: int = TARGET_BUDGET, seed: int = 0,
                 config: EnvConfig | None = None, rollouts: Rollouts | None = None,
                 episode_seed: int = 0, start: PartState | None = None,
                 **search_kw: Any) -> TargetResult:
    """Search the open-loop plan that brings the part to rest closest to ``target_m`` [m,
    measured from actuator 1] within ``budget`` episodes (used <= budget: see :mod:`.search`).

    ``method``: ``"de"`` (scipy differential evolution) or ``"cmaes"`` (pycma); ``seed`` [-]
    makes the run deterministic; ``config``: the env config (default: the env's defaults;
    ignored when ``rollouts`` is given, whose config is used and whose envs are reused);
    ``search_kw``: passed to the minimiser (e.g. ``popsize``). Every candidate plays the
    episode of seed ``episode_seed`` [-] (:meth:`Rollouts.run`, ``same_episode``): with the env's
    per-episode randomisation on (docs/randomisation.md) that is one draw of the factors and of
    the action noise, the same for all candidates. ``start``: plan only the remaining firings
    of an episode from this part state (:meth:`Rollouts.run`; model-predictive control,
    :mod:`agents.mpc`); the plan then has ``n_actuators - start.fired`` rows and the target is
    the state's."""
    roll = rollouts or Rollouts(config)
    cfg = roll.config
    n = cfg.n_actuators - (0 if start is None else start.fired)
    target = float(target_m if start is None else start.target_m)
    best: dict[str, Any] = {"cost": np.inf}

    def cost(X: np.ndarray) -> np.ndarray:
        plans = X.reshape(-1, n, 3).astype(np.float32).astype(float)
        r = roll.run(plans, target, seed=episode_seed, start=start)
        err = r.abs_error_m
        c = np.where(r.rest, err, MISS + np.minimum(np.nan_to_num(err, nan=MISS), MISS))
        i = int(np.argmin(c))
        if c[i] < best["cost"] or "plan" not in best:  # the same rule as search._Counter
            best.update(cost=float(c[i]), plan=plans[i], error=float(r.error_m[i]),
                        outcome=str(r.outcome[i]), success=bool(r.success[i]),
                        time=float(r.time_s[i]))
        return c

    t0 = time.perf_counter()
    res: SearchResult = minimize(method, cost, [(-1.0, 1.0)] * (3 * n), budget, seed,
                                 **search_kw)
    hist = [c if c < MISS else None for c in res.history_best_cost]
    return TargetResult(
        target_m=target, method=method, seed=int(seed), budget=int(budget),
        episodes=res.episodes, plan=best["plan"].reshape(n, 3),
        firings=decode_plan(best["plan"].reshape(n, 3), cfg),
        final_position_m=target + best["error"], error_m=best["error"],
        abs_error_m=abs(best["error"]), outcome=best["outcome"], success=best["success"],
        sim_time_s=best["time"], wall_time_s=time.perf_counter() - t0,
        tolerance_m=cfg.tolerance, history_episodes=res.history_episodes,
        history_best_abs_error_m=hist)


def plan_trajectory(plan: np.ndarray, target_m: float,
                    config: EnvConfig | None = None) -> dict[str, np.ndarray]:
    """The recorded run of one plan ``(n_actuators, 3)`` on the env's model (the same numbers the
    env plays, from ``-start_offset``: without ``start_jitter``): ``t_s`` [s], ``x_m`` [m],
    ``v_m_s`` [m/s]. ``target_m`` [m] is unused by the physics and only checked, so a
    trajectory always belongs to a well-posed episode."""
    from microconveyor_env.envs.line.common import check_target, make_simulator
    from microconveyor_env.physics.schedule import ActuatorArray, Schedule

    cfg = config or EnvConfig.from_yaml()
    check_target(target_m)
    fir = decode_plan(plan, cfg)
    sched = Schedule.sequence(ActuatorArray(cfg.actuator_positions), fir["frequency_hz"],
                              fir["stroke_m"], fir["delay_s"])
    r = make_simulator(cfg).simulate(sched, -cfg.start_offset, record=True)
    assert r.trajectory is not None
    return {k: r.trajectory[k] for k in ("t_s", "x_m", "v_m_s")}
