"""One placement: carry one part to one target on the line with a chosen method and say what was
fired, where the part came to rest and what it cost.

* ``policy``: the env's default shipped policy (or a given one), closed loop, one episode.
* ``mpc``: model-predictive control (:class:`agents.mpc.control.MPC`) on the nominal model,
  every search seeded by that policy's plan; it re-plans after each firing from the part's
  observed state.
* ``de``: the open-loop plan of differential evolution on the nominal model
  (:func:`agents.openloop.target.solve_target`), then played once.

The part is placed in the env ``config`` as given: with per-episode randomisation on (execution
noise, friction and mass spread: :class:`.perturb.Level`) the planners still plan on the nominal
model and the episode shows how the plan holds. Compute: wall time [s] and the simulator
episodes spent (the placement itself included).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv
from microconveyor_env.envs.versions import nominal

from ..mpc import MPC, MPCSettings
from ..openloop.search import TARGET_BUDGET

METHODS = ("policy", "mpc", "de")
DE_BUDGET = TARGET_BUDGET   # DE episodes of the model (optimize's default for one target)


def _firings(freq: list[float], stroke: list[float], delay: list[float]) -> list[dict[str, Any]]:
    """The firings in order (SI): the line fires its actuators one after the other, from 1."""
    return [{"actuator": k + 1, "frequency_hz": f, "stroke_m": h, "delay_s": d}
            for k, (f, h, d) in enumerate(zip(freq, stroke, delay, strict=True))]


def _episode(config: EnvConfig, target: float, seed: int,
             act: Callable[[np.ndarray, int], np.ndarray]) -> dict[str, Any]:
    """One episode of ``config`` to ``target`` [m] (reset with ``seed``), firing ``act(obs, k)``
    at firing ``k``; the outcome and the firings as fired (execution noise included)."""
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


def place(target_m: float, method: str, config: EnvConfig, policy: Any = None, seed: int = 0,
          budget: int = DE_BUDGET, mpc: MPCSettings | None = None) -> dict[str, Any]:
    """Place one part at ``target_m`` [m, beyond actuator 1] in ``config`` with ``method``
    (:data:`METHODS`): ``policy`` acts (``policy``) or seeds the MPC (``mpc``; settings
    ``mpc``, default :class:`MPCSettings` with ``seed``); ``budget`` [episodes]: DE's search;
    ``seed`` [-]: the episode's and the searches'. The result (SI units): the firings (actuator,
    frequency, stroke, delay), the rest position and signed error, the outcome, success (at rest
    within the config's tolerance), the simulated time and the compute (``wall_time_s``,
    ``episodes``: every simulator episode, the placement's included)."""
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is invalid: must be one of {METHODS}")
    if method in ("policy", "mpc") and policy is None:
        raise ValueError(f"method {method!r} needs a policy")
    model = nominal(config)
    t0 = time.perf_counter()
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
                 "mpc_replan_budget": settings.replan_budget}
    else:
        from ..openloop.target import solve_target

        plan = solve_target(target_m, "de", budget, seed, config=model)
        res = _episode(config, target_m, seed, lambda _obs, k: plan.plan[k])
        episodes = plan.episodes + 1
        extra = {"budget": int(budget), "model_error_m": plan.error_m}
    return {"target_m": float(target_m), "method": method, "seed": int(seed), **res,
            "final_position_m": float(target_m) + res["error_m"],
            "tolerance_m": config.tolerance, "wall_time_s": time.perf_counter() - t0,
            "episodes": int(episodes), **extra}


def place_text(r: dict[str, Any]) -> str:
    """A placement in the units people read: the plan, one line per firing, then the result
    and the compute."""
    lines = [f"{r['env_id']}, {r['method']} ({r['actor']}): target {r['target_m'] * 1e3:.3f} mm",
             f"{'firing':>6} {'actuator':>8} {'frequency [Hz]':>14} {'stroke [µm]':>11} "
             f"{'delay [µs]':>10}"]
    for k, f in enumerate(r["firings"], 1):
        lines.append(f"{k:6d} {f['actuator']:8d} {f['frequency_hz']:14.1f} "
                     f"{f['stroke_m'] * 1e6:11.1f} {f['delay_s'] * 1e6:10.1f}")
    ok = "success" if r["success"] else "miss"
    lines.append(f"rest position {r['final_position_m'] * 1e3:.4f} mm, error "
                 f"{r['error_m'] * 1e6:+.1f} µm, {r['outcome']}: {ok} (±"
                 f"{r['tolerance_m'] * 1e6:.0f} µm)")
    lines.append(f"compute: {r['wall_time_s']:.2f} s wall, {r['episodes']} simulator "
                 f"episode(s)")
    return "\n".join(lines)
