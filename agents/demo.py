"""The policy part of ``microconveyor demo``: the shipped PPO policy on a handful of targets,
a table (target, final position, error, time, success) and a chart of the trajectories."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from microconveyor_env.envs import EnvConfig

from .evaluate import load_policy, rollout


def load_demo_policy(policy_path=None):
    """The demo's policy (default: the shipped one), loaded before any other work so that a bad
    ``--policy`` fails at once."""
    from .policy import shipped_path

    return load_policy(policy_path or shipped_path(), EnvConfig.from_yaml())


def policy_demo(out_dir, policy=None, n_targets: int = 6) -> dict:
    """The demo's policy part; ``policy`` a loaded :class:`~.policy_files.Policy` or a path
    (default: the shipped policy)."""
    cfg = EnvConfig.from_yaml()
    pol = policy if hasattr(policy, "act") else load_demo_policy(policy)
    targets = np.linspace(*cfg.target_range, n_targets)
    res = rollout(pol, targets, cfg, seed=0, record=True)
    rows = []
    for i, tgt in enumerate(targets):
        err = float(res["error_m"][i])
        rows.append({"target_m": float(tgt), "final_position_m": float(tgt + err),
                     "error_m": err, "time_s": float(res["time_s"][i]),
                     "outcome": str(res["outcome"][i]),
                     "success": bool(res["outcome"][i] == "rest" and abs(err) <= cfg.tolerance)})
    chart = plot_trajectories(res, cfg, Path(out_dir) / "policy.png")
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


def plot_trajectories(res: dict, cfg: EnvConfig, path: Path) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, tgt in enumerate(res["targets_m"]):
        k = int(res["firings"][i]) + 1  # the start and the position after each firing made
        line, = ax.plot(np.arange(k), res["path_m"][:k, i] * 1e3, "o-", ms=3)
        ax.axhline(tgt * 1e3, color=line.get_color(), ls=":", lw=0.8)
    for xa in cfg.actuator_positions:
        ax.axhline(xa * 1e3, color="0.85", lw=0.6, zorder=0)
    ax.set_xlabel("firings (the conveyor stops once the part is delivered)")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_ylabel("part position [mm] (dotted: targets, grey: actuators)")
    ax.set_title("Shipped PPO policy: position after each firing (at its end: at rest)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)
