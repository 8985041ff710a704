"""The dissertation's optimisation problem (docs/physics.md §5, its Table 4.3) on this model.

Five actuators fire once each, in order, all with the same four numbers: stroke frequency
``f`` [Hz] (200-10000), actuator spacing ``s`` [m] (500-1500 µm; actuator k at x = k s, the
first at 0), delay ``d`` [s] (0-0.1) and stroke ``h`` [m] (100-200 µm). The delay is the
simulator's (docs/physics.md §1): the still time between the end of one stroke and the start
of the next; the first actuator fires at t = 0 (a delay before it would only add time). The
surface is chapter 4's (preset ``conveyor``, Table 4.2: dgamma = 0.5 J/m^2). The part starts at rest ``config.start_offset`` (0.15 mm) upstream of actuator 1; the target is
10 mm beyond actuator 1.

Cost of a candidate (:func:`dissertation_cost`), with ``e = x_f - x_target``:

* at rest: ``A T_f + |e / T_d|^C``, ``T_f`` the travel time [s] (until the part rests);
* detached (or still moving at ``max_time``): ``P + |(x_0 - x_target) / T_d|^C``: the penalty on
  top of the cost of a part that never moved.

The dissertation gives ``A ≈ 1e3``, "a large C" and ``P = 1e5`` but neither ``T_d`` nor ``C``.
Chosen here: ``A = 1e3`` 1/s (its 0.037 s answer costs 37), ``T_d = 50 µm`` (the tolerance:
the position term is < 1 exactly inside ±50 µm, where travel time decides) and ``C = 10``
(2x the tolerance costs 1024, so outside it position dominates). With these the literal
reading "detached costs P" would rank a detached part *above* one that stays 0.5 mm short
(``(500/50)^10 = 1e10 > 1e5``), so the penalty is added to the cost of not moving at all:
every run that rests nearer the target than its start costs less than any detached run (its
time term is at most ``A max_time = 1e3 < P``).

:func:`solve_dissertation` runs DE (population 50, 50 generations, CR 0.8, F 0.9: 2,550
episodes) or CMA-ES with the same budget; each generation is one batched call of the compiled
kernel (:func:`microconveyor_env.physics.batch.simulate_batch`), every row with its own spacing.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.core.threads import ThreadChooser, threads
from microconveyor_env.physics.batch import simulate_batch
from microconveyor_env.physics.materials import ContactParams
from microconveyor_env.physics.schedule import ActuatorArray, Schedule
from microconveyor_env.physics.simulator import Simulator

from ..planning.cost import EXPONENT, PENALTY, TIME_WEIGHT, time_weighted_cost
from .search import minimize

VARIABLES = ("frequency_hz", "spacing_m", "delay_s", "stroke_m")
BOUNDS = ((200.0, 10000.0), (500e-6, 1500e-6), (0.0, 0.1), (100e-6, 200e-6))
# the dissertation's optimum (its Table 4.3) and what it reports for it
TABLE_4_3 = {"frequency_hz": 719.0, "spacing_m": 500e-6, "delay_s": 1e-3, "stroke_m": 178e-6,
             "final_position_m": 10.02e-3, "travel_time_s": 0.037}
# the surface of the dissertation's chapter 4 (Table 4.2; docs/physics.md §8)
PRESET = "conveyor"
# the dissertation's DE settings
DE_SETTINGS = {"popsize": 50, "generations": 50, "recombination": 0.8, "mutation": 0.9}


@dataclass(frozen=True)
class DissertationProblem:
    """The problem's constants. ``target_m`` [m] beyond actuator 1; ``time_weight`` A [1/s];
    ``scale_m`` T_d [m]; ``exponent`` C [-]; ``penalty`` P [-]; ``config``: the model (preset,
    shape, wavelength, kinematics, integrator, dt, max_time, start_offset, n_actuators: the
    env's settings); ``contact``: contact parameters replacing the preset's (None: the
    preset's); ``start_m`` [m]: the start position (None: ``config.start_offset`` upstream of
    actuator 1)."""

    target_m: float = 10e-3
    time_weight: float = TIME_WEIGHT
    scale_m: float = 50e-6
    exponent: float = EXPONENT
    penalty: float = PENALTY
    config: EnvConfig = field(default_factory=lambda: EnvConfig.from_yaml(preset=PRESET))
    contact: ContactParams | None = None
    start_m: float | None = None

    @property
    def x0_m(self) -> float:
        """Start position [m]: ``start_m`` if given (either side of actuator 1 at x = 0), else
        ``config.start_offset`` upstream of actuator 1."""
        return -self.config.start_offset if self.start_m is None else float(self.start_m)

    def simulator(self) -> Simulator:
        """The simulator of ``config`` (with ``contact`` if given)."""
        from microconveyor_env.presets import load_preset

        cfg = self.config
        contact = self.contact or load_preset(cfg.preset).contact
        return Simulator(contact, shape=cfg.shape, wavelength=cfg.wavelength,
                         kinematics=cfg.kinematics, mode=cfg.mode, dt=cfg.dt,
                         max_time=cfg.max_time, min_steps=cfg.min_steps,
                         max_steps=cfg.max_steps)

    def replace(self, **changes: Any) -> DissertationProblem:
        """A copy with some fields changed; ``config__NAME=value`` changes a config field."""
        cfg = {k[8:]: changes.pop(k) for k in list(changes) if k.startswith("config__")}
        if cfg:
            changes["config"] = dataclasses.replace(changes.get("config", self.config), **cfg)
        return dataclasses.replace(self, **changes)


def dissertation_cost(final_position_m: Any, travel_time_s: Any, rest: Any,
                      problem: DissertationProblem) -> np.ndarray:
    """The cost (module docstring; :func:`agents.planning.cost.time_weighted_cost`) of runs
    ending at ``final_position_m`` [m] after ``travel_time_s`` [s]; ``rest`` [bool]: the part
    came to rest (False: detached or out of time). Arrays or scalars; returns an array."""
    p = problem
    error = np.asarray(final_position_m, dtype=float) - p.target_m
    return time_weighted_cost(error, travel_time_s, rest, p.time_weight, p.scale_m,
                              p.x0_m - p.target_m, p.exponent, p.penalty)


class Evaluator:
    """Batched runs of shared-parameter schedules on one problem; ``episodes`` counts them."""

    def __init__(self, problem: DissertationProblem) -> None:
        self.problem = problem
        self.sim = problem.simulator()
        self.n = problem.config.n_actuators
        self.episodes = 0
        self._threads: dict[int, ThreadChooser] = {}

    def run(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows of ``X``: (f [Hz], spacing [m], delay [s], stroke [m]) -> (final position [m],
        end time [s], outcome names)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        b = X.shape[0]
        f, s, d, h = X.T
        xa = np.arange(self.n)[None, :] * s[:, None]
        delay = np.repeat(d[:, None], self.n, axis=1)
        delay[:, 0] = 0.0
        chooser = self._threads.setdefault(
            b, ThreadChooser(self.problem.config.num_threads, b))
        k = chooser.choose()
        t0 = time.perf_counter()
        with threads(k):
            r = simulate_batch(self.sim, xa, f[:, None], h[:, None], delay,
                               self.problem.x0_m, parallel=k > 1)
        chooser.record(k, time.perf_counter() - t0, b * self.n)
        self.episodes += b
        return r.final_position_m, r.end_time_s, r.outcome

    def cost(self, X: np.ndarray) -> np.ndarray:
        x, t, outcome = self.run(X)
        return dissertation_cost(x, t, outcome == "rest", self.problem)


@dataclass
class DissertationResult:
    """An optimum of the problem (SI units): the four shared numbers, where the part ends, when
    (``travel_time_s``: rest time; detachment time if detached), the cost, the episodes and
    wall time, and the best cost after each generation (``history_*``)."""

    method: str
    seed: int
    parameters: dict[str, float]
    final_position_m: float
    travel_time_s: float
    outcome: str
    cost: float
    episodes: int
    generations: int
    wall_time_s: float
    history_episodes: list[int]
    history_best_cost: list[float]

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def evaluate_parameters(params: dict[str, float],
                        problem: DissertationProblem | None = None) -> dict[str, Any]:
    """One schedule of shared ``params`` (keys :data:`VARIABLES`, SI units; e.g. :data:`TABLE_4_3`)
    on ``problem``: final position [m], travel time [s], outcome and cost."""
    return _evaluate(Evaluator(problem or DissertationProblem()), params)


def _evaluate(ev: Evaluator, params: dict[str, float]) -> dict[str, Any]:
    X = np.array([[params[k] for k in VARIABLES]])
    x, t, outcome = ev.run(X)
    cost = dissertation_cost(x, t, outcome == "rest", ev.problem)
    return {"parameters": {k: float(params[k]) for k in VARIABLES},
            "final_position_m": float(x[0]), "travel_time_s": float(t[0]),
            "outcome": str(outcome[0]), "cost": float(cost[0])}


def solve_dissertation(method: str = "de", seed: int = 0, budget: int | None = None,
                       problem: DissertationProblem | None = None,
                       popsize: int | None = None, generations: int = 50,
                       mutation: float = 0.9, recombination: float = 0.8) -> DissertationResult:
    """Minimise the dissertation's cost over the four shared numbers (:data:`BOUNDS`).

    ``method``: ``"de"`` (scipy DE, strategy best1bin, ``popsize`` [-] members, default 50,
    ``mutation`` F and ``recombination`` CR as the dissertation's) or ``"cmaes"`` (pycma,
    ``popsize`` default pycma's 8 for 4 variables). ``budget`` [episodes] default
    ``50 * (generations + 1)`` = 2,550 (the DE's start population plus 50 generations);
    used <= budget (:mod:`.search`). ``seed`` [-]: deterministic runs."""
    prob = problem or DissertationProblem()
    ev = Evaluator(prob)
    pop = popsize if popsize is not None else (DE_SETTINGS["popsize"] if method == "de" else None)
    if budget is None:
        budget = int(DE_SETTINGS["popsize"]) * (int(generations) + 1)
    kw: dict[str, Any] = {"popsize": pop}
    if method == "de":
        kw.update(mutation=mutation, recombination=recombination)
    t0 = time.perf_counter()
    res = minimize(method, ev.cost, BOUNDS, budget, seed, **kw)
    wall = time.perf_counter() - t0
    best = _evaluate(ev, dict(zip(VARIABLES, res.x, strict=True)))  # the optimum replayed (not counted)
    return DissertationResult(
        method=method, seed=int(seed), parameters=best["parameters"],
        final_position_m=best["final_position_m"], travel_time_s=best["travel_time_s"],
        outcome=best["outcome"], cost=res.cost, episodes=res.episodes,
        generations=res.generations, wall_time_s=wall,
        history_episodes=res.history_episodes, history_best_cost=res.history_best_cost)


def trajectory(params: dict[str, float],
               problem: DissertationProblem | None = None) -> dict[str, np.ndarray]:
    """The recorded run of shared ``params`` (keys :data:`VARIABLES`): ``t_s`` [s], ``x_m`` [m],
    ``v_m_s`` [m/s] (strokes at every RK4 step, coasts at 32 exact points each)."""
    prob = problem or DissertationProblem()
    n = prob.config.n_actuators
    sched = Schedule.sequence(ActuatorArray.uniform(n, params["spacing_m"]),
                              params["frequency_hz"], params["stroke_m"],
                              [0.0] + [params["delay_s"]] * (n - 1))
    r = prob.simulator().simulate(sched, prob.x0_m, record=True)
    assert r.trajectory is not None
    return {k: r.trajectory[k] for k in ("t_s", "x_m", "v_m_s")}
