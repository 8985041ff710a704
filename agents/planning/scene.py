"""A scene as planners see it, one class per registered scene family they serve.

A planner needs four things of a scene, and gets them here whatever the scene:

* the part's **observed state** (:meth:`Scene.observed`): what a controller may see of a saved
  state, never the episode's hidden friction and mass factors or noise draws;
* the **candidate firings** from a state: on the line a plan holds one action per actuator
  still to fire, anywhere in the box [-1, 1]³ (:meth:`Scene.plan_firings`); on the positioner
  any actuator may fire, and :meth:`PositionerScene.candidates` lists a grid of them;
* a **rollout** of whole plans, from the start or from a saved state, batched on the scene's
  own vector env (:class:`Rollouts`, :meth:`Scene.rollouts`): on the nominal model, or with
  per-episode randomisation as the real part meets it;
* a **rollout of one firing** from many states, each on a model part with its own friction and
  mass factors (:class:`FiringModel`, :meth:`Scene.firing_model`): the identified model;
* the same on the scene's **firing map** (:class:`MapModel`, :meth:`PositionerScene.map_model`):
  the nominal model tabulated once (:mod:`microconveyor_env.physics.firing_map`), a few hundred
  times faster, trusted away from detachment; a planner searches on it and confirms its choice
  on the full model.

:class:`LineScene` serves MicroConveyor-v0 and -v1 (and the line seen by the goal env);
:class:`PositionerScene` serves MicroPositioner-v0. :func:`scene_of` picks the class for a
config. The plane (MicroConveyor2D-v0, -v1) has no class: its part moves in two dimensions
and no planner searches its firings (its actuators fire without a part-relative aim and its
episodes have no fixed length of firings), so :func:`scene_of` refuses it in one sentence.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, MicroConveyorVectorEnv, PartState
from microconveyor_env.envs.core.actions import constants as action_constants, decode
from microconveyor_env.envs.core.episodes import PlanActor, run_episodes
from microconveyor_env.envs.core.randomisation import FACTOR_BOUNDS
from microconveyor_env.envs.line.state import Conveyor
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState
from microconveyor_env.envs.positioner.state import PositionerParts
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.envs.rail.firing_map import firing_map
from microconveyor_env.physics import dynamics_kernel as kernel
from microconveyor_env.physics.forces import I_FSCALE, I_MASS

PLAN_FIRINGS = 5   # firings of a positioner plan unless told (its closed-loop controller needs ~4)
AT_REST = ("moving", "rest")   # a model firing that ends at rest (the episode going on or not)


@dataclass
class Replay:
    """Per-episode outcomes of a batch of plans (arrays over the batch, SI units):
    ``error_m`` signed final x - target [m], ``outcome`` (``rest``, ``detached``, ``max_time``,
    ``too_many_events``; on the line ``moving`` for a plan that ended before the episode),
    ``success`` (at rest within the config's tolerance), ``time_s`` the simulated time at the
    end [s]."""

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
    """Batched open-loop episodes of whole plans ``(B, K, 3)`` on one scene config (envs cached
    by batch size); ``episodes`` counts every episode played. The scene's subclass says how many
    firings a plan holds and how an episode the plan did not finish ends."""

    vector_env: ClassVar[Any]

    def __init__(self, config: Any) -> None:
        self.config = config
        self._envs: dict[int, Any] = {}
        self.episodes = 0
        # with randomisation on: the friction and mass factors of the last run's episodes [-]
        self.factors: dict[str, np.ndarray] = {}

    def check_plans(self, plans: np.ndarray, start: Any) -> None:
        raise NotImplementedError

    def run(self, plans: np.ndarray, target: float | np.ndarray,
            seed: int | Sequence[int] = 0, same_episode: bool = True,
            start: Any = None) -> Replay:
        """Play ``plans`` ``(B, K, 3)`` towards ``target`` [m] (scalar or per plan). Resets with
        ``seed`` [-]: ``same_episode`` gives every plan the episode of that seed (the same start,
        the same randomisation: common random numbers for a fair comparison); otherwise plan
        ``i`` gets seed ``seed + i`` (independent episodes, as for replays under perturbation);
        a sequence gives plan ``i`` seed ``seed[i]``. ``start``: every episode starts from this
        saved part state instead (its target is the one played; ``target`` is ignored) and the
        plans hold the remaining firings."""
        plans = np.asarray(plans, dtype=float)
        self.check_plans(plans, start)
        b, k = plans.shape[:2]
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = self.vector_env(b, config=self.config,
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
        options = {"target": targets} if start is None else {"state": start}
        ep = run_episodes(env, PlanActor(plans), seeds, options, max_steps=k)
        self.episodes += b
        return self.ending(env, ep, targets)

    def ending(self, env: Any, ep: Any, targets: np.ndarray) -> Replay:
        """The batch's outcomes from the episodes ``ep`` of ``env``."""
        raise NotImplementedError


class LineRollouts(Rollouts):
    """The line's plans on ``config`` (default: MicroConveyor-v0's defaults): one firing per
    actuator still to fire, ``(B, n_actuators - fired, 3)``; a plan that ends before its episode
    (the part still moving) has outcome ``moving``."""

    vector_env = MicroConveyorVectorEnv

    def __init__(self, config: EnvConfig | None = None) -> None:
        super().__init__(config or EnvConfig.from_yaml())
        self._parts: dict[int, Conveyor] = {}

    def check_plans(self, plans: np.ndarray, start: Any) -> None:
        n = self.config.n_actuators - (0 if start is None else start.fired)
        if plans.ndim != 3 or plans.shape[1:] != (n, 3):
            raise ValueError(f"plans must have shape (batch, {n}, 3), got {plans.shape}")

    def ending(self, env: Any, ep: Any, targets: np.ndarray) -> Replay:
        f = ep.final
        outcome = np.where(ep.ended, f["outcome"], "moving").astype(object)
        return Replay(targets, f["position_error_m"], outcome, f["is_success"], f["sim_time_s"])

    def run(self, plans: np.ndarray, target: float | np.ndarray,
            seed: int | Sequence[int] = 0, same_episode: bool = True,
            start: Any = None) -> Replay:
        """As :meth:`Rollouts.run`; from a saved ``start`` on a nominal config (no randomisation
        to draw, no seed to use) the plans are played on the part container directly, the
        state written into its arrays as a reset from it would write them: the same episodes
        bit for bit, at a fraction of the env's overhead (a planner re-plans from every state)."""
        if start is None or self.config.randomised:
            return super().run(plans, target, seed, same_episode, start)
        plans = np.asarray(plans, dtype=float)
        self.check_plans(plans, start)
        b, k = plans.shape[:2]
        c = self._parts.get(b)
        if c is None:
            c = self._parts[b] = Conveyor(self.config, b, num_threads=1)
        p = c.parts
        p.x[:], p.v[:], p.t[:] = start.position_m, start.velocity_m_s, start.time_s
        p.fired[:], p.target[:] = start.fired, start.target_m
        code = np.full(b, kernel.MOVING)
        live = np.ones(b, bool)
        acts = plans.astype(np.float32).astype(np.float64)
        for j in range(k):
            out = c.step(np.ascontiguousarray(acts[:, j]), live)
            code = np.where(live, out.outcome, code)
            live &= out.outcome == kernel.MOVING
            if not live.any():
                break
        self.episodes += b
        target_m = float(start.target_m)
        err = p.x - target_m
        ended = code != kernel.MOVING
        names = np.array(kernel.OUTCOMES, dtype=object)[code]
        outcome = np.where(ended, names, "moving").astype(object)
        success = ended & (code == kernel.REST) & (np.abs(err) <= self.config.tolerance)
        return Replay(np.full(b, target_m), err.copy(), outcome, success, p.t.copy())


class PositionerRollouts(Rollouts):
    """The positioner's plans of ``K`` firings of any actuator, ``(B, K, 3)``; a plan played to
    its end leaves the part at rest, and that rest is its result (outcome ``rest``)."""

    vector_env = MicroPositionerVectorEnv

    def check_plans(self, plans: np.ndarray, start: Any) -> None:
        if start is not None:
            raise ValueError("a positioner plan is played from the episode's start")
        if plans.ndim != 3 or plans.shape[2] != 3 or plans.shape[1] < 1:
            raise ValueError(f"plans must have shape (batch, firings, 3), got {plans.shape}")
        if plans.shape[1] > self.config.max_firings:
            raise ValueError(f"a plan of {plans.shape[1]} firings: the env allows "
                             f"{self.config.max_firings}")

    def ending(self, env: Any, ep: Any, targets: np.ndarray) -> Replay:
        f = ep.final
        ended = ep.ended
        err = np.where(ended, f["position_error_m"], env.x - env.target)
        outcome = np.where(ended, f["outcome"], "rest").astype(object)
        success = np.where(ended, f["is_success"], np.abs(err) <= self.config.tolerance)
        t = np.where(ended, f["sim_time_s"], env.t)
        if self.config.randomised:   # each episode's draws (an ended one's from its final info)
            self.factors = {k: np.where(ended, f[k], getattr(env, k)).astype(float)
                            for k in ("friction_factor", "mass_factor")}
        return Replay(targets, err.astype(float), outcome, success.astype(bool),
                      t.astype(float))


class FiringModel:
    """One firing from many part states on the model, batched: :meth:`rests` fires ``(B, 3)``
    actions from saved states (each naming its friction and mass factors) and says where each
    part ends and whether it rests. The model is ``config``'s scene without execution noise,
    any factor a state sets allowed, one thread. Envs are kept by batch size; ``firings``
    counts every model firing."""

    def __init__(self, config: Any, vector_env: Any) -> None:
        self.config = dataclasses.replace(config, action_noise=0.0,
                                          friction_factor_range=FACTOR_BOUNDS,
                                          mass_factor_range=FACTOR_BOUNDS, num_threads=1)
        self._vector_env = vector_env
        self._envs: dict[int, Any] = {}
        self.firings = 0

    def rests(self, states: Any, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where each part is after the firing [m] ``(B,)`` and a mask of the firings that end
        at rest, for ``actions`` ``(B, 3)`` fired from ``states`` (one for all, or one per
        action)."""
        b = len(actions)
        env = self._envs.get(b)
        if env is None:
            env = self._envs[b] = self._vector_env(b, config=self.config)
        env.reset(options={"state": states})
        _, _, _, _, info = env.step(np.asarray(actions, np.float32))
        self.firings += b
        ok = np.isin(info["outcome"], AT_REST)
        return env.x.copy(), ok


class RestFiringModel(FiringModel):
    """:class:`FiringModel` for the positioner, whose firings start from rest: the states are
    written into the part container's arrays directly (position, time, firings, target, and the
    friction and mass factors into each part's model constants, as a reset from the state would
    write them; a factor left None is 1), not through the env's checked resets, so a few hundred
    model firings cost little more than the firings themselves. The results are the reset
    path's, bit for bit (``tests/agents/test_positioner_control.py``)."""

    def __init__(self, config: PositionerConfig) -> None:
        super().__init__(config, MicroPositionerVectorEnv)
        self._parts: dict[int, Any] = {}

    def rests(self, states: Any, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b = len(actions)
        c = self._parts.get(b)
        if c is None:
            c = self._parts[b] = PositionerParts(self.config, b, num_threads=1)
        rows = [states] * b if isinstance(states, PositionerState) else list(states)
        if len(rows) != b:
            raise ValueError(f"{len(rows)} states for {b} actions")
        p = c.parts
        p.x[:] = [s.position_m for s in rows]
        p.t[:] = [s.time_s for s in rows]
        p.fired[:] = [s.fired for s in rows]
        p.target[:] = [s.target_m for s in rows]
        ff = np.array([1.0 if s.friction_factor is None else s.friction_factor for s in rows])
        mf = np.array([1.0 if s.mass_factor is None else s.mass_factor for s in rows])
        base = c.sim.params
        P = c.consts.P
        P[:] = base
        P[:, I_MASS] = base[I_MASS] * mf
        P[:, I_FSCALE] = base[I_FSCALE] * ff
        c.friction_factor[:], c.mass_factor[:] = ff, mf
        out = c.step(np.asarray(actions, np.float32).astype(np.float64))
        self.firings += b
        ok = (out.outcome == kernel.MOVING) | (out.outcome == kernel.REST)
        return p.x.copy(), ok


class MapModel:
    """One firing from rest on the positioner's firing map (nominal friction and mass):
    :meth:`rests` says where each part comes to rest, when, and whether the map trusts it
    (away from detachment and inside the map); ``queries`` counts every firing asked."""

    def __init__(self, config: PositionerConfig) -> None:
        self.config = config
        self.map = firing_map(config)
        self.positions = np.asarray(config.actuator_positions, float)
        self.AC = action_constants(config)
        self.queries = 0

    def firings(self, x: np.ndarray, actions: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The actuator each action picks from a part resting at ``x`` [m] (the env's rule) and
        the frequency [Hz] and stroke [m] it fires (as the env decodes float32 actions)."""
        a = np.clip(np.asarray(actions, np.float32).astype(float), -1.0, 1.0)
        c = self.config
        j = np.clip(np.floor((x + a[:, 0] * c.pick_reach) / c.spacing + 0.5).astype(int), 0,
                    len(self.positions) - 1)
        f = self.AC.f0 * np.exp((a[:, 1] + 1.0) * 0.5 * self.AC.log_span)
        h = self.AC.h0 + (a[:, 2] + 1.0) * 0.5 * self.AC.h_span
        return self.positions[j], f, h

    def rests(self, x: Any, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each part comes to rest [m] ``(B,)``, the firing's duration to rest [s] and
        whether the map trusts it, for ``actions`` ``(B, 3)`` fired from rest at ``x`` [m] (one
        position for all, or one per action)."""
        x = np.broadcast_to(np.asarray(x, float), (len(actions),))
        xa, f, h = self.firings(x, actions)
        dx, t, ok = self.map.rest(x - xa, f, h)
        self.queries += len(actions)
        return x + dx, t, ok


class Scene:
    """What a planner needs of one scene (module docstring); ``config`` is the scene as the real
    env has it (its randomisation is the real part's, never the model's)."""

    firing_keys: ClassVar[tuple[str, ...]]   # the info keys of a firing as fired (SI)
    env_class: ClassVar[Any]
    rollouts_class: ClassVar[type[Rollouts]]

    def __init__(self, config: Any) -> None:
        self.config = config

    def env(self, config: Any = None) -> Any:
        """A single env of ``config`` (default: the scene's)."""
        return self.env_class(config=self.config if config is None else config)

    def rollouts(self, config: Any = None) -> Rollouts:
        """Batched plans on ``config`` (default: the scene's)."""
        return self.rollouts_class(self.config if config is None else config)

    def firing_model(self) -> FiringModel:
        """One firing from many states on the scene's model (any factors a state names)."""
        return FiringModel(self.config, self.rollouts_class.vector_env)

    def observed(self, state: Any) -> Any:
        raise NotImplementedError

    def plan_firings(self, start: Any = None, firings: int | None = None) -> int:
        raise NotImplementedError

    def decode_plan(self, plan: np.ndarray) -> dict[str, list[float]]:
        raise NotImplementedError


class LineScene(Scene):
    """The conveyor line (MicroConveyor-v0, -v1): the part passes every actuator once, in order,
    and a plan fires each (frequency, stroke, delay)."""

    firing_keys = ("frequency_hz", "stroke_m", "delay_s")
    env_class = MicroConveyorEnv
    rollouts_class = LineRollouts

    def observed(self, state: PartState) -> PartState:
        """Its kinematic state, never the episode's hidden randomisation."""
        return PartState(state.position_m, state.velocity_m_s, state.time_s, state.fired,
                         state.target_m)

    def plan_firings(self, start: PartState | None = None, firings: int | None = None) -> int:
        """The actuators still to fire from ``start`` (all from the episode's start)."""
        n = self.config.n_actuators - (0 if start is None else start.fired)
        if firings is not None and firings != n:
            raise ValueError(f"a line's plan fires each of the {n} actuators left once")
        return n

    def decode_plan(self, plan: np.ndarray) -> dict[str, list[float]]:
        """The plan's firings in SI units: ``frequency_hz``, ``stroke_m``, ``delay_s``."""
        AC = action_constants(self.config)
        rows = [decode(float(a[0]), float(a[1]), float(a[2]), AC)
                for a in np.asarray(plan, float)]
        return {"frequency_hz": [r[0] for r in rows], "stroke_m": [r[1] for r in rows],
                "delay_s": [r[2] for r in rows]}


class PositionerScene(Scene):
    """The positioner (MicroPositioner-v0): every firing picks the actuator nearest ``x + aim ·
    pick_reach`` from where the part rests, and runs the part to rest."""

    firing_keys = ("frequency_hz", "stroke_m")
    env_class = MicroPositionerEnv
    rollouts_class = PositionerRollouts

    def observed(self, state: PositionerState) -> PositionerState:
        """Where it rests, its time, firings, target and last firing (nor the env it was saved
        in: the model's env takes it as its own)."""
        return PositionerState(state.position_m, state.time_s, state.fired, state.target_m,
                               state.last_step_m, state.last_frequency, state.last_stroke,
                               state.last_offset_m)

    def plan_firings(self, start: Any = None, firings: int | None = None) -> int:
        """A plan's firings: ``firings`` (default :data:`PLAN_FIRINGS`)."""
        return PLAN_FIRINGS if firings is None else int(firings)

    def decode_plan(self, plan: np.ndarray) -> dict[str, list[float]]:
        """The plan's aims [-] and firings in SI units (``frequency_hz``, ``stroke_m``)."""
        AC = action_constants(self.config)
        rows = [decode(float(a[1]), float(a[2]), -1.0, AC) for a in np.asarray(plan, float)]
        return {"aim": [float(a[0]) for a in np.asarray(plan, float)],
                "frequency_hz": [r[0] for r in rows], "stroke_m": [r[1] for r in rows]}

    def firing_model(self) -> FiringModel:
        """One firing from many resting states on the scene's model (:class:`RestFiringModel`)."""
        return RestFiringModel(self.config)

    def map_model(self) -> MapModel:
        """One firing from rest on the scene's firing map (nominal model)."""
        return MapModel(self.config)

    def candidates(self, x: float, frequencies: int, strokes: int) -> tuple[np.ndarray, int]:
        """The candidate firings from a part resting at ``x`` [m]: every actuator the aim can
        pick, aimed at exactly (action 0 = its offset / ``pick_reach``, clipped), times
        ``frequencies`` × ``strokes`` values of actions 1 and 2 evenly over [-1, 1]. Returns the
        actions ``(A * F * H, 3)`` float32 (aim slowest, stroke fastest) and ``A``."""
        config = self.config
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


def scene_of(config: Any) -> Scene:
    """The planners' view of ``config``'s scene: :class:`PositionerScene` for a
    :class:`PositionerConfig`, :class:`LineScene` for the line's :class:`EnvConfig`; any other
    scene (the plane, served by :mod:`.plane`) is refused in one sentence."""
    if isinstance(config, PositionerConfig):
        return PositionerScene(config)
    if isinstance(config, EnvConfig):
        return LineScene(config)
    raise ValueError(f"no planner serves {type(config).__name__}'s scene: planners search the "
                     "firings of the conveyor line (MicroConveyor-v0, -v1) and the positioner "
                     "(MicroPositioner-v0); the plane has its own one-step controller "
                     "(agents.planning.plane)")
