"""Charts of :mod:`.compare`: accuracy against compute, success against tolerance, success
against perturbation."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import pyplot

LABELS = {"ppo": "PPO (shipped)", "ppo_randomised": "PPO trained with randomisation",
          "random": "random policy", "fixed_schedule": "fixed schedule (950 Hz, 200 µm)",
          "de": "DE (open loop)", "cmaes": "CMA-ES (open loop)"}
COLORS = {"ppo": "C0", "ppo_randomised": "C4", "random": "C7", "fixed_schedule": "C5",
          "de": "C1", "cmaes": "C2"}


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


def accuracy_vs_compute(result: dict, path: str | Path) -> str:
    """Median |error| and success against wall time per target (log axes)."""
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
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
        a.loglog(r["wall_s_per_target"], 1e6 * r["median_abs_error_m"], "s", color=_color(m),
                 label=LABELS.get(m, m))
        b.semilogx(r["wall_s_per_target"], 100 * r["success_rate"], "s", color=_color(m))
        if m == "ppo":
            am = result["ppo_amortised"]
            a.loglog(am["wall_s_per_target"], 1e6 * r["median_abs_error_m"], "D", mfc="none",
                     color=_color(m), label=f"PPO incl. training / {am['over_targets']} targets")
            b.semilogx(am["wall_s_per_target"], 100 * r["success_rate"], "D", mfc="none",
                       color=_color(m))
    a.axhline(tol, color="k", ls=":", lw=1)
    a.set(xlabel="wall time per target [s] (2 cores)", ylabel="median |final error| [µm]",
          title="accuracy against compute (labels: episodes per target)")
    b.set(xlabel="wall time per target [s] (2 cores)", ylabel=f"success within ±{tol:.0f} µm [%]",
          ylim=(-2, 102), title=f"success against compute ({result['rows'][0]['n_targets']} targets)")
    a.legend(fontsize=7, loc="lower left")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def success_vs_tolerance(result: dict, path: str | Path) -> str:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4), constrained_layout=True)
    tols = 1e6 * np.asarray(result["tolerance"]["tolerances_m"])
    budgets = sorted({r["budget"] for r in result["rows"] if "budget" in r})
    for key, rates in result["tolerance"]["success_rate"].items():
        method, _, b = key.partition("_")
        if method in ("de", "cmaes") and b and int(b) not in (budgets[0], budgets[-1]):
            continue
        ls = "--" if method in ("de", "cmaes") and b and int(b) == budgets[0] else "-"
        ax.semilogx(tols, 100 * np.asarray(rates), ls, color=_color(key), label=_label(key))
    ax.axvline(1e6 * result["tolerance_m"], color="k", ls=":", lw=1)
    ax.set(xlabel="tolerance [µm]", ylabel="success [%] (at rest within the tolerance)",
           ylim=(-2, 102), title="success against tolerance (env tolerance dotted)")
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def success_vs_perturbation(result: dict, path: str | Path) -> str:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    titles = {"action_noise": ("execution noise σ [action units]", "actions executed with noise"),
              "spread": ("friction and mass factors in [1 − r, 1 + r]: r [-]",
                         "model error (friction, mass)")}
    for ax, axis in zip(axes, ("action_noise", "spread"), strict=True):
        for name, tables in result["perturbation"].items():
            rows = tables[axis]
            x = np.array([r[axis] for r in rows], float)
            y = 100 * np.array([r["success_rate"] for r in rows])
            lo = 100 * np.array([r["success_ci95"][0] for r in rows])
            hi = 100 * np.array([r["success_ci95"][1] for r in rows])
            xp = np.where(x > 0, x, np.nan)
            ax.semilogx(xp, y, "o-", color=_color(name), label=_label(name))
            ax.fill_between(xp, lo, hi, color=_color(name), alpha=0.15, lw=0)
            ax.axhline(y[0], color=_color(name), ls=":", lw=0.8)  # unperturbed level
        xlabel, title = titles[axis]
        ax.set(xlabel=xlabel, ylabel="success within ±50 µm [%]", ylim=(-2, 102),
               title=f"{title} (dotted: unperturbed)")
    axes[0].legend(fontsize=7)
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
