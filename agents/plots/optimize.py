"""Charts of the optimisers: the dissertation's cost history (its Fig. 4.11), a per-target
best-error history, and budget versus error (trajectories: :mod:`.trajectories`)."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .common import pyplot


def plot_cost_history(history: Mapping[str, tuple[Sequence[int], Sequence[float]]],
                      path: str, title: str = "") -> str:
    """Best cost so far after each generation against the episodes used, one line per run:
    ``{label: (episodes, best cost)}`` (one point per generation: for the dissertation's DE,
    50 episodes each, so the x axis is 50 x the generation of its Fig. 4.11)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for label, (episodes, cost) in history.items():
        ax.semilogy(episodes, cost, "o-", ms=3, label=label)
    ax.set_xlabel("episodes (one point per generation)")
    ax.set_ylabel("best cost so far")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title or "Dissertation problem: best cost per generation (cf. Fig. 4.11)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_error_history(episodes: Sequence[int], best_abs_error_m: Sequence[float | None],
                       tolerance_m: float, path: str, title: str = "") -> str:
    """Best |error| at rest so far against episodes used (one point per generation)."""
    plt = pyplot()
    e = np.array(episodes, float)
    err = np.array([np.nan if v is None else max(v, 1e-9) for v in best_abs_error_m], float)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.semilogy(e, err * 1e6, "-")
    ax.axhline(tolerance_m * 1e6, color="k", ls="--", lw=0.8, label="tolerance")
    ax.set_xlabel("episodes")
    ax.set_ylabel("best |error| at rest [µm]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_budget_errors(rows: Sequence[Mapping[str, Any]], path: str, tolerance_m: float) -> str:
    """Median |error| and success rate against budget, one line per method; ``rows``: dicts
    with ``method``, ``budget``, ``median_abs_error_m``, ``success_rate``."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6.5, 6), sharex=True)
    for method in sorted({r["method"] for r in rows}):
        rs = sorted((r for r in rows if r["method"] == method), key=lambda r: r["budget"])
        b = [r["budget"] for r in rs]
        a1.loglog(b, [max(r["median_abs_error_m"], 1e-10) * 1e6 for r in rs], "o-", label=method)
        a2.semilogx(b, [100 * r["success_rate"] for r in rs], "o-", label=method)
    a1.axhline(tolerance_m * 1e6, color="k", ls="--", lw=0.8, label="tolerance")
    a1.set_ylabel("median best |error| [µm]")
    a2.set_ylabel(f"success within ±{tolerance_m * 1e6:g} µm [%]")
    a2.set_xlabel("budget [episodes per target]")
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
