"""The reach study's chart: best open-loop error and success under noise against the target."""
from __future__ import annotations

import numpy as np

from .common import pyplot


def plot_reach(study: dict, path: str) -> str:
    plt = pyplot()

    rows = study["rows"]
    t = np.array([r["target_m"] for r in rows]) * 1e3
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    a1.semilogy(t, [max(r["best_abs_error_m"], 1e-9) * 1e6 for r in rows], "o-")
    a1.axhline(study["tolerance_m"] * 1e6, color="k", ls="--", lw=0.8, label="tolerance")
    a1.set_ylabel("best open-loop |error| [µm]")
    a1.legend()
    a2.plot(t, [100 * r["noisy_success_rate"] for r in rows], "s-", label="best-error answer")
    a2.plot(t, [100 * r["best_noisy_success_rate"] for r in rows], "o-",
            label="best of it and the noise-robust answer")
    a2.legend(fontsize=8)
    a2.axhline(100 * study["robust_rate"], color="k", ls="--", lw=0.8)
    a2.set_ylabel(f"success under noise σ={study['sigma']:g} [%]")
    a2.set_xlabel("target [mm]")
    rr = study["robust_target_range_m"]
    if rr:
        for ax in (a1, a2):
            ax.axvspan(rr[0] * 1e3, rr[1] * 1e3, color="g", alpha=0.1)
    scene = study.get("scene_label")
    fig.suptitle(f"Reach of open-loop schedules (DE, {study['budget_episodes']} episodes/target)"
                 + (f"\n{scene}" if scene else ""), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
