"""Figures (matplotlib with the Agg backend, imported lazily so the simulator never needs it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_contact(table, path: str | Path, title: str = "") -> Path:
    """Seed Fig. 3.11 / 3.15 analogues: P, F_s, N versus separation (pull-off marked), and Q."""
    from .physics.rough_surface import surface_forces

    plt = _plt()
    p = table.params
    sig = p.surface.sigma
    d = np.linspace(max(table.base.d[-1], table.base.d_balance - 1.5) * sig,
                    table.pull_off_separation + 1.5 * sig, 600)
    f = surface_forces(p, d)
    dn = d * 1e9
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    uN = 1e6
    ax1.plot(dn, f["P_N"] * uN, label="contact load P")
    ax1.plot(dn, f["Fs_N"] * uN, label="adhesion F_s")
    ax1.plot(dn, f["N_N"] * uN, "k", lw=2, label="net load N = P - F_s")
    ax1.axhline(0, color="0.6", lw=0.8)
    dA, Fp = table.pull_off_separation * 1e9, table.pull_off_force
    ax1.plot([dA], [-Fp * uN], "ro", label=f"pull-off: {Fp:.3g} N at {dA:.1f} nm")
    db = table.balance_separation * 1e9
    ax1.axvline(db, color="0.5", ls=":", label=f"balance P = F_s at {db:.1f} nm")
    ax1.axvspan(dn[0], dA, color="tab:green", alpha=0.06, label="stable branch")
    ax1.set_ylim(-2.0 * Fp * uN, 6.0 * Fp * uN)
    ax1.set_xlabel("separation d [nm]")
    ax1.set_ylabel("force [uN]")
    ax1.set_title("Load, adhesion and net load (cf. Fig. 3.11)")
    ax1.legend(fontsize=8)
    ax2.semilogy(dn, np.maximum(f["Q_N"], 1e-30), "tab:purple", label="max static friction Q")
    w = p.part.weight
    dw = float(table.separation(w)) * 1e9
    ax2.plot([dw], [float(table.friction(w))], "ko",
             label=f"at weight m g: Q = {float(table.friction(w)):.3g} N")
    ax2.axvline(dA, color="r", ls="--", lw=0.8, label="pull-off separation")
    ax2.set_xlabel("separation d [nm]")
    ax2.set_ylabel("Q [N]")
    ax2.set_title("Maximum static friction (cf. Fig. 3.15)")
    ax2.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
