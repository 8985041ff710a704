"""Trajectories: of open-loop plans in time (position and velocity, cf. the dissertation's
Fig. 4.13), and of a policy's episodes firing by firing."""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from microconveyor_env.envs import EnvConfig

from .common import pyplot


def plot_plan_trajectories(runs: Mapping[str, Mapping[str, np.ndarray]], path: str,
                      target_m: float | None = None, spacing: Mapping[str, float] | None = None,
                      title: str = "") -> str:
    """Position and velocity against time, one line per run ``{label: {"t_s", "x_m",
    "v_m_s"}}`` (cf. Fig. 4.13); the target as a dashed line."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 6), sharex=True)
    for label, tr in runs.items():
        a1.plot(tr["t_s"] * 1e3, tr["x_m"] * 1e3, label=label)
        a2.plot(tr["t_s"] * 1e3, tr["v_m_s"], label=label)
    if target_m is not None:
        a1.axhline(target_m * 1e3, color="k", ls="--", lw=0.8, label="target")
    a1.set_ylabel("position x [mm]")
    a2.set_ylabel("velocity [m/s]")
    a2.set_xlabel("time [ms]")
    for ax in (a1, a2):
        ax.grid(True, alpha=0.3)
    a1.legend(fontsize=7)
    a1.set_title(title or "Trajectory and velocity of the optimum (cf. Fig. 4.13)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_policy_paths(res: dict, cfg: EnvConfig, path: Path,
                      title: str = "Shipped PPO policy: position after each firing") -> str:
    """A policy's episodes: the part's position after each firing, one line per target
    (``res`` from :func:`agents.rl.evaluation.evaluate.rollout` with ``record=True``)."""
    plt = pyplot()

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
    ax.set_title(f"{title} (at its end: at rest)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def plot_policy_errors(rows: list[dict], tolerance: float, path: Path,
                       title: str = "Final error per target") -> str:
    """A policy's final error [µm] per target [mm] (``rows``: ``target_m``, ``error_m``,
    ``outcome``), the tolerance band shaded; an episode not at rest is drawn as a cross."""
    plt = pyplot()

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    tol = tolerance * 1e6
    ax.axhspan(-tol, tol, color="0.9", zorder=0, label=f"±{tol:.0f} µm")
    ax.axhline(0.0, color="0.6", lw=0.6)
    for rest, marker in ((True, "o"), (False, "x")):
        pts = [(r["target_m"] * 1e3, r["error_m"] * 1e6) for r in rows
               if (r["outcome"] == "rest") == rest]
        if pts:
            x, y = zip(*pts, strict=True)
            ax.plot(x, y, marker, ls="", label="at rest" if rest else "not at rest")
    ax.set_xlabel("target [mm]")
    ax.set_ylabel("final error [µm]")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)
