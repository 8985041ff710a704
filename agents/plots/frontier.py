"""The frontier chart of one scene: the share of parts resting within ±50, ±20, ±10 and ±5 µm of
their target against the placement time, one panel per radius and perturbation level, one curve
per method through the requests it was run at (from the stored JSON of
:mod:`agents.experiments.frontier`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import pyplot

RADII_UM = (50, 20, 10, 5)
LEVEL_TITLES = {"nominal": "nominal", "perturbed": "σ = 3e-3, r = 5 %"}


def plot_frontier(data: dict[str, Any], path: str | Path) -> Path:
    """Draw ``data`` (``{"env_id", "rows", "time_bound_s"?}``) to ``path``: x the median placement
    time [ms] (a marker; a thin line from it to the 90th percentile), y the share within the
    panel's radius [%]; a method's markers joined in the order of its requests, the tightest
    request marked largest. ``time_bound_s``: a lower bound on the median target's placement
    time [s], drawn as a vertical line."""
    plt = pyplot()
    rows = [r for r in data.get("rows", []) if r.get("median_placement_time_s") is not None]
    levels = [lv for lv in LEVEL_TITLES if any(r["level"] == lv for r in data.get("rows", []))]
    levels = levels or ["nominal"]
    methods = list(dict.fromkeys(r["method"] for r in data.get("rows", [])))
    colours = {m: plt.get_cmap("tab10")(i % 10) for i, m in enumerate(methods)}
    fig, axes = plt.subplots(len(levels), len(RADII_UM), figsize=(3.2 * len(RADII_UM),
                             3.0 * len(levels) + 0.8), sharex=True, sharey=True, squeeze=False)
    bound = data.get("time_bound_s")
    for i, level in enumerate(levels):
        for j, radius in enumerate(RADII_UM):
            ax = axes[i][j]
            for m in methods:
                mine = sorted((r for r in rows if r["level"] == level and r["method"] == m),
                              key=lambda r: -r["request_tolerance_m"])
                if not mine:
                    continue
                x = [1e3 * r["median_placement_time_s"] for r in mine]
                y = [100 * r[f"success_rate_{radius}um"] for r in mine]
                sizes = [12 + 4 * (50e-6 / r["request_tolerance_m"]) for r in mine]
                ax.plot(x, y, "-", color=colours[m], lw=1.0, alpha=0.7)
                ax.scatter(x, y, s=sizes, color=colours[m], zorder=3,
                           label=m if (i, j) == (0, 0) else None)
                for r, xi, yi in zip(mine, x, y, strict=True):
                    ax.plot([xi, 1e3 * r["p90_placement_time_s"]], [yi, yi], color=colours[m],
                            lw=0.6, alpha=0.5)
            if bound is not None:
                ax.axvline(1e3 * bound, color="k", ls=":", lw=1.0,
                           label="time bound (median target)" if (i, j) == (0, 0) else None)
            ax.set_ylim(-3, 103)
            ax.grid(alpha=0.3)
            ax.set_title(f"{LEVEL_TITLES[level]}: within ±{radius} µm", fontsize=9)
            if i == len(levels) - 1:
                ax.set_xlabel("placement time [ms] (median — p90)")
            if j == 0:
                ax.set_ylabel("parts within [%]")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5) or 1, fontsize=8,
               frameon=False)
    fig.suptitle(f"{data.get('env_id', '')}: precision against placement time (one curve per "
                 "method through its requests; the larger the marker, the tighter the request)",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.08, 1, 0.96))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
