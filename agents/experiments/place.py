"""One placement: carry one part to one target with a chosen method and say what was fired, where
the part came to rest and what it cost, on every scene: the line, the positioner and the plane.

* ``policy``: the env's default shipped policy (or a given one), closed loop, one episode.
* ``mpc``: model-predictive control on the nominal model (:class:`agents.mpc.MPC`). On the
  line, every search seeded by a policy's plan (or by none), a re-plan after each firing from
  the part's observed state; on the positioner, the one-step controller (its friction
  identified online): before every firing, the firing whose predicted rest is nearest the
  target.
* ``de``: the open-loop plan of differential evolution on the nominal model
  (:func:`agents.openloop.target.solve_target`), then played once: the line's plan fires every
  actuator in turn; the positioner's is :data:`~agents.planning.scene.PLAN_FIRINGS` firings of
  any actuator.

On the plane (MicroConveyor2D-v0, -v1) ``mpc`` is the plane's one-step controller
(:class:`agents.planning.plane.PlaneController`: before every firing, the candidates ranked on
the plane's firing map, the best few confirmed on the full nominal model, the landing nearest
the target, or staged for a next firing, fires); no open-loop search is defined there
(:func:`methods_of`).

The *request* is the precision asked for, the env config's ``tolerance`` [m] (``place(...,
tolerance=)``; :func:`with_request`): the env ends the episode once the part rests within it,
so every method serves it; a request-conditioned policy reads it, and DE can trade time for
precision on it (``time_weight`` [1/s]: the dissertation's time-weighted cost,
:func:`agents.planning.cost.time_weighted_cost`, with the request as its ``T_d``). Every
placement reports its placement time ``placement_time_s`` [s]: the simulated time until the
part rests (or the episode ends), the env's ``sim_time_s``.

The part is placed in the env ``config`` as given: with per-episode randomisation on (execution
noise, friction and mass spread: :class:`.perturb.Level`) the planners still plan on the nominal
model and the episode shows how the plan holds. Compute: wall time [s] and the simulator
episodes spent (the placement itself included; for the positioner's controller, every firing
it tried on its model).

Actuators: on the line and the positioner numbered from 1 (actuator 1 is where targets are
measured from); on the plane by the env's index ``i + nx j`` (``actuator_index``, from 0). On the
positioner and the plane each firing also says where its actuator is (``actuator_position_m``).
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.core.config import MIN_LENGTH
from microconveyor_env.envs.core.versions import nominal, scene_differences

from ..mpc import MPC, MPCSettings
from ..openloop.search import TARGET_BUDGET
from ..openloop.target import solve_target
from ..planning.cost import EXPONENT
from ..planning.scene import PLAN_FIRINGS
from ..rl.artefacts.policy_files import bind_request

METHODS = ("policy", "mpc", "de")
DE_BUDGET = TARGET_BUDGET   # DE episodes of the model (optimize's default for one target)
POSITIONER_DE_BUDGET = 3000  # the positioner's: the stored comparison's (82 % within ±50 µm)


def geometry_of(config: Any) -> str:
    """``"line"``, ``"positioner"`` or ``"plane"``: the scene ``config`` describes."""
    if isinstance(config, PlaneEnvConfig):
        return "plane"
    return "positioner" if isinstance(config, PositionerConfig) else "line"


def methods_of(config: Any) -> tuple[str, ...]:
    """The methods that place a part in ``config``'s scene: all of :data:`METHODS` on the line
    and the positioner; the plane's policy and its one-step controller (no open-loop search is
    defined there)."""
    return ("policy", "mpc") if geometry_of(config) == "plane" else METHODS


def check_method(method: str, config: Any, env_id: str) -> str:
    """``method`` if it places a part in ``config``'s scene, else a one-line ValueError naming
    the methods that do."""
    have = methods_of(config)
    if method not in have:
        raise ValueError(f"--method {method}: {env_id} (the {geometry_of(config)}) has no "
                         f"{'model-based planner' if method == 'mpc' else 'open-loop search'}; "
                         f"its method{'s are' if len(have) > 1 else ' is'} "
                         f"{', '.join(have)}")
    return method


MAX_REQUEST = 1e-3   # m: the largest tolerance a placement may ask for


def check_request(tolerance: Any) -> float:
    """``tolerance`` [m] as a float if it is a precision a placement may ask for, in
    [1 nm, :data:`MAX_REQUEST`], else a one-line ValueError."""
    try:
        t = float(tolerance)
    except (TypeError, ValueError):
        t = float("nan")
    if not MIN_LENGTH <= t <= MAX_REQUEST:
        raise ValueError(f"--tolerance {tolerance!r} is invalid: the precision asked for is a "
                         f"distance in m from 1e-09 to {MAX_REQUEST:g} (1 nm to "
                         f"{MAX_REQUEST * 1e3:g} mm), e.g. 1e-5 for ±10 µm")
    return t


def with_request(config: Any, tolerance: float | None) -> Any:
    """``config`` asking for ``tolerance`` [m] (:func:`check_request`; None: ``config`` as it
    is): its ``tolerance`` replaced, and its ``progress_scale`` with it where it followed the
    tolerance (the env's default), as ``gym.make(id, tolerance=...)`` builds it."""
    if tolerance is None:
        return config
    t = check_request(tolerance)
    follows = config.progress_scale == config.tolerance
    changes: dict[str, Any] = {"tolerance": t}
    if follows:
        changes["progress_scale"] = None
    return dataclasses.replace(config, **changes)


def de_budget(config: Any) -> int:
    """DE's default budget [episodes] in ``config``'s scene."""
    return POSITIONER_DE_BUDGET if geometry_of(config) == "positioner" else DE_BUDGET


def check_target(target: Any, config: Any, env_id: str) -> Any:
    """``target`` (a float [m]; on the plane an (x, y) pair [m]) if it lies in ``config``'s
    targets (the line's and the positioner's target range, the plane's grid box), else a
    one-line ValueError naming the range in mm."""
    values = [float(v) for v in np.atleast_1d(target)]
    if geometry_of(config) == "plane":
        if len(values) != 2:
            raise ValueError(f"--target on {env_id} is a point of the plane: give X,Y [m], "
                             "e.g. 1.5e-3,0.5e-3")
        (x0, x1), (y0, y1) = config.grid_box
        x, y = values
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            raise ValueError(f"--target ({x * 1e3:g}, {y * 1e3:g}) mm is outside {env_id}'s "
                             f"targets: x in [{x0 * 1e3:g}, {x1 * 1e3:g}] mm, y in "
                             f"[{y0 * 1e3:g}, {y1 * 1e3:g}] mm (the actuator grid's box)")
        return (x, y)
    if len(values) != 1:
        raise ValueError(f"--target on {env_id} is a distance along the line: give one number "
                         "[m], e.g. 7.5e-3")
    lo, hi = (float(v) for v in config.target_range)
    t = values[0]
    if not lo <= t <= hi:
        raise ValueError(f"--target {t * 1e3:g} mm is outside {env_id}'s target range, "
                         f"{lo * 1e3:g} to {hi * 1e3:g} mm ({lo:g} to {hi:g} m)")
    return t


def mpc_seed(policy_path: str | Path | None, config: EnvConfig,
             env_id: str) -> tuple[Any, str]:
    """The policy that seeds the line's MPC in ``config``'s scene and how it does, in words:
    ``policy_path`` (default: ``env_id``'s default shipped policy). A policy of another scene
    (e.g. a user's own ``--preset``) is only a start for the searches, which score every plan
    on ``config``'s model: it seeds them if its observations fit this scene's; otherwise the
    MPC runs unseeded (None)."""
    from ..rl.artefacts.policy_files import policy_scene, read_policy_meta
    from ..rl.artefacts.shipped import require_shipped
    from ..rl.evaluation.evaluate import load_policy

    path = Path(policy_path) if policy_path else require_shipped(env_id)
    meta = read_policy_meta(path)
    if not meta or not scene_differences(nominal(policy_scene(meta)), nominal(config)):
        return load_policy(path, config), f"policy {path}, seeding the MPC"
    policy = load_policy(path)   # its own scene: a seed only, scored on this scene's model
    own = policy.config
    shape = MicroConveyorEnv(config=nominal(config)).observation_space.shape
    if not isinstance(own, EnvConfig) or type(own) is not type(config) or MicroConveyorEnv(
            config=own).observation_space.shape != shape:
        return None, (f"MPC on the nominal model, unseeded: policy {path} was trained on "
                      "another scene, whose observations do not fit this one")
    return policy, (f"policy {path}, seeding the MPC: trained on another scene, its plan is "
                    "only a start for the searches on this scene's model")


def _firings(freq: list[float], stroke: list[float], delay: list[float]) -> list[dict[str, Any]]:
    """The line's firings in order (SI): the line fires its actuators one after the other,
    from 1."""
    return [{"actuator": k + 1, "frequency_hz": f, "stroke_m": h, "delay_s": d}
            for k, (f, h, d) in enumerate(zip(freq, stroke, delay, strict=True))]


def _episode(config: EnvConfig, target: float, seed: int,
             act: Callable[[np.ndarray, int], np.ndarray]) -> dict[str, Any]:
    """One episode of the line ``config`` to ``target`` [m] (reset with ``seed``), firing
    ``act(obs, k)`` at firing ``k``; the outcome and the firings as fired (execution noise
    included)."""
    env = MicroConveyorEnv(config=config)
    obs, _ = env.reset(seed=int(seed), options={"target": float(target)})
    fired: dict[str, list[float]] = {"frequency_hz": [], "stroke_m": [], "delay_s": []}
    k = 0
    while True:
        obs, _, term, trunc, info = env.step(np.asarray(act(obs, k), np.float32))
        for key, values in fired.items():
            values.append(float(info[key]))
        k += 1
        if term or trunc:
            break
    env.close()
    return {"error_m": float(info["position_error_m"]), "outcome": str(info["outcome"]),
            "success": bool(info["is_success"]), "sim_time_s": float(info["sim_time_s"]),
            "firings": _firings(fired["frequency_hz"], fired["stroke_m"], fired["delay_s"])}


class _Recorder:
    """An env that notes every firing as fired (the actuator, where it is, frequency, stroke,
    delay, where the part is after it) and otherwise is the env it wraps."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.firings: list[dict[str, Any]] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        info = out[4]
        j = int(info["actuator"])
        pos = np.asarray(self.env.positions[j], float)
        after: Any = [self.env.x, self.env.y] if pos.ndim else self.env.x
        # the positioner numbers its actuators from 1 (actuator 1 at 0 m, as the line); the
        # plane names them by index i + nx j, from 0, as its info and its frames do
        name = {"actuator_index": j} if pos.ndim else {"actuator": j + 1}
        self.firings.append({**name, "actuator_position_m": pos.tolist(),
                             "frequency_hz": float(info["frequency_hz"]),
                             "stroke_m": float(info["stroke_m"]),
                             "delay_s": float(info.get("delay_s", 0.0)),
                             "position_after_m": after})
        return out


def _scene_env(config: Any) -> Any:
    from microconveyor_env.envs.plane.env import MicroConveyor2DEnv
    from microconveyor_env.envs.positioner.env import MicroPositionerEnv

    if geometry_of(config) == "plane":
        return MicroConveyor2DEnv(config=config)
    return MicroPositionerEnv(config=config)


def _played(env: _Recorder, target: Any, seed: int,
            act: Callable[[np.ndarray, int], np.ndarray | None]) -> dict[str, Any]:
    """One episode of the positioner or the plane (``env``, recording) to ``target``, firing
    ``act(obs, k)`` until the episode ends or ``act`` has nothing more to fire (the part then
    rests where it is: outcome ``rest``)."""
    obs, _ = env.reset(seed=int(seed), options={"target": target})
    info: dict[str, Any] = {}
    k = 0
    while True:
        a = act(obs, k)
        if a is None:
            break
        obs, _, term, trunc, info = env.step(np.asarray(a, np.float32))
        k += 1
        if term or trunc:
            break
    return _ending(env, info, k)


def _ending(env: _Recorder, info: dict[str, Any], k: int) -> dict[str, Any]:
    """The outcome of the episode of ``env`` after ``k`` firings (``info``: the last step's)."""
    cfg = env.config
    ended = k > 0 and info.get("outcome", "moving") != "moving"
    if geometry_of(cfg) == "plane":
        tx, ty = env.target
        err = (env.x - tx, env.y - ty)
        dist = float(np.hypot(*err))
        res: dict[str, Any] = {"error_m": dist, "position_error_m": [float(e) for e in err],
                               "final_position_m": [env.x, env.y]}
    else:
        dist = env.x - env.target
        res = {"error_m": float(dist), "final_position_m": env.x}
    outcome = str(info["outcome"]) if ended else "rest"
    success = bool(info["is_success"]) if ended else abs(dist) <= cfg.tolerance
    return {**res, "outcome": outcome, "success": success, "sim_time_s": env.t,
            "firings": env.firings}


def actor_for(method: str, policy: Any, config: Any, env_id: str) -> tuple[Any, str]:
    """What acts for ``method`` in ``config``'s scene, and how, in words: the policy that acts
    (``policy``) or seeds the line's MPC (``mpc``), loaded from ``policy`` when it is a folder
    [path] or None (``env_id``'s default shipped policy), or taken as it is when already loaded;
    None for the positioner's controller and DE. A policy of another scene is refused for
    ``policy`` and only seeds the line's MPC where its observations fit (:func:`mpc_seed`)."""
    loaded = policy is not None and not isinstance(policy, (str, Path))
    if method == "policy":
        if not loaded:
            from .demo import load_demo_policy

            policy = load_demo_policy(policy, config, env_id)   # another scene is refused
        # a request-conditioned policy acts for this placement's tolerance (the others as given)
        return bind_request(policy, config), f"policy {policy.path}"
    if method == "mpc" and geometry_of(config) == "line":
        if loaded:
            return policy, f"policy {policy.path}, seeding the MPC"
        return mpc_seed(policy, config, env_id)
    if method == "mpc" and geometry_of(config) == "plane":
        return None, "the one-step controller on the firing map and the nominal model"
    if method == "mpc":
        return None, "the one-step controller on its model, friction identified online"
    return None, "differential evolution on the nominal model"


def place(target_m: Any, method: str, config: Any, policy: Any = None, seed: int = 0,
          budget: int | None = None, mpc: MPCSettings | None = None,
          env_id: str = "this scene",
          checked: Callable[[], None] | None = None, tolerance: float | None = None,
          time_weight: float | None = None) -> dict[str, Any]:
    """Place one part at ``target_m`` [m: beyond actuator 1 on the line and the positioner, an
    (x, y) point on the plane] in ``config`` with ``method`` (:func:`methods_of`): ``policy``
    (a loaded policy, a policy folder, or None: the default shipped one; :func:`actor_for`)
    acts (``policy``) or seeds the line's MPC (``mpc``; settings ``mpc``, default
    :class:`MPCSettings` with ``seed``); ``budget`` [episodes]: DE's search
    (default :func:`de_budget`); ``seed`` [-]: the episode's and the searches'.
    ``tolerance`` [m]: the request, the precision asked for (None: the config's tolerance;
    :func:`with_request`); ``time_weight`` A [1/s]: DE minimises the time-weighted cost with
    the request as ``T_d`` (None: the error alone; :func:`agents.openloop.target.solve_target`).
    The result (SI units): the firings (actuator, frequency, stroke, delay), the rest position
    and the error (signed on a line, the distance on the plane), the outcome, success (at rest
    within the request), the placement time ``placement_time_s`` [s] (until the part rests or
    the episode ends; ``sim_time_s``, the env's name, holds the same) and the compute
    (``wall_time_s``, ``episodes``: every simulator episode, the placement's included).
    ``target_m``, ``method``, ``tolerance`` and ``time_weight`` are checked here, once
    (:func:`check_target`, :func:`check_method`, :func:`check_request`; ``env_id`` names the
    scene in their messages), then the policy is loaded (in the config of the request);
    ``checked()`` is called once they pass, before any work. The result also names the
    ``actor`` (in words) and the ``policy`` folder."""
    check_method(method, config, env_id)
    target = check_target(target_m, config, env_id)
    config = with_request(config, tolerance)
    if time_weight is not None:
        if method != "de":
            raise ValueError(f"--time-weight is DE's cost: give it with --method de, not "
                             f"{method}")
        if not (isinstance(time_weight, (int, float)) and 0.0 <= time_weight < np.inf):
            raise ValueError(f"--time-weight {time_weight!r} is invalid: must be a number >= 0 "
                             "[1/s]")
    policy, actor = actor_for(method, policy, config, env_id)
    if checked is not None:
        checked()
    budget = de_budget(config) if budget is None else int(budget)
    t0 = time.perf_counter()
    if geometry_of(config) == "line":
        res, episodes, extra = _place_line(target, method, config, policy, seed, budget, mpc,
                                           time_weight)
    else:
        res, episodes, extra = _place_scene(target, method, config, policy, seed, budget,
                                            time_weight)
    if method == "de":
        extra["time_weight"] = time_weight
        if time_weight:
            actor += (f", minimising {time_weight:g} 1/s × placement time + (error / "
                      f"{config.tolerance * 1e6:g} µm)^{EXPONENT:g}")
    final = res.pop("final_position_m", None)
    if final is None:
        final = target + res["error_m"]
    return {"target_m": list(target) if isinstance(target, tuple) else target,
            "method": method, "seed": int(seed), **res,
            "final_position_m": final, "tolerance_m": config.tolerance,
            "placement_time_s": res["sim_time_s"],
            "wall_time_s": time.perf_counter() - t0, "episodes": int(episodes), **extra,
            "actor": actor, "policy": None if policy is None else str(policy.path)}


def _place_line(target_m: float, method: str, config: EnvConfig, policy: Any, seed: int,
                budget: int, mpc: MPCSettings | None,
                time_weight: float | None) -> tuple[dict, int, dict]:
    model = nominal(config)
    extra: dict[str, Any] = {}
    if method == "policy":
        res = _episode(config, target_m, seed,
                       lambda obs, _k: np.asarray(policy.act(obs[None]))[0])
        episodes = 1
    elif method == "mpc":
        settings = mpc or MPCSettings(seed=seed)
        env = MicroConveyorEnv(config=config)
        ep = MPC(model, settings, prior=policy).run(env, target_m, seed)
        env.close()
        res = {"error_m": ep.error_m, "outcome": ep.outcome, "success": ep.success,
               "sim_time_s": ep.time_s,
               "firings": _firings(ep.frequency_hz, ep.stroke_m, ep.delay_s)}
        episodes = ep.episodes + 1
        extra = {"mpc_first_budget": settings.first_budget,
                 "mpc_replan_budget": settings.replan_budget, "mpc_seeded": policy is not None}
    else:
        plan = solve_target(target_m, "de", budget, seed, config=model, time_weight=time_weight)
        res = _episode(config, target_m, seed, lambda _obs, k: plan.plan[k])
        episodes = plan.episodes + 1
        extra = {"budget": int(budget), "model_error_m": plan.error_m}
    return res, episodes, extra


def _place_scene(target: Any, method: str, config: Any, policy: Any, seed: int,
                 budget: int, time_weight: float | None) -> tuple[dict, int, dict]:
    """A placement on the positioner or the plane: the result, the episodes, the extra keys."""
    env = _Recorder(_scene_env(config))
    tg = target
    extra: dict[str, Any] = {}
    try:
        if method == "policy":
            res = _played(env, tg, seed, lambda obs, _k: np.asarray(policy.act(obs[None]))[0])
            episodes = 1
        elif method == "mpc" and geometry_of(config) == "plane":
            res, episodes = _plane_mpc(env, tg, seed, config)
            extra = {"mpc_model": "nominal"}
        elif method == "mpc":
            ctl = MPC(nominal(config))
            ep = ctl.run(env, tg, seed)   # the env, recording
            info = {"outcome": ep.outcome, "is_success": ep.success}
            res = _ending(env, info, ep.firings)
            episodes = ep.episodes + 1
            extra = {"mpc_model": getattr(ctl.settings, "model", None),
                     "estimated_friction_factor": float(ep.estimated_factors[0])}
        else:
            found = solve_target(tg, "de", budget, seed, config=nominal(config),
                                 firings=PLAN_FIRINGS, time_weight=time_weight)
            plan = found.plan
            res = _played(env, tg, seed,
                          lambda _obs, k: plan[k] if k < len(plan) else None)
            episodes = found.episodes + 1
            extra = {"budget": int(budget), "plan_firings": PLAN_FIRINGS,
                     "model_error_m": found.error_m}
    finally:
        env.env.close()
    return res, episodes, extra


def _plane_mpc(env: _Recorder, target: Any, seed: int, config: Any) -> tuple[dict, int]:
    """One episode of the plane's one-step controller on the nominal model (it sees the part's
    position, velocity, time and firings, never its factors or noise) until the episode ends
    or no firing brings the part closer: the result and the episodes (the controller's firings
    on its model and the placement)."""
    from ..planning.plane import PartStates, PlaneController

    ctl = PlaneController(nominal(config))

    def act(_obs: np.ndarray, _k: int) -> np.ndarray | None:
        a, ok, _ = ctl.choose(PartStates.of(env.env.conveyor.parts, [0]))
        return a[0] if ok[0] else None

    res = _played(env, target, seed, act)
    return res, ctl.scene.full_firings + 1


def place_text(r: dict[str, Any]) -> str:
    """A placement in the units people read: the plan, one line per firing, then the result
    and the compute."""
    if isinstance(r["target_m"], list):
        return _plane_text(r)
    scene = bool(r["firings"]) and "actuator_position_m" in r["firings"][0]
    lines = [f"{r['env_id']}, {r['method']} ({r['actor']}): target {r['target_m'] * 1e3:.3f} mm"]
    if scene:   # the positioner: any actuator fires, the part rests after each firing
        lines.append(f"{'firing':>6} {'actuator':>8} {'at [mm]':>8} {'frequency [Hz]':>14} "
                     f"{'stroke [µm]':>11} {'rest after [mm]':>15}")
        for k, f in enumerate(r["firings"], 1):
            lines.append(f"{k:6d} {f['actuator']:8d} {f['actuator_position_m'] * 1e3:8.3f} "
                         f"{f['frequency_hz']:14.1f} {f['stroke_m'] * 1e6:11.1f} "
                         f"{f['position_after_m'] * 1e3:15.4f}")
    else:
        lines.append(f"{'firing':>6} {'actuator':>8} {'frequency [Hz]':>14} {'stroke [µm]':>11} "
                     f"{'delay [µs]':>10}")
        for k, f in enumerate(r["firings"], 1):
            lines.append(f"{k:6d} {f['actuator']:8d} {f['frequency_hz']:14.1f} "
                         f"{f['stroke_m'] * 1e6:11.1f} {f['delay_s'] * 1e6:10.1f}")
    ok = "success" if r["success"] else "miss"
    lines.append(f"rest position {r['final_position_m'] * 1e3:.4f} mm, error "
                 f"{r['error_m'] * 1e6:+.1f} µm, {r['outcome']}: {ok} (±"
                 f"{r['tolerance_m'] * 1e6:g} µm), {_time_text(r)}")
    lines.append(_compute_text(r))
    return "\n".join(lines)


def _time_text(r: dict[str, Any]) -> str:
    """The placement time in ms, in words: until the part rests, or until the episode ended."""
    when = "placed in" if r["outcome"] == "rest" else "ended after"
    return f"{when} {r['placement_time_s'] * 1e3:.1f} ms"


def _compute_text(r: dict[str, Any]) -> str:
    what = (" (the controller's firings on its model and the placement)"
            if r["method"] == "mpc" and "mpc_model" in r else "")
    return (f"compute: {r['wall_time_s']:.2f} s wall, {r['episodes']} simulator "
            f"episode(s){what}")


def _mm2(p: list[float]) -> str:
    return f"({p[0] * 1e3:.3f}, {p[1] * 1e3:.3f})"


def _plane_text(r: dict[str, Any]) -> str:
    lines = [f"{r['env_id']}, {r['method']} ({r['actor']}): target {_mm2(r['target_m'])} mm",
             f"{'firing':>6} {'index':>8} {'at (x, y) [mm]':>16} {'frequency [Hz]':>14} "
             f"{'stroke [µm]':>11} {'delay [ms]':>10} {'after (x, y) [mm]':>18}"]
    for k, f in enumerate(r["firings"], 1):
        lines.append(f"{k:6d} {f['actuator_index']:8d} {_mm2(f['actuator_position_m']):>16} "
                     f"{f['frequency_hz']:14.1f} {f['stroke_m'] * 1e6:11.1f} "
                     f"{f['delay_s'] * 1e3:10.2f} {_mm2(f['position_after_m']):>18}")
    ok = "success" if r["success"] else "miss"
    lines.append(f"rest position {_mm2(r['final_position_m'])} mm, distance "
                 f"{r['error_m'] * 1e6:.1f} µm, {r['outcome']}: {ok} (±"
                 f"{r['tolerance_m'] * 1e6:g} µm), {_time_text(r)}")
    lines.append(_compute_text(r))
    return "\n".join(lines)
