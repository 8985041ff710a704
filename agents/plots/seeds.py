"""Learning curves of several training runs (``microconveyor seeds --plot``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import pyplot


def plot_curves(curve: dict, path: str | Path, tolerance_um: int = 50) -> str:
    """Success within +-``tolerance_um`` against steps and against wall time, and the median
    |error| against steps, one line per run."""
    plt = pyplot()

    fig, (a, w, b) = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
    for name, c in curve.items():
        steps = np.asarray(c["steps"]) / 1e6
        success = 100 * np.asarray(c[f"success_rate_{tolerance_um}um"])
        a.plot(steps, success, marker=".", label=Path(name).name)
        if c.get("wall_time_s"):
            w.plot(np.asarray(c["wall_time_s"], float) / 60, success, marker=".")
        b.semilogy(steps, 1e6 * np.asarray(c["median_abs_error_m"]), marker=".")
    for ax in (a, w):
        ax.axhline(90, color="k", ls=":", lw=1, label="goal (90 %)" if ax is a else None)
        ax.set(ylabel=f"success within ±{tolerance_um} µm [%]", ylim=(0, 100))
    b.axhline(20, color="k", ls=":", lw=1)
    a.set(xlabel="environment steps [millions]", title="PPO learning curves (100 fixed targets)")
    w.set(xlabel="wall time [min] (as the run measured it)", title="against wall time")
    w.axvline(15, color="C3", ls="--", lw=1)
    b.set(xlabel="environment steps [millions]", ylabel="median |final error| [µm]",
          title="median error (goal 20 µm dotted)")
    a.legend(fontsize=8)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)
