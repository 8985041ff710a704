"""Charts of the comparison's result (:func:`agents.experiments.compare.compare`): accuracy
against compute, success against tolerance, the ECDF of the episodes a search needs to reach the
tolerance, success against perturbation along each axis, and the full (σ, r) grid."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .common import pyplot

LABELS = {"ppo": "PPO (shipped)", "ppo_randomised": "PPO trained with randomisation",
          "ppo_refined": "PPO refined on the simulator (shipped)",
          "mpc": "MPC (re-plans after each firing)",
          "mpc_ppo": "MPC seeded by the PPO's plan",
          "mpc_ppo_refined": "MPC seeded by ppo_refined's plan",
          "mpc_robust": "robust adaptive MPC (noisy copies, identifies friction)",
          "random": "random policy", "fixed_schedule": "fixed schedule (950 Hz, 200 µm)",
          "de": "DE (open loop)", "cmaes": "CMA-ES (open loop)",
          "mpc_identified": "model-based, friction identified online",
          "mpc_nominal": "model-based, nominal model",
          "mpc_oracle": "reference (knows the hidden factors): model-based, true factors",
          "dagger": "policy trained by DAgger (shipped)"}
COLORS = {"ppo": "C0", "ppo_randomised": "C4", "ppo_refined": "C0", "mpc": "C3", "mpc_ppo": "C8",
          "mpc_ppo_refined": "C8", "mpc_robust": "C9", "random": "C7", "fixed_schedule": "C5",
          "de": "C1", "cmaes": "C2", "mpc_identified": "C3", "mpc_nominal": "C6",
          "mpc_oracle": "k", "dagger": "C0"}
# one marker shape per method, so points that coincide (e.g. several methods at 0 %) stay
# distinguishable
MARKERS = {"ppo": "s", "ppo_randomised": "P", "ppo_refined": "s", "mpc": "*", "mpc_ppo": "p",
           "mpc_ppo_refined": "p", "mpc_robust": "h", "random": "X", "fixed_schedule": "^",
           "de": "o", "cmaes": "D", "mpc_identified": "*", "mpc_nominal": "v", "mpc_oracle": "x",
           "dagger": "s"}


def _seeded(key: str) -> bool:
    """Whether ``key`` names an MPC seeded by a policy's plan (``mpc_<policy folder>``) that
    the tables do not name."""
    return key.startswith("mpc_") and key not in LABELS


def _label(key: str) -> str:
    base, _, rest = key.partition("_")
    if key in LABELS:
        return LABELS[key]
    if base in ("de", "cmaes"):
        budget = rest.replace("_plan", "")
        return f"{LABELS[base]}, {budget} episodes"
    if _seeded(key):
        return f"MPC seeded by {key.removeprefix('mpc_seeded_').removeprefix('mpc_')}'s plan"
    return key   # a policy's row: its folder's name


def _color(key: str) -> str:
    if _seeded(key):
        return COLORS["mpc_ppo"]
    return COLORS.get(key, COLORS.get(key.partition("_")[0], "k"))


def _marker(key: str) -> str:
    if _seeded(key):
        return MARKERS["mpc_ppo"]
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
        if r is result["rows"][0] and "train_wall_s" in r and "ppo_amortised" in result:
            am = result["ppo_amortised"]
            a.loglog(am["wall_s_per_target"], 1e6 * r["median_abs_error_m"], "D", mfc="none",
                     color=_color(m), label=f"{LABELS.get(m, m)} incl. training / "
                                              f"{am['over_targets']} targets")
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


def _level_label(row: dict) -> str:
    parts = []
    if row["action_noise"]:
        parts.append(f"σ={row['action_noise']:g}")
    if row["spread"]:
        parts.append(f"r={100 * row['spread']:g}%")
    return ", ".join(parts) or "none"


def success_vs_perturbation(result: dict, path: str | Path) -> str:
    """Success against each perturbation axis (noise, model error, both on the diagonal), 95 %
    Wilson bands; methods side by side at each level so markers do not overlap."""
    plt = pyplot()
    axes_names = [a for a in ("action_noise", "spread", "combined")
                  if a in next(iter(result["perturbation"].values()))]
    fig, axes = plt.subplots(1, len(axes_names), figsize=(5.2 * len(axes_names), 3.9),
                             layout="constrained", squeeze=False)
    titles = {"action_noise": "execution noise σ [action units]",
              "spread": "model error: friction, mass in [1 − r, 1 + r]",
              "combined": "both (the diagonal of the grid)"}
    names = list(result["perturbation"])
    for ax, axis in zip(axes[0], axes_names, strict=True):
        for k, name in enumerate(names):
            rows = result["perturbation"][name][axis]
            x = np.arange(len(rows)) + 0.6 * (k - (len(names) - 1) / 2) / max(len(names), 1)
            y = 100 * np.array([r["success_rate"] for r in rows])
            lo = 100 * np.array([r["success_ci95"][0] for r in rows])
            hi = 100 * np.array([r["success_ci95"][1] for r in rows])
            ax.errorbar(x, y, yerr=[y - lo, hi - y], fmt=_marker(name) + "-", color=_color(name),
                        label=_label(name), ms=5, lw=1, capsize=2, alpha=0.9)
        seeds = result.get("seeds")
        if seeds:
            rows = seeds["perturbation"][axis]
            x = np.arange(len(rows)) + 0.34
            y = 100 * np.array([r["iqm"] for r in rows])
            ci = 100 * np.array([r["ci95"] for r in rows])
            ax.errorbar(x, y, yerr=[y - ci[:, 0], ci[:, 1] - y], fmt="s--", mfc="none",
                        color=_color("ppo"), ms=5, lw=1, capsize=2,
                        label=f"PPO, IQM of {len(seeds['policies'])} seeds")
        labels = [_level_label(r) for r in result["perturbation"][names[0]][axis]]
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=7)
        ax.set(xlabel=titles[axis], ylabel=f"success within ±{1e6 * result['tolerance_m']:.0f} µm [%]",
               ylim=(-2, 102))
    n = result["rows"][0]["n_targets"]
    fig.suptitle(f"success against perturbation ({n} targets; bars: 95 % Wilson intervals)",
                 fontsize=10)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="outside right upper")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def perturbation_grid(result: dict, path: str | Path) -> str | None:
    """With the full grid: success [%] of each method at every (σ, r), as heat maps."""
    names = [n for n, t in result["perturbation"].items() if "grid" in t]
    if not names:
        return None
    plt = pyplot()
    cols = min(4, len(names))
    rows_n = -(-len(names) // cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(3.4 * cols, 3.0 * rows_n),
                             layout="constrained", squeeze=False)
    for ax in axes.ravel()[len(names):]:
        ax.set_visible(False)
    im = None
    for ax, name in zip(axes.ravel(), names, strict=False):
        grid = result["perturbation"][name]["grid"]
        sig = sorted({r["action_noise"] for r in grid})
        rr = sorted({r["spread"] for r in grid})
        z = np.full((len(sig), len(rr)), np.nan)
        for r in grid:
            z[sig.index(r["action_noise"]), rr.index(r["spread"])] = 100 * r["success_rate"]
        im = ax.imshow(z, origin="lower", vmin=0, vmax=100, cmap="viridis", aspect="auto")
        for (i, j), v in np.ndenumerate(z):
            ax.text(j, i, f"{v:.0f}", ha="center", va="center", fontsize=7,
                    color="w" if v < 60 else "k")
        ax.set_xticks(range(len(rr)), [f"{100 * r:g}" for r in rr], fontsize=7)
        ax.set_yticks(range(len(sig)), [f"{x:g}" for x in sig], fontsize=7)
        ax.set(xlabel="model error r [%]", ylabel="noise σ", title=_label(name))
        ax.title.set_fontsize(8)
    if im is not None:
        fig.colorbar(im, ax=axes, label="success [%]", shrink=0.8)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def episodes_ecdf(result: dict, path: str | Path) -> str:
    """For the optimisers: the fraction of targets reached within the tolerance against the
    episodes spent (the ECDF of each search's episodes to the tolerance, as COCO's runtime
    distributions); MPC as a point at its mean episodes per target."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.4, 4), layout="constrained")
    tol = 1e6 * result["tolerance_m"]
    for r in result["rows"]:
        if "episodes_to_tolerance" not in r:
            continue
        hits = np.sort([e for e in r["episodes_to_tolerance"] if e is not None])
        n = r["n_targets"]
        x = np.concatenate([[1], hits, [r["budget"]]])
        y = 100 * np.concatenate([[0], np.arange(1, hits.size + 1) / n, [hits.size / n]])
        ax.step(x, y, where="post", color=_color(r["method"]),
                label=f"{_label(r['method'])}, budget {r['budget']}")
    for r in result["rows"]:
        if r["method"].startswith("mpc"):
            m = r["method"]
            ax.semilogx(r["episodes_per_target"], 100 * r["success_rate"], _marker(m), ms=12,
                        color=_color(m), label=f"{_label(m)} (mean episodes)")
    ax.set_xscale("log")
    ax.set(xlabel="episodes of the model per target", ylim=(-2, 102),
           ylabel=f"targets reached within ±{tol:.0f} µm [%]",
           title="episodes needed to reach the tolerance (ECDF over targets)")
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7, loc="outside right upper")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)


def plot_all(result: dict, tolerance: str | Path, compute: str | Path,
             perturbation: str | Path, ecdf: str | Path | None = None,
             grid: str | Path | None = None) -> list[str]:
    """The charts, at the paths given (``ecdf``: episodes to the tolerance; ``grid``: the full
    perturbation grid, drawn when the result has one)."""
    Path(tolerance).parent.mkdir(parents=True, exist_ok=True)
    out = [success_vs_tolerance(result, Path(tolerance)),
           accuracy_vs_compute(result, Path(compute)),
           success_vs_perturbation(result, Path(perturbation))]
    if ecdf is not None:
        out.append(episodes_ecdf(result, Path(ecdf)))
    if grid is not None:
        g = perturbation_grid(result, Path(grid))
        if g:
            out.append(g)
    return out
