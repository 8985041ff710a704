"""Open-loop plans for MicroPositioner-v0: per target, ``K`` firings searched on the nominal
model, then replayed unchanged.

A *plan* is the env's own action for each of ``K`` firings, in order: a ``(K, 3)`` array in
[-1, 1] (aim, frequency, stroke; the env picks the actuator nearest ``x + aim * pick_reach``
from wherever the part rests, so the aim is relative to the part, as every action of this env
is). It is played without looking at the part: firing ``k`` of the plan is the ``k``-th step,
whatever the part did. The episode may end before the plan does (the part rests within the
tolerance, or detaches); a plan played to its end leaves the part at rest, and that rest is its
result (outcome ``rest``, success if within the tolerance).

* :class:`PlanRollouts` plays a batch of plans on a config's batched env (its randomisation
  included: seeded episodes, the same draws as a closed-loop rollout of the same seeds);
* :func:`solve_plan` searches the plan for one target with DE or CMA-ES (:mod:`.search`) on the
  nominal model, cost = |final error| [m] at rest, ``MISS + min(|error|, MISS)`` otherwise
  (detached, out of time: :data:`.target.MISS`);
* :func:`plans_rollout` replays fixed plans, one per target, as a rollout function
  (:mod:`agents.experiments.perturb`).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs.core.episodes import PlanActor, run_episodes
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.envs.versions import nominal

from .search import METHODS, minimize
from .target import MISS, Replay

__all__ = ["PLAN_FIRINGS", "PlanResult", "PlanRollouts", "plans_rollout", "solve_plan"]

PLAN_FIRINGS = 5   # firings of a plan unless told (the closed-loop controller needs ~4)


class PlanRollouts:
    """Batched open-loop episodes of ``(B, K, 3)`` plans on ``config`` (envs cached by batch
    size); ``episodes`` counts every episode played."""

    def __init__(self, config: PositionerConfig) -> None:
        self.config = config
        self._envs: dict[int, MicroPositionerVectorEnv] = {}
        self.episodes = 0
        # with randomisation on: the friction and mass factors of the last run's episodes [-]
        self.factors: dict[str, np.ndarray] = {}

    def run(self, plans: np.ndarray, targets: float | np.ndarray,
            seeds: int | list[int] = 0) -> Replay:
        """Play ``plans`` towards ``targets`` [m] (one, or one per plan), sub-env ``i`` reset
        with ``seeds[i]`` (an int: every plan the episode of that seed). Outcomes as the env
        reports them at the episode's end; a plan played out leaves the part at rest
        (``rest``)."""
        plans = np.asarray(plans, float)
        if plans.ndim != 3 or plans.shape[2] != 3 or plans.shape[1] < 1:
            raise ValueError(f"plans must have shape (batch, firings, 3), got {plans.shape}")
        b, k = plans.shape[:2]
        if k > self.config.max_firings:
            raise ValueError(f"a plan of {k} firings: the env allows {self.config.max_firings}")
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = MicroPositionerVectorEnv(b, config=self.config,
                                                           autoreset_mode="SameStep")
        tg = np.broadcast_to(np.asarray(targets, float), (b,)).copy()
        sd = [int(seeds)] * b if isinstance(seeds, (int, np.integer)) else [int(s) for s in seeds]
        ep = run_episodes(env, PlanActor(plans), sd, {"target": tg}, max_steps=k)
        self.episodes += b
        f = ep.final
        ended = ep.ended
        err = np.where(ended, f["position_error_m"], env.x - env.target)
        outcome = np.where(ended, f["outcome"], "rest").astype(object)
        success = np.where(ended, f["is_success"], np.abs(err) <= self.config.tolerance)
        t = np.where(ended, f["sim_time_s"], env.t)
        if self.config.randomised:   # each episode's draws (an ended one's from its final info)
            self.factors = {k: np.where(ended, f[k], getattr(env, k)).astype(float)
                            for k in ("friction_factor", "mass_factor")}
        return Replay(tg, err.astype(float), outcome, success.astype(bool), t.astype(float))


@dataclass
class PlanResult:
    """The best plan found for one target (SI units): ``plan`` ``(K, 3)`` actions (float32
    values, exactly as played), its result on the model (``error_m`` signed final x − target,
    ``outcome``, ``success``), the search's ``episodes`` and ``wall_time_s`` [s], and after each
    generation the episodes so far and the best |error| [m] at rest so far (None: none yet)."""

    target_m: float
    method: str
    seed: int
    budget: int
    episodes: int
    plan: np.ndarray
    error_m: float
    outcome: str
    success: bool
    sim_time_s: float
    wall_time_s: float
    history_episodes: list[int] = field(default_factory=list)
    history_best_abs_error_m: list[float | None] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["plan"] = self.plan.tolist()
        return d


def solve_plan(target_m: float, method: str, budget: int, seed: int,
               rollouts: PlanRollouts, firings: int = PLAN_FIRINGS,
               **search_kw: Any) -> PlanResult:
    """Search the ``firings``-firing plan that rests the part nearest ``target_m`` [m] on
    ``rollouts``' config (its nominal model: randomisation off) within ``budget`` episodes, with
    ``method`` (``"de"`` or ``"cmaes"``) seeded ``seed``; ``search_kw`` goes to the minimiser."""
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is invalid: must be one of {METHODS}")
    if rollouts.config.randomised:
        raise ValueError("plans are searched on the nominal model: give a config with "
                         "randomisation off")
    best: dict[str, Any] = {"cost": np.inf}

    def cost(X: np.ndarray) -> np.ndarray:
        plans = X.reshape(-1, firings, 3).astype(np.float32).astype(float)
        r = rollouts.run(plans, float(target_m), 0)
        err = r.abs_error_m
        c = np.where(r.rest, err, MISS + np.minimum(np.nan_to_num(err, nan=MISS), MISS))
        i = int(np.argmin(c))
        if c[i] < best["cost"] or "plan" not in best:
            best.update(cost=float(c[i]), plan=plans[i], error=float(r.error_m[i]),
                        outcome=str(r.outcome[i]), success=bool(r.success[i]),
                        time=float(r.time_s[i]))
        return c

    t0 = time.perf_counter()
    res = minimize(method, cost, [(-1.0, 1.0)] * (3 * firings), int(budget), int(seed),
                   **search_kw)
    hist = [c if c < MISS else None for c in res.history_best_cost]
    return PlanResult(float(target_m), method, int(seed), int(budget), res.episodes,
                      best["plan"].reshape(firings, 3), best["error"], best["outcome"],
                      best["success"], best["time"], time.perf_counter() - t0,
                      res.history_episodes, hist)


def plans_rollout(plans: np.ndarray) -> Any:
    """Open loop as a rollout function ``(config, targets, seed) -> dict``: ``plans``
    ``(n_targets, K, 3)``, plan ``i`` replayed unchanged towards target ``i`` in sub-env ``i``
    seeded ``seed + i`` (with the config's randomisation: the perturbation under test)."""
    plans = np.asarray(plans, float)

    def run(config: PositionerConfig, targets: np.ndarray, seed: int) -> dict:
        tg = np.asarray(targets, float)
        if plans.shape[0] != tg.size:
            raise ValueError(f"{plans.shape[0]} plans for {tg.size} targets")
        roll = PlanRollouts(config)
        r = roll.run(plans, tg, [int(seed) + i for i in range(tg.size)])
        out: dict[str, Any] = {"targets_m": tg, "error_m": r.error_m, "outcome": r.outcome,
                               "success": r.success, "time_s": r.time_s}
        if config.randomised:
            out.update(roll.factors)
        return out

    return run


def nominal_rollouts(config: PositionerConfig) -> PlanRollouts:
    """:class:`PlanRollouts` on ``config`` with randomisation off (the model plans are made on)."""
    return PlanRollouts(nominal(config))
