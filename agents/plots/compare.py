"""Charts of :mod:`.compare`: accuracy against compute, success against tolerance, success
against perturbation."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .common import pyplot

LABELS = {"ppo": "PPO (shipped)", "ppo_randomised": "PPO trained with randomisation",
          "random": "random policy", "fixed_schedule": "fixed schedule (950 Hz, 200 µm)",
          "de": "DE (open loop)", "cmaes": "CMA-ES (open loop)"}
COLORS = {"ppo": "C0", "ppo_randomised": "C4", "random": "C7", "fixed_schedule": "C5",
          "de": "C1", "cmaes": "C2"}
# one marker shape per method, so points that coincide (e.g. several methods at 0 %) stay
# distinguishable
MARKERS = {"ppo": "s", "ppo_randomised": "P", "random": "X", "fixed_schedule": "^",
           "de": "o", "cmaes": "D"}


def _label(key: str) -> str:
    base, _, rest = key.partition("_")
    if key in LABELS:
        return LABELS[key]
    if base in ("de", "cmaes"):
        budget = rest.replace("_plan", "")
        return f"{LABELS[base]}, {budget} episodes"
    return key


def _color(key: str) -> str:
    return COLORS.get(key, COLORS.get(key.partition("_")[0], "k"))


def _marker(key: str) -> str:
    return MARKERS.get(key, MARKERS.get(key.partition("_")[0], "o"))


def _tolerance_line(ax: Any, value: float, horizontal: bool) -> None:
    """The env's tolerance as a dotted line that says what it is."""
    if horizontal:
        ax.axhline(value, color="k", ls=":", lw=1)
        ax.annotate(f"±{value:.0f} µm tolerance", (0.99, value), xycoords=("axes fraction", "data"),
                    ha="right", va="bottom", fontsize=7)
    else:
        ax.axvline(value, color="k", ls=":", lw=1)
        ax.annotate(f"env tolerance ±{value:.0f} µm", (value, 1), rotation=90, fontsize=7,
                    xycoords=("data", "axes fraction"), ha="right", va="top",
                    xytext=(-3, -4), textcoords="offset points")


def accuracy_vs_compute(result: dict, path: str | Path) -> str:
    """Median |error| and success against wall time per target (log axes)."""
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12.5, 3.8), layout="constrained")
    tol = 1e6 * result["tolerance_m"]
    for method in ("de", "cmaes"):
        rs = [r for r in result["rows"] if r["method"] == method]
        if not rs:
            continue
        w = [r["wall_s_per_target"] for r in rs]
        a.loglog(w, [1e6 * r["median_abs_error_m"] for r in rs], "o-", color=_color(method),
                 label=LABELS[method])
        b.semilogx(w, [100 * r["success_rate"] for r in rs], "o-", color=_color(method),
                   label=LABELS[method])
        for r in rs:
            a.annotate(f"{r['budget']}", (r["wall_s_per_target"], 1e6 * r["median_abs_error_m"]),
                       fontsize=7, xytext=(3, 3), textcoords="offset points")
    for r in result["rows"]:
        if "budget" in r:
            continue
        m = r["method"]
        a.loglog(r["wall_s_per_target"], 1e6 * r["median_abs_error_m"], _marker(m),
                 color=_color(m), label=LABELS.get(m, m), alpha=0.85)
        b.semilogx(r["wall_s_per_target"], 100 * r["success_rate"], _marker(m), color=_color(m),
                   alpha=0.85)
        if m == "ppo":
            am = result["ppo_amortised"]
            a.loglog(am["wall_s_per_target"], 1e6 * r["median_abs_error_m"], "D", mfc="none",
                     color=_color(m), label=f"PPO incl. training / {am['over_targets']} targets")
            b.semilogx(am["wall_s_per_target"], 100 * r["success_rate"], "D", mfc="none",
                       color=_color(m))
    _tolerance_line(a, tol, horizontal=True)
    a.set(xlabel="wall time per target [s] (2 cores)", ylabel="median |final error| [µm]",
          title="accuracy against compute (labels: episodes per target)")
    b.set(xlabel="wall time per target [s] (2 cores)", ylabel=f"success within ±{tol:.0f} µm [%]",
          ylim=(-2, 102), title=f"success against compute ({result['rows'][0]['n_targets']} targets)")
    fig.legend(*a.get_legend_handles_labels(), fontsize=7, loc="outside right upper")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def success_vs_tolerance(result: dict, path: str | Path) -> str:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.4, 4), layout="constrained")
    tols = 1e6 * np.asarray(result["tolerance"]["tolerances_m"])
    budgets = sorted({r["budget"] for r in result["rows"] if "budget" in r})
    for key, rates in result["tolerance"]["success_rate"].items():
        method, _, b = key.partition("_")
        if method in ("de", "cmaes") and b and int(b) not in (budgets[0], budgets[-1]):
            continue
        ls = "--" if method in ("de", "cmaes") and b and int(b) == budgets[0] else "-"
        ax.semilogx(tols, 100 * np.asarray(rates), ls, color=_color(key), label=_label(key))
    _tolerance_line(ax, 1e6 * result["tolerance_m"], horizontal=False)
    ax.set(xlabel="tolerance [µm]", ylabel="success [%] (at rest within the tolerance)",
           ylim=(-2, 102), title="success against tolerance (performance profile)")
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="outside right upper")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def success_vs_perturbation(result: dict, path: str | Path) -> str:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 3.8), layout="constrained")
    titles = {"action_noise": ("execution noise σ [action units]", "actions executed with noise"),
              "spread": ("friction and mass factors in [1 − r, 1 + r]: r [-]",
                         "model error (friction, mass)")}
    for ax, axis in zip(axes, ("action_noise", "spread"), strict=True):
        names = list(result["perturbation"])
        for k, (name, tables) in enumerate(result["perturbation"].items()):
            rows = tables[axis]
            # methods side by side at each level (a few % in log x) so markers do not overlap
            x = np.array([r[axis] for r in rows], float) * 1.06 ** (k - (len(names) - 1) / 2)
            y = 100 * np.array([r["success_rate"] for r in rows])
            lo = 100 * np.array([r["success_ci95"][0] for r in rows])
            hi = 100 * np.array([r["success_ci95"][1] for r in rows])
            xp = np.where(x > 0, x, np.nan)
            ax.semilogx(xp, y, "-", marker=_marker(name), color=_color(name), label=_label(name))
            ax.fill_between(xp, lo, hi, color=_color(name), alpha=0.15, lw=0)
            ax.axhline(y[0], color=_color(name), ls=":", lw=0.8)  # unperturbed level
        xlabel, title = titles[axis]
        from matplotlib.ticker import NullFormatter

        ax.xaxis.set_minor_formatter(NullFormatter())  # labels at the decades only
        ax.set(xlabel=xlabel, ylabel="success within ±50 µm [%]", ylim=(-2, 102),
               title=f"{title} (dotted: unperturbed)")
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="outside right upper")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def plot_all(result: dict, tolerance: str | Path, compute: str | Path,
             perturbation: str | Path) -> list[str]:
    """The three charts, at the three paths given."""
    Path(tolerance).parent.mkdir(parents=True, exist_ok=True)
    return [success_vs_tolerance(result, Path(tolerance)),
            accuracy_vs_compute(result, Path(compute)),
            success_vs_perturbation(result, Path(perturbation))]
