"""What the comparisons of every scene share (:mod:`.compare`, on the line and the positioner):
a method's row from its per-target results, a closed-loop policy's row, the episodes a search
needed to reach the tolerance, the tolerances success is read at, and a rollout function that
does not replay the unperturbed episodes its row already played."""
from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microconveyor_env.envs import EnvConfig

from ..mpc.harness import LOST
from ..rl.evaluation.evaluate import placement_times, rollout
from .perturb import Level

# success against tolerance is read off the final errors at these tolerances [m]
TOLERANCES = tuple(float(t) for t in np.geomspace(1e-8, 1e-3, 51))


# the names of the comparison's other rows (and the prefixes of its open-loop and MPC rows)
OTHER_ROWS = frozenset({"ppo_randomised", "random", "fixed_schedule"})
OPEN_LOOP = ("de", "cmaes")


def policy_row_name(metadata: dict, path: str | Path | None = None) -> str:
    """The name of a policy's row: its folder's name (``ppo_refined`` for the shipped
    ``MicroConveyor-v1/ppo_refined``; a run folder's own name), prefixed ``policy_`` where that
    would read as another row's (``random``, ``mpc...``, ``de...``, ...); without a folder, how
    it was trained (``ppo``; ``dagger``: by imitation)."""
    if path is None:
        return str(metadata.get("trained_by", "ppo"))
    name = Path(path).resolve().name if Path(path).name in ("", ".", "..") else Path(path).name
    if name in OTHER_ROWS or name.startswith("mpc") or name.split("_")[0] in OPEN_LOOP:
        return f"policy_{name}"
    return name


def seeded_mpc_name(prior: str | Path, taken: Collection[str] = ()) -> str:
    """The name of the MPC row seeded by the policy folder ``prior``: ``mpc_<folder name>``
    (``mpc_ppo_refined``), ``mpc_seeded_<folder name>`` where that is a name in ``taken``."""
    name = f"mpc_{Path(prior).name or Path(prior).resolve().name}"
    return f"mpc_seeded_{name[4:]}" if name in taken else name


def result_row(name: str, res: dict, targets: np.ndarray, tol: float, **extra: Any) -> dict:
    """A method's row: success within ``tol`` [m] at rest, median |error|, detach rate, the
    placement time of the parts at rest (the simulated time until they rested, ``time_s`` of
    ``res``): its median ``median_placement_time_s`` (also ``median_travel_time_s``, the name of
    the stored comparisons) and 90th percentile ``p90_placement_time_s`` [s], every |error| and
    rest flag, and ``extra`` (SI units)."""
    err = np.asarray(res["error_m"], float)
    outcome = np.asarray(res["outcome"])
    rest = outcome == "rest"
    ok = rest & (np.abs(err) <= tol)
    t = np.asarray(res["time_s"], float)
    lost = outcome == LOST   # MPC episodes whose worker process died (failures)
    if lost.any():
        extra["lost_episodes"] = int(lost.sum())
    return {"method": name, "n_targets": int(len(targets)), "success_rate": float(ok.mean()),
            "median_abs_error_m": float(np.median(np.abs(err[~lost]))) if (~lost).any()
            else None,
            "detach_rate": float(np.mean(np.asarray(res["outcome"]) == "detached")),
            "median_travel_time_s": float(np.median(t[rest])) if rest.any() else None,
            **placement_times(t, outcome),
            "abs_error_m": np.abs(err).tolist(), "rest": rest.tolist(), **extra}


def closed_loop_row(name: str, policy: Any, targets: np.ndarray, cfg: EnvConfig, seed: int, /,
                    **extra: Any) -> dict:
    """A policy's row: one batched rollout of every target (sub-env ``i`` seeded ``seed + i``),
    its wall time per target, and ``extra`` (e.g. ``policy``: its folder)."""
    t0 = time.perf_counter()
    res = rollout(policy, targets, cfg, seed=seed)
    wall = time.perf_counter() - t0
    return result_row(name, res, targets, cfg.tolerance,
                      wall_s_per_target=wall / len(targets), episodes_per_target=1, **extra)


def episodes_to(history_episodes: Sequence[int], history_best: Sequence[float | None],
                tolerance: float) -> int | None:
    """The episodes a search had used when its best part at rest first came within
    ``tolerance`` [m]; None if it never did."""
    for e, best in zip(history_episodes, history_best, strict=True):
        if best is not None and best <= tolerance:
            return int(e)
    return None


def reusing(run: Callable, cfg: EnvConfig, targets: np.ndarray, seed: int,
            result: dict) -> Callable:
    """``run``, except that the unperturbed level's call (``cfg`` without randomisation, these
    targets, ``seed``: the episodes the table's row already played) returns ``result``: an
    expensive method (MPC) is not played twice on the same episodes."""
    base = Level().config(cfg)

    def wrapped(config: EnvConfig, tg: np.ndarray, s: int) -> dict:
        if s == seed and config == base and np.array_equal(tg, targets):
            return result
        return run(config, tg, s)

    return wrapped
