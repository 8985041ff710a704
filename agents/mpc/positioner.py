"""Model-based control of MicroPositioner-v0: before every firing, try many firings on a model
of the part from its observed state and fire the one whose predicted rest is nearest the target.

The positioner's firings each run the part to rest, so a one-step search is a whole plan: from
the observed state (where the part rests, its time, its firings so far, the last firing), the
controller (:class:`PositionerMPC`) steps a batched env of the model
(:class:`~microconveyor_env.envs.positioner.vector.MicroPositionerVectorEnv`, every sub-env
reset to that state) with a grid of candidate firings: every actuator the aim can pick (the
nearest few, each aimed at exactly), ``frequencies`` frequencies and ``strokes`` strokes across
their action ranges. A candidate whose model part detaches (or runs out of time) is refused, and
so are its ``margin`` neighbours in frequency and stroke: a margin from detachment for the
execution noise; the nearest few are fired again on the model with its friction and mass
``check_factor`` higher and lower, and one that detaches there is passed over: a margin for the
model's error (the mass sets detachment on its own, not only through the friction ratio below).
Of the rest, the one whose predicted rest is nearest the target fires on the real env. The controller stops when no candidate is predicted to bring the
part closer (the part is at rest where it is).

The model (``model=``):

* ``"nominal"``: the env's nominal friction and mass;
* ``"identified"``: the friction fitted online from the episode's own firings
  (:class:`FrictionFit`): each past firing's observed rest against the model's rest from the
  observed state before it and the **commanded** action (the env does not say what noise it
  added), least squares over a grid of friction factors with a weak prior at 1, refined by a
  parabola through the best three. Only one factor is fitted: a firing's rest depends on the
  friction and mass factors through their ratio (a part ``k`` times heavier on ``k`` times the
  friction rests where the nominal part does, within 0.2 % of the displacement over ±10 %), so the
  rests cannot tell them apart; the fitted *effective* friction factor (mass held nominal) is
  the one number that carries the difference;
* ``"oracle"``: the episode's true friction and mass factors, read from the env. It knows what a
  controller cannot: a reference for the others, never a method.

It acts only through the env's API: ``reset``, ``step`` and the saved state without its hidden
factors and noise (:func:`observed`). Many episodes: :class:`PositionerMPCRollout`, a rollout
function as :mod:`agents.experiments.perturb` runs them.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from microconveyor_env.envs.line.config import FACTOR_BOUNDS
from microconveyor_env.envs.line.randomisation import apply_factors
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState
from microconveyor_env.envs.positioner.state import PositionerParts
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.physics import dynamics_kernel as kernel

from .control import MPCEpisode

__all__ = ["BatchExpert", "MODELS", "FrictionFit", "PositionerMPC", "PositionerMPCRollout",
           "PositionerMPCSettings", "Transition", "candidate_actions", "observed"]

MODELS = ("nominal", "identified", "oracle")
AT_REST = ("moving", "rest")   # a model firing that ends at rest (the episode going on or not)
# the step below which a candidate does not count as bringing the part closer [m]
MIN_GAIN = 0.1e-6


@dataclass(frozen=True)
class PositionerMPCSettings:
    """``model``: ``"nominal"``, ``"identified"`` or ``"oracle"`` (module docstring);
    ``frequencies``, ``strokes`` [-]: candidate values evenly spaced over the frequency and
    stroke actions' range [-1, 1] (the env maps them log-uniformly onto its frequency range and
    linearly onto its stroke range); ``margin`` [-]: grid cells in frequency and stroke around a
    candidate whose model part detaches that are refused too; ``factor_range`` R [-] and
    ``factor_points`` [-]: the identified friction factor's grid over [1 − R, 1 + R];
    ``prior_width`` [-]: the fit's prior standard deviation of that factor around 1;
    ``residual_m`` [m]: the rest residual that weighs as much as one prior width;
    ``check_factor`` δ [-] and ``check_best`` [-]: the nearest ``check_best`` candidates are
    fired again with the model's friction and mass factors times 1 ± δ (four corners), and one
    that detaches under any is passed over (0: no check), a margin for the model's error."""

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

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"model = {self.model!r} is invalid: must be one of {MODELS}")
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


# one observed firing: the state before it (as observed), the action commanded, the rest after [m]
Transition = tuple[PositionerState, np.ndarray, float]


def observed(state: PositionerState) -> PositionerState:
    """What a controller sees of a part: where it rests, its time, firings, target and last
    firing, never the episode's hidden friction and mass factors or noise draws (nor the env it
    was saved in: the model's env takes it as its own)."""
    return PositionerState(state.position_m, state.time_s, state.fired, state.target_m,
                           state.last_step_m, state.last_frequency, state.last_stroke,
                           state.last_offset_m)


def model_config(config: PositionerConfig) -> PositionerConfig:
    """The model's config: ``config``'s scene without execution noise, any friction and mass
    factor a state sets allowed, one thread (the candidates run serially)."""
    return dataclasses.replace(config, action_noise=0.0, friction_factor_range=FACTOR_BOUNDS,
                               mass_factor_range=FACTOR_BOUNDS, num_threads=1)


class Model:
    """Batched firings on the model: :meth:`rests` fires a batch of actions from part states
    with given factors and returns where each part rests and whether it did (not detached, not
    out of time). Envs are kept by batch size; ``firings`` counts every model firing."""

    def __init__(self, config: PositionerConfig) -> None:
        self.config = model_config(config)
        self._envs: dict[int, MicroPositionerVectorEnv] = {}
        self.firings = 0

    def rests(self, states: PositionerState | list[PositionerState],
              actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rest positions [m] ``(B,)`` and a mask of the firings that end at rest, for
        ``actions`` ``(B, 3)`` fired from ``states`` (one for all, or one per action; each
        naming its friction and mass factors)."""
        b = len(actions)
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = MicroPositionerVectorEnv(b, config=self.config)
        env.reset(options={"state": states})
        _, _, _, _, info = env.step(np.asarray(actions, np.float32))
        self.firings += b
        ok = np.isin(info["outcome"], AT_REST)
        return env.x.copy(), ok


def with_factors(state: PositionerState, friction: float, mass: float = 1.0) -> PositionerState:
    """``state`` on a model part with these friction and mass factors [-]."""
    return dataclasses.replace(state, friction_factor=float(friction), mass_factor=float(mass))


class FrictionFit:
    """The effective friction factor [-] fitted from observed firings (module docstring): on a
    grid of ``settings.factor_points`` factors over [1 − R, 1 + R], the cost of each is the sum
    of the squared rest residuals (in units of ``residual_m``) plus ``((factor − 1) /
    prior_width)²``; each firing adds its residuals once (:meth:`add`), and :meth:`estimate`
    refines the grid's best by a parabola through it and its neighbours."""

    def __init__(self, model: Model, settings: PositionerMPCSettings) -> None:
        self.model = model
        self.settings = s = settings
        self.grid = np.linspace(1.0 - s.factor_range, 1.0 + s.factor_range, s.factor_points)
        self.prior = ((self.grid - 1.0) / s.prior_width) ** 2
        self.reset()

    def reset(self) -> None:
        """Forget every firing (a new episode)."""
        self.cost = self.prior.copy()
        self.firings = 0

    def add(self, transition: Transition) -> None:
        """Count one observed firing: the model's rest at every grid factor against the
        observed one. A factor under which the model part detaches costs as if it rested
        1 mm off."""
        before, action, after = transition
        states = [with_factors(before, f) for f in self.grid]
        x, ok = self.model.rests(states, np.repeat(np.asarray(action, float)[None],
                                                   len(self.grid), axis=0))
        r = np.where(ok, x - after, 1e-3) / self.settings.residual_m
        self.cost += r ** 2
        self.firings += 1

    def estimate(self) -> float:
        """The fitted factor [-] (1 before any firing)."""
        if not self.firings:
            return 1.0
        i = int(np.argmin(self.cost))
        if 0 < i < len(self.grid) - 1:
            c0, c1, c2 = self.cost[i - 1:i + 2]
            den = c0 - 2.0 * c1 + c2
            if den > 0:
                step = self.grid[1] - self.grid[0]
                return float(self.grid[i] + 0.5 * step * (c0 - c2) / den)
        return float(self.grid[i])


def candidate_actions(x: float, config: PositionerConfig, frequencies: int,
                      strokes: int) -> tuple[np.ndarray, int]:
    """The candidate firings from a part resting at ``x`` [m]: every actuator the aim can pick,
    aimed at exactly (action 0 = its offset / ``pick_reach``, clipped), times ``frequencies``
    × ``strokes`` values of actions 1 and 2 evenly over [-1, 1]. Returns the actions
    ``(A * F * H, 3)`` float32 (aim slowest, stroke fastest) and ``A``."""
    pos = np.asarray(config.actuator_positions, float)
    s, reach = float(config.spacing), float(config.pick_reach)

    def pick(a: np.ndarray) -> np.ndarray:   # the env's rule (positioner.task.pick)
        j = np.floor((x + np.clip(a, -1.0, 1.0) * reach) / s + 0.5).astype(int)
        return np.clip(j, 0, len(pos) - 1)

    reachable = np.unique(pick(np.linspace(-1.0, 1.0, 8 * int(reach / s + 1) + 1)))
    aims = np.clip((pos[reachable] - x) / reach, -1.0, 1.0).astype(np.float32)
    keep = pick(aims.astype(float)) == reachable
    aims = aims[keep]
    f = np.linspace(-1.0, 1.0, frequencies)
    h = np.linspace(-1.0, 1.0, strokes)
    A, F, H = np.meshgrid(aims, f, h, indexing="ij")
    acts = np.stack([A.ravel(), F.ravel(), H.ravel()], axis=1).astype(np.float32)
    return acts, len(aims)


def _dilate(bad: np.ndarray, margin: int) -> np.ndarray:
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


class PositionerMPC:
    """The one-step model-based controller of MicroPositioner-v0 (module docstring) on the
    scene of ``config`` (a :class:`PositionerConfig`; its randomisation is the real env's and
    is not used by the model) with ``settings``. :meth:`choose` picks one firing;
    :meth:`run` controls one episode of a real env."""

    def __init__(self, config: PositionerConfig,
                 settings: PositionerMPCSettings | None = None) -> None:
        self.config = config
        self.settings = settings or PositionerMPCSettings()
        self.model = Model(config)
        self.fit = FrictionFit(self.model, self.settings)
        self.factors: tuple[float, float] = (1.0, 1.0)   # friction, mass of the model now

    def predict(self, state: PositionerState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate from ``state`` (observed) on the model with :attr:`factors`: the
        actions ``(A, F, H, 3)``, the predicted rests [m] ``(A, F, H)`` and whether each is
        allowed (rests, and no neighbour within the margin detaches)."""
        s = self.settings
        acts, n_aims = candidate_actions(state.position_m, self.config, s.frequencies,
                                         s.strokes)
        x, ok = self.model.rests(with_factors(state, *self.factors), acts)
        shape = (n_aims, s.frequencies, s.strokes)
        allowed = ~_dilate(~ok.reshape(shape), s.margin)
        return acts.reshape(*shape, 3), x.reshape(shape), allowed

    def choose(self, state: PositionerState) -> np.ndarray | None:
        """The firing (action ``(3,)`` float32) whose predicted rest from ``state`` is nearest
        its target, or None when no allowed candidate is predicted to bring the part closer.
            With ``check_factor`` δ > 0, the ``check_best`` nearest are fired again on the model
        with its friction and mass factors each times 1 − δ or 1 + δ (the four corners), and
        the nearest that rests under all four is chosen (the nearest of all if none does)."""
        s = self.settings
        acts, x, allowed = self.predict(state)
        err = np.where(allowed, np.abs(x - state.target_m), np.inf).ravel()
        gain = err < abs(state.position_m - state.target_m) - MIN_GAIN
        order = np.argsort(err, kind="stable")[:s.check_best]
        order = order[gain[order]]
        if not order.size:
            return None
        flat = acts.reshape(-1, 3)
        if s.check_factor > 0.0:
            f, m = self.factors
            d = s.check_factor
            corners = [(f * a, m * b) for a in (1.0 - d, 1.0 + d) for b in (1.0 - d, 1.0 + d)]
            states = [with_factors(state, a, b) for a, b in corners for _ in order]
            _, ok = self.model.rests(states, np.tile(flat[order], (len(corners), 1)))
            every = ok.reshape(len(corners), order.size).all(axis=0)
            if every.any():
                return flat[order[int(np.argmax(every))]]
        return flat[order[0]]

    def run(self, env: MicroPositionerEnv, target_m: float, seed: int) -> MPCEpisode:
        """Control one episode of ``env`` (reset with ``seed`` towards ``target_m`` [m]) to its
        end, or until no firing is predicted to bring the part closer (it then rests where it
        is: outcome ``rest``). ``episodes`` counts the model's firings."""
        s = self.settings
        env.reset(seed=int(seed), options={"target": float(target_m)})
        true = (env.friction_factor, env.mass_factor)
        self.fit.reset()
        self.factors = true if s.model == "oracle" else (1.0, 1.0)
        start = self.model.firings
        wall, k = 0.0, 0
        fired: dict[str, list[float]] = {"frequency_hz": [], "stroke_m": []}
        before: PositionerState | None = None
        action: np.ndarray | None = None
        info: dict[str, Any] = {"position_error_m": env.x - env.target, "outcome": "rest",
                                "is_success": False, "sim_time_s": env.t}
        while True:
            state = observed(env.get_state())
            t0 = time.perf_counter()
            if s.model == "identified" and before is not None and action is not None:
                self.fit.add((before, action, state.position_m))
                self.factors = (self.fit.estimate(), 1.0)
            action = self.choose(state)
            wall += time.perf_counter() - t0
            if action is None:   # nothing brings it closer: it rests where it is
                info = {"position_error_m": state.position_m - state.target_m,
                        "outcome": "rest", "is_success": False, "sim_time_s": state.time_s}
                break
            before = state
            _, _, term, trunc, info = env.step(action)
            fired["frequency_hz"].append(float(info["frequency_hz"]))
            fired["stroke_m"].append(float(info["stroke_m"]))
            k += 1
            if term or trunc:
                break
        return MPCEpisode(
            target_m=float(target_m), error_m=float(info["position_error_m"]),
            outcome=str(info["outcome"]), success=bool(info["is_success"]),
            time_s=float(info["sim_time_s"]), firings=k, episodes=self.model.firings - start,
            wall_time_s=wall, friction_factor=true[0], mass_factor=true[1],
            estimated_factors=self.factors, frequency_hz=fired["frequency_hz"],
            stroke_m=fired["stroke_m"])


class PositionerMPCRollout:
    """A rollout function ``(config, targets, seed) -> dict`` as :mod:`agents.experiments.perturb`
    runs them: episode ``i`` is the single env of ``config`` seeded ``seed + i`` (the same
    episode as sub-env ``i`` of the batched env seeded ``seed``), controlled by a
    :class:`PositionerMPC` with ``settings``, in this process. The dict also holds the compute
    per target: ``episodes`` (model firings) and ``wall_time_s`` (choosing), and the model's
    ``estimated_friction_factor``."""

    def __init__(self, settings: PositionerMPCSettings | None = None) -> None:
        self.settings = settings or PositionerMPCSettings()

    def __call__(self, config: PositionerConfig, targets: np.ndarray, seed: int) -> dict:
        tg = np.asarray(targets, float)
        ctl = PositionerMPC(config, self.settings)
        env = MicroPositionerEnv(config=config)
        eps = [ctl.run(env, float(t), int(seed) + i) for i, t in enumerate(tg)]
        out: dict[str, Any] = {
            "targets_m": tg,
            "error_m": np.array([e.error_m for e in eps]),
            "outcome": np.array([e.outcome for e in eps], dtype=object),
            "success": np.array([e.success for e in eps]),
            "time_s": np.array([e.time_s for e in eps]),
            "firings": np.array([e.firings for e in eps]),
            "episodes": np.array([e.episodes for e in eps]),
            "wall_time_s": np.array([e.wall_time_s for e in eps]),
            "estimated_friction_factor": np.array([e.estimated_factors[0] for e in eps])}
        if config.randomised:
            out["friction_factor"] = np.array([e.friction_factor for e in eps])
            out["mass_factor"] = np.array([e.mass_factor for e in eps])
        return out


# ---- the same search batched over many parts (DAgger's expert, the sizing study) ----
AIMS = 3          # the reachable actuators tried per part (the nearest three)
CHECKED = 24      # candidates per part fired again on the heavier model, in the order tried


class BatchExpert:
    """The one-step search of :class:`PositionerMPC` batched over many parts (DAgger's expert
    and the sizing study play hundreds of episodes at once): for every part, each of the
    ``AIMS`` nearest actuators x ``frequencies`` x ``strokes`` fired on the model from where the
    part rests, in one compiled call of the env's own step on a part container
    (:class:`~microconveyor_env.envs.positioner.state.PositionerParts`) whose state arrays are
    written directly, not through resets. The model is nominal (or, with ``factors``, each
    part's friction and mass: a reference that knows them, never a method); it never sees an
    episode's noise.

    A candidate that detaches, or whose neighbour within ``margin`` [-] grid cells in frequency
    or stroke does, is refused; with ``heavier`` δ [-] > 0 so is one that detaches on the model
    of a part 1 + δ times heavier (the mass alone sets when the surface outruns the part's
    pull-off, so an unknown mass is what turns a firing near the edge into a detachment); so is
    one that does not bring the part closer. Of the rest, among those predicted to come to rest
    within ``slack`` [m] of the nearest, the gentlest fires (the lowest frequency, then the
    shortest stroke): it lands as near, accelerates the part least and makes the answer change
    smoothly with the state, which a network imitating it needs (an argmin over the grid jumps
    between firings that land equally near). The heavier model checks the first ``CHECKED`` in
    that order (then by predicted error), and the first one it does not detach fires. ``frequencies`` and ``strokes`` [-]: candidates
    evenly over each action's [-1, 1]; ``config``'s randomisation is the real env's, unused."""

    def __init__(self, config: PositionerConfig, frequencies: int = 41, strokes: int = 6,
                 margin: int = 1, slack: float = 5e-6, heavier: float = 0.0) -> None:
        self.config = dataclasses.replace(config, action_noise=0.0, num_threads=1,
                                          friction_factor_range=FACTOR_BOUNDS,
                                          mass_factor_range=FACTOR_BOUNDS)
        self.fa = np.linspace(-1.0, 1.0, frequencies)
        self.ha = np.linspace(-1.0, 1.0, strokes)
        self.margin = margin
        self.slack = slack
        self.heavier = heavier
        self.per_part = AIMS * frequencies * strokes
        self._parts: dict[int, PositionerParts] = {}
        self._factored: dict[int, bool] = {}   # a container whose rows hold other factors
        self.positions = np.asarray(config.actuator_positions)

    def _container(self, n: int) -> PositionerParts:
        if n not in self._parts:
            self._parts[n] = PositionerParts(self.config, n, num_threads=1)
        return self._parts[n]

    def candidates(self, x: np.ndarray) -> np.ndarray:
        """``(M, AIMS, F, H, 3)`` actions: each of the nearest actuators aimed at exactly."""
        s, reach = self.config.spacing, self.config.pick_reach
        j0 = np.clip(np.floor(x / s + 0.5).astype(int), 1, len(self.positions) - 2)
        js = j0[:, None] + np.arange(-1, AIMS - 1)[None, :]
        aim = np.clip((self.positions[js] - x[:, None]) / reach, -1.0, 1.0)
        m, f, h = len(x), len(self.fa), len(self.ha)
        a = np.empty((m, AIMS, f, h, 3))
        a[..., 0] = aim[:, :, None, None]
        a[..., 1] = self.fa[None, None, :, None]
        a[..., 2] = self.ha[None, None, None, :]
        return a

    def act(self, x: np.ndarray, t: np.ndarray, target: np.ndarray,
            factors: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """For parts resting at ``x`` [m] at time ``t`` [s] with ``target`` [m]: the expert's
        actions ``(M, 3)`` and whether each has one (False: no allowed firing brings the part
        closer). ``factors`` ``(M, 2)``: each part's friction and mass factors [-] for the
        model (a controller that knows them: a reference, never a method); None: nominal."""
        m = len(x)
        acts = self.candidates(np.asarray(x, float))
        flat = acts.reshape(-1, 3)
        c = self._container(len(flat))
        p = c.parts
        rep = self.per_part
        if factors is not None or self._factored.get(len(flat)):
            fac = np.ones((m, 2)) if factors is None else np.asarray(factors, float)
            base = c.sim.params
            for i in range(m):
                rows = c.consts.P[i * rep:(i + 1) * rep]
                apply_factors(base, rows[0], fac[i, 0], fac[i, 1])
                rows[1:] = rows[0]
            self._factored[len(flat)] = factors is not None
        p.x[:] = np.repeat(x, rep)
        p.t[:] = np.repeat(t, rep)
        p.target[:] = np.repeat(target, rep)
        p.fired[:] = 0
        shape = (m, AIMS, len(self.fa), len(self.ha))
        c.step(flat)
        code = c.out.outcome.reshape(shape)
        grown = _dilate(~((code == kernel.MOVING) | (code == kernel.REST)), self.margin)
        err = np.abs(p.x.reshape(code.shape) - np.asarray(target)[:, None, None, None])
        err = np.where(grown, np.inf, err).reshape(m, -1)
        least = err.min(axis=1, keepdims=True)
        # the gentlest within the slack first (candidates are ordered aim, frequency, stroke;
        # ranked by frequency, then stroke, then aim), then the others by predicted error
        f, h = len(self.fa), len(self.ha)
        rank = (np.arange(f)[None, :, None] * (h * AIMS) + np.arange(h)[None, None, :] * AIMS
                + np.arange(AIMS)[:, None, None]).ravel()
        n = rank.size
        by_err = np.argsort(np.argsort(err, axis=1, kind="stable"), axis=1)
        key = np.where(err <= least + self.slack, rank[None, :], n + by_err)
        order = np.argsort(key, axis=1, kind="stable")
        best = order[:, 0]
        if self.heavier > 0.0:   # the first of the CHECKED in that order that a heavier part survives
            k = min(CHECKED, n)
            top = order[:, :k]
            fac = np.ones((m, 2)) if factors is None else np.asarray(factors, float)
            hc = self._container(m * k)
            self._factored[m * k] = True
            for i in range(m):
                apply_factors(hc.sim.params, hc.consts.P[i * k], fac[i, 0],
                              fac[i, 1] * (1.0 + self.heavier))
                hc.consts.P[i * k + 1:(i + 1) * k] = hc.consts.P[i * k]
            hp = hc.parts
            hp.x[:], hp.t[:] = np.repeat(x, k), np.repeat(t, k)
            hp.target[:], hp.fired[:] = np.repeat(target, k), 0
            hc.step(acts.reshape(m, -1, 3)[np.arange(m)[:, None], top].reshape(-1, 3))
            hcode = hc.out.outcome.reshape(m, k)
            survives = ((hcode == kernel.MOVING) | (hcode == kernel.REST)) & \
                np.isfinite(np.take_along_axis(err, top, axis=1))
            first = np.argmax(survives, axis=1)
            best = np.where(survives.any(axis=1), top[np.arange(m), first], best)
        now = np.abs(np.asarray(x) - np.asarray(target))
        ok = err[np.arange(m), best] < now - 0.1e-6
        return acts.reshape(m, -1, 3)[np.arange(m), best].astype(np.float32), ok
