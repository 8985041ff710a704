"""Learning curves of several training runs (``microconveyor seeds --plot``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import pyplot


def plot_curves(curve: dict, path: str | Path, tolerance_um: int = 50) -> str:
    """Success within +-``tolerance_um`` and median |error| against steps, one line per run."""
    plt = pyplot()

    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
    for name, c in curve.items():
        steps = np.asarray(c["steps"]) / 1e6
        a.plot(steps, 100 * np.asarray(c[f"success_rate_{tolerance_um}um"]), marker=".",
               label=Path(name).name)
        b.semilogy(steps, 1e6 * np.asarray(c["median_abs_error_m"]), marker=".")
    a.axhline(90, color="k", ls=":", lw=1, label="goal (90 %)")
    b.axhline(20, color="k", ls=":", lw=1)
    a.set(xlabel="environment steps [millions]", ylabel=f"success within ±{tolerance_um} µm [%]",
          ylim=(0, 100), title="PPO learning curves (100 fixed targets)")
    b.set(xlabel="environment steps [millions]", ylabel="median |final error| [µm]",
          title="median error (goal 20 µm dotted)")
    a.legend(fontsize=8)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return str(path)
