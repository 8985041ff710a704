"""The policy part of ``microconveyor demo``: the shipped PPO policy on a handful of targets,
a table (target, final position, error, time, success) and a chart of the trajectories."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from microconveyor_env.envs import EnvConfig

from ..plots.trajectories import plot_policy_paths
from ..rl.evaluation.evaluate import Policy, load_policy, rollout


def load_demo_policy(policy_path: str | Path | None = None, config: EnvConfig | None = None,
                     env_id: str = "MicroConveyor-v0") -> Policy:
    """The demo's policy (default: the one shipped for ``env_id``) for the scene ``config``
    (default: ``env_id``'s defaults), loaded before any other work so that a bad ``--policy``
    (or one of another scene) fails at once."""
    from microconveyor_env.envs import env_config

    from ..rl.artefacts.shipped import require_shipped

    return load_policy(policy_path or require_shipped(env_id), config or env_config(env_id))


def policy_demo(out_dir: str | Path, policy: Policy | str | Path | None = None,
                n_targets: int = 6, config: EnvConfig | None = None) -> dict:
    """The demo's policy part on ``config`` (default: MicroConveyor-v0's); ``policy`` a loaded
    :class:`~.policy_files.Policy` or a path (default: the shipped policy)."""
    cfg = config or EnvConfig.from_yaml()
    pol = policy if isinstance(policy, Policy) else load_demo_policy(policy, cfg)
    lo, hi = cfg.target_range
    targets = np.linspace(lo, hi, n_targets)
    res = rollout(pol, targets, cfg, seed=0, record=True)
    rows = []
    for i, tgt in enumerate(targets):
        err = float(res["error_m"][i])
        rows.append({"target_m": float(tgt), "final_position_m": float(tgt + err),
                     "error_m": err, "time_s": float(res["time_s"][i]),
                     "outcome": str(res["outcome"][i]),
                     "success": bool(res["outcome"][i] == "rest" and abs(err) <= cfg.tolerance)})
    chart = plot_policy_paths(res, cfg, Path(out_dir) / "policy.png")
    return {"policy": str(pol.path), "trained_steps": pol.metadata.get("steps"),
            "tolerance_m": cfg.tolerance, "rows": rows, "chart": chart}


def table(demo: dict) -> str:
    lines = [f"policy {demo['policy']} ({demo['trained_steps']} steps)",
             f"{'target [mm]':>11} {'final [mm]':>10} {'error [um]':>10} {'time [s]':>8}  success"]
    for r in demo["rows"]:
        lines.append(f"{r['target_m'] * 1e3:11.3f} {r['final_position_m'] * 1e3:10.3f} "
                     f"{r['error_m'] * 1e6:10.1f} {r['time_s']:8.3f}  "
                     f"{'yes' if r['success'] else 'no (' + r['outcome'] + ')'}")
    return "\n".join(lines)
