"""Open-loop plans on any scene planners serve: search one target's plan, replay plans.

A *plan* is the env's own action for each firing, in order: a ``(K, 3)`` array in [-1, 1]. On
the line (MicroConveyor-v0, -v1) it fires each actuator in turn (frequency, stroke, delay;
``K = n_actuators``, or the actuators left from a saved state); on the positioner
(MicroPositioner-v0) it fires ``K`` times whichever actuator its aim picks from where the part
rests (aim, frequency, stroke; ``K``: :data:`~agents.planning.scene.PLAN_FIRINGS` unless
told). It is played without looking at the part, and scored by the env itself (final position,
outcome, ``is_success``) on the scene's batched env (:meth:`agents.planning.Scene.rollouts`), a
whole batch of plans per call.

* :func:`solve_target` searches the plan for one target (DE or CMA-ES, :mod:`.search`) with a
  budget of episodes: cost :func:`agents.planning.cost.plan_cost` (|final error| [m] for a part
  at rest, ``MISS + min(|error|, MISS)`` otherwise: detached, out of time), or with a
  ``time_weight`` the dissertation's time-weighted cost
  :func:`agents.planning.cost.time_weighted_cost` (placement time against precision, the
  config's tolerance as the precision asked for).
* :func:`replay` plays a fixed line plan (or a batch of plans) in any env config, e.g. a
  perturbed one; :func:`plans_rollout` replays fixed plans, one per target, as a rollout
  function (:mod:`agents.experiments.perturb`).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, PartState

from ..planning import PositionerScene, Replay, Rollouts, plan_cost, scene_of
from ..planning.cost import time_weighted_cost
from .search import METHODS, TARGET_BUDGET, SearchResult, minimize


def replay(plan: np.ndarray, target_m: float, config: EnvConfig | None = None,
           copies: int = 1, seed: int = 0) -> Replay:
    """Play one plan ``(n_actuators, 3)`` (or a batch ``(B, n_actuators, 3)``) towards
    ``target_m`` [m] in ``config`` (default: the env's defaults). ``copies`` [-] repeats a single
    plan; copy ``i`` is reset with seed ``seed + i``, so a config with per-episode
    randomisation gives each copy its own episode."""
    plans = np.asarray(plan, dtype=float)
    if plans.ndim == 2:
        plans = np.repeat(plans[None], int(copies), axis=0)
    roll = scene_of(config or EnvConfig.from_yaml()).rollouts()
    return roll.run(plans, target_m, seed=seed, same_episode=False)


@dataclass
class TargetResult:
    """The best open-loop plan found for one target (SI units; see :func:`solve_target`).

    ``plan``: ``(K, 3)`` actions in [-1, 1] (float32 values, exactly as played);
    ``firings``: the same in SI units (:meth:`agents.planning.Scene.decode_plan`);
    ``error_m``: signed final x - target [m];
    ``sim_time_s``: the placement time on the model [s] (until the part rests, or the episode
    ends); ``time_weight``: the cost's A [1/s] (None: precision only);
    ``history_episodes`` / ``history_best_abs_error_m``: after each generation, the episodes
    used so far and the |error| [m] of the best plan so far if it rests (None: none at rest
    yet; with precision only it is the best |error| so far)."""

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
    time_weight: float | None = None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["plan"] = self.plan.tolist()
        return d


def solve_target(target_m: float, method: str = "de", budget: int = TARGET_BUDGET, seed: int = 0,
                 config: Any = None, rollouts: Rollouts | None = None,
                 episode_seed: int = 0, start: PartState | None = None,
                 firings: int | None = None, time_weight: float | None = None,
                 **search_kw: Any) -> TargetResult:
    """Search the open-loop plan that brings the part to rest closest to ``target_m`` [m,
    measured from actuator 1] within ``budget`` episodes (used <= budget: see :mod:`.search`).

    ``method``: ``"de"`` (scipy differential evolution) or ``"cmaes"`` (pycma); ``seed`` [-]
    makes the run deterministic; ``config``: the scene's config (default: MicroConveyor-v0's
    defaults; ignored when ``rollouts`` is given, whose config is used and whose envs are
    reused); ``search_kw``: passed to the minimiser (e.g. ``popsize``). Every candidate plays
    the episode of seed ``episode_seed`` [-] (:meth:`~agents.planning.Rollouts.run`,
    ``same_episode``): with the env's per-episode randomisation on (docs/randomisation.md) that
    is one draw of the factors and of the action noise, the same for all candidates (the
    positioner's plans are searched on its nominal model only). ``firings``: the plan's firings
    (:meth:`~agents.planning.Scene.plan_firings`: on the line every actuator left; on the
    positioner :data:`~agents.planning.scene.PLAN_FIRINGS` unless told). ``start``: plan only
    the remaining firings of a line's episode from this part state (model-predictive control,
    :mod:`agents.mpc`); the target is then the state's.

    ``time_weight`` A [1/s] (None: precision only): minimise the dissertation's time-weighted
    cost (:func:`agents.planning.cost.time_weighted_cost`) instead, ``A T_f + |e / T_d|^10``
    for a part that rests after ``T_f`` [s] with error ``e``, ``T_d`` the config's
    ``tolerance`` (the precision asked for: inside it time decides, outside it precision
    does), and a penalty for a part that does not rest. The dissertation's A is
    :data:`agents.planning.cost.TIME_WEIGHT` (1e3 1/s: 1 ms weighs as much as an error of
    T_d)."""
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is invalid: must be one of {METHODS}")
    roll = rollouts or scene_of(config or EnvConfig.from_yaml()).rollouts()
    cfg = roll.config
    scene = scene_of(cfg)
    if isinstance(scene, PositionerScene) and cfg.randomised:
        raise ValueError("plans are searched on the nominal model: give a config with "
                         "randomisation off")
    if time_weight is not None and not (isinstance(time_weight, (int, float))
                                        and 0.0 <= time_weight < np.inf):
        raise ValueError(f"time_weight = {time_weight!r} is invalid: must be a number >= 0 "
                         "[1/s], or None (precision only)")
    n = scene.plan_firings(start, firings)
    target = float(target_m if start is None else start.target_m)
    # the error of a part that never moves: where the episode starts
    start_error = -target - cfg.start_offset if start is None else start.position_m - target
    best: dict[str, Any] = {"cost": np.inf}
    hist: list[float | None] = []

    def cost(X: np.ndarray) -> np.ndarray:
        plans = X.reshape(-1, n, 3).astype(np.float32).astype(float)
        r = roll.run(plans, target, seed=episode_seed, start=start)
        if time_weight is None:
            c = plan_cost(r.abs_error_m, r.rest)
        else:
            c = time_weighted_cost(r.error_m, r.time_s, r.rest, float(time_weight),
                                   cfg.tolerance, start_error)
        i = int(np.argmin(c))
        if c[i] < best["cost"] or "plan" not in best:  # the same rule as search._Counter
            best.update(cost=float(c[i]), plan=plans[i], error=float(r.error_m[i]),
                        outcome=str(r.outcome[i]), success=bool(r.success[i]),
                        time=float(r.time_s[i]))
        hist.append(abs(best["error"]) if best["outcome"] == "rest" else None)
        return c

    t0 = time.perf_counter()
    res: SearchResult = minimize(method, cost, [(-1.0, 1.0)] * (3 * n), int(budget), int(seed),
                                 **search_kw)
    plan = best["plan"].reshape(n, 3)
    return TargetResult(
        target_m=target, method=method, seed=int(seed), budget=int(budget),
        episodes=res.episodes, plan=plan, firings=scene.decode_plan(plan),
        final_position_m=target + best["error"], error_m=best["error"],
        abs_error_m=abs(best["error"]), outcome=best["outcome"], success=best["success"],
        sim_time_s=best["time"], wall_time_s=time.perf_counter() - t0,
        tolerance_m=cfg.tolerance, history_episodes=res.history_episodes,
        history_best_abs_error_m=hist, time_weight=None if time_weight is None
        else float(time_weight))


def plans_rollout(plans: np.ndarray) -> Any:
    """Open loop as a rollout function ``(config, targets, seed) -> dict``: ``plans``
    ``(n_targets, K, 3)``, plan ``i`` replayed unchanged towards target ``i`` in sub-env ``i``
    seeded ``seed + i`` (with the config's randomisation: the perturbation under test)."""
    plans = np.asarray(plans, float)

    def run(config: Any, targets: np.ndarray, seed: int) -> dict:
        tg = np.asarray(targets, float)
        if plans.shape[0] != tg.size:
            raise ValueError(f"{plans.shape[0]} plans for {tg.size} targets")
        roll = scene_of(config).rollouts()
        r = roll.run(plans, tg, [int(seed) + i for i in range(tg.size)])
        out: dict[str, Any] = {"targets_m": tg, "error_m": r.error_m, "outcome": r.outcome,
                               "success": r.success, "time_s": r.time_s}
        if config.randomised:
            out.update(roll.factors)
        return out

    return run


def plan_trajectory(plan: np.ndarray, target_m: float,
                    config: EnvConfig | None = None) -> dict[str, np.ndarray]:
    """The recorded run of one plan ``(n_actuators, 3)`` on the env's model (the same numbers the
    env plays, from ``-start_offset``: without ``start_jitter``): ``t_s`` [s], ``x_m`` [m],
    ``v_m_s`` [m/s]. ``target_m`` [m] is unused by the physics and only checked, so a
    trajectory always belongs to a well-posed episode."""
    from microconveyor_env.envs.rail.parts import check_target, make_simulator
    from microconveyor_env.physics.schedule import ActuatorArray, Schedule

    cfg = config or EnvConfig.from_yaml()
    check_target(target_m)
    fir = scene_of(cfg).decode_plan(plan)
    sched = Schedule.sequence(ActuatorArray(cfg.actuator_positions), fir["frequency_hz"],
                              fir["stroke_m"], fir["delay_s"])
    r = make_simulator(cfg).simulate(sched, -cfg.start_offset, record=True)
    assert r.trajectory is not None
    return {k: r.trajectory[k] for k in ("t_s", "x_m", "v_m_s")}
