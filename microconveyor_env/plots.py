"""Figures (matplotlib with the Agg backend, imported lazily so the simulator never needs it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _subplots(nrows: int = 1, ncols: int = 1, **kw):
    """A stand-alone Agg figure (no pyplot, so the caller's matplotlib backend is untouched)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=kw.pop("figsize", None), layout="constrained")
    return fig, fig.subplots(nrows, ncols, **kw)


def plot_contact(table, path: str | Path, title: str = "") -> Path:
    """Seed Fig. 3.11 / 3.15 analogues: P, F_s, N versus separation (pull-off marked), and Q."""
    from .physics.rough_surface import surface_forces

    p = table.params
    sig = p.surface.sigma
    d = np.linspace(max(table.base.d[-1], table.base.d_balance - 1.5) * sig,
                    table.pull_off_separation + 1.5 * sig, 600)
    f = surface_forces(p, d)
    dn = d * 1e9
    fig, (ax1, ax2) = _subplots(1, 2, figsize=(11, 4.2))
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
    return _save(fig, path)


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def plot_firing(result, freq: float, path, delay: float = 0.0, title: str = "") -> Path:
    """Seed Fig. 3.16 analogue: friction force and horizontal velocity versus time, with the
    stroke's up and down phases shaded and stick intervals marked."""
    tr = result.trajectory
    t_ms = tr["t_s"] * 1e3
    fig, (ax1, ax2, ax3) = _subplots(3, 1, figsize=(9, 7.5), sharex=True)
    T = 1.0 / freq
    for ax in (ax1, ax2, ax3):
        ax.axvspan(delay * 1e3, (delay + T / 2) * 1e3, color="tab:orange", alpha=0.12)
        ax.axvspan((delay + T / 2) * 1e3, (delay + T) * 1e3, color="tab:blue", alpha=0.10)
    ax1.plot(t_ms, tr["F_N"] * 1e9, "k", lw=1.2, label="friction force F")
    ax1.plot(t_ms, tr["Q_N"] * 1e9, color="tab:purple", lw=0.8, ls="--", label="max static friction Q")
    ax1.plot(t_ms, -tr["Q_N"] * 1e9, color="tab:purple", lw=0.8, ls="--")
    ax1.set_ylabel("force [nN]")
    ax1.legend(fontsize=8, loc="upper right")
    ax2.plot(t_ms, tr["v_m_s"] * 1e3, "tab:green", lw=1.2)
    stick = tr["stick"]
    ax2.plot(t_ms[stick], tr["v_m_s"][stick] * 1e3, "k.", ms=2, label="sticking")
    ax2.set_ylabel("velocity dx/dt [mm/s]")
    ax2.legend(fontsize=8, loc="upper right")
    ax3.plot(t_ms, tr["x_m"] * 1e6, "tab:red", lw=1.2)
    ax3.set_ylabel("part position x [um]", color="tab:red")
    ax3.set_xlabel("time [ms]  (orange: stroke up, blue: stroke down)")
    ax4 = ax3.twinx()
    ax4.plot(t_ms, tr["N_N"] * 1e6, color="0.35", lw=0.9)
    ax4.set_ylabel("normal load N [uN]", color="0.35")
    ax1.set_title(title or f"one firing at {freq:g} Hz (cf. Fig. 3.16): outcome {result.outcome}")
    return _save(fig, path)


def plot_sweep(sweep: dict, path, title: str = "") -> Path:
    """Seed Fig. 3.17 analogue: travel versus the swept parameter, detachment and window marked."""
    vals = np.asarray(sweep["values"], dtype=object)
    fig, ax = _subplots(figsize=(8, 4.5))
    numeric = sweep["param"] != "profile"
    x = np.asarray(vals, float) if numeric else np.arange(len(vals))
    d = np.abs(np.asarray(sweep["displacement_m"])) * 1e6
    det = np.array([o == "detached" for o in sweep["outcome"]])
    ax.plot(x[~det], d[~det], "o-", ms=3, label="travel |x_final - x0|")
    if det.any():
        ax.plot(x[det], d[det], "rx", label="detached (travel until detachment)")
    win = sweep.get("window")
    if win:
        ax.axvspan(win[0], win[1], color="tab:green", alpha=0.1,
                   label=f"feasible window {win[0]:g} .. {win[1]:g} {sweep['unit']}")
    if not numeric:
        ax.set_xticks(x, list(vals))
    ax.set_xlabel(f"{sweep['param']} [{sweep['unit']}]")
    ax.set_ylabel("travel [um]")
    ax.set_title(title or f"travel versus {sweep['param']} (cf. Fig. 3.17)")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_accuracy(study: dict, path) -> Path:
    """Error of the final position versus wall time per firing, per mode and kinematics level."""
    fig, ax = _subplots(figsize=(8, 5))
    styles = {("event", "seed"): "o-", ("karnopp", "seed"): "s-",
              ("event", "exact"): "o--", ("karnopp", "exact"): "s--"}
    floor = 1e-12
    for (mode, kin), st in styles.items():
        rows = [r for r in study["rows"] if r["mode"] == mode and r["kinematics"] == kin]
        if not rows:
            continue
        w = [r["wall_time_s"] * 1e6 for r in rows]
        e = [max(r["error_m"], floor) * 1e6 for r in rows]
        ax.loglog(w, e, st, label=f"{mode}, {kin} kinematics")
        for r, wi, ei in zip(rows, w, e):
            ax.annotate(f"{r['dt_s']:.2g}", (wi, ei), fontsize=6, alpha=0.7)
    ax.axhline(study["tolerance_m"] * 1e6, color="r", lw=0.8, ls=":", label="1 um tolerance")
    d = study.get("default")
    if d:
        ax.plot([d["wall_time_s"] * 1e6], [max(d["error_m"], floor) * 1e6], "r*", ms=16,
                label=f"default: {d['mode']}, dt = {d['dt_s']:g} s")
    ax.set_xlabel("wall time per firing [us]  (labels: dt [s])")
    ax.set_ylabel("|final position - converged| [um]")
    ax.set_title(f"speed versus accuracy, seed firing {study['freq_hz']:g} Hz")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_episode_accuracy(study: dict, path) -> Path:
    """Episode-level error (p95 and max of the final position) versus cost per episode."""
    fig, ax = _subplots(figsize=(8.5, 5.5))
    floor = 1e-10
    for mode, colour in (("event", "C0"), ("karnopp", "C1")):
        for ms, marker in zip((20, 32, 40, 48, 64), "osvD^"):
            rows = [r for r in study["rows"] if r["mode"] == mode and r["min_steps"] == ms]
            if not rows:
                continue
            w = [r["wall_per_episode_s"] * 1e6 for r in rows]
            p95 = [max(r["p95_error_m"], floor) * 1e6 for r in rows]
            ax.loglog(w, p95, marker + "-", color=colour, alpha=0.85,
                      label=f"{mode}, >= {ms} steps/stroke: 95th percentile")
            ax.loglog(w, [max(r["max_error_m"], floor) * 1e6 for r in rows], marker, color=colour,
                      mfc="none", alpha=0.5)
            for r, wi, ei in zip(rows, w, p95):
                bad = r["outcome_disagreements"]
                ax.annotate(f"{r['dt_s']:.2g}" + (f" ({bad} flips)" if bad else ""), (wi, ei),
                            fontsize=6, alpha=0.7, xytext=(3, -8), textcoords="offset points")
    ax.axhline(study["error_bar_m"] * 1e6, color="r", lw=0.8, ls=":",
               label=f"bar: tolerance / 10 = {study['error_bar_m'] * 1e6:g} µm")
    for key, style, name in (("env_default", "r*", "env default"),
                             ("recommended", "g*", "cheapest meeting the bar")):
        d = study.get(key)
        if d:
            ax.plot([d["wall_per_episode_s"] * 1e6], [max(d["p95_error_m"], floor) * 1e6], style,
                    ms=15, label=f"{name}: {d['mode']}, dt = {d['dt_s']:g} s, "
                                 f">= {d['min_steps']} steps/stroke")
    ax.set_xlabel("wall time per episode [µs] (serial, this machine)  —  labels: dt [s]")
    ax.set_ylabel("|final position − converged| [µm]  (open markers: max)")
    ax.set_title(f"MicroConveyor-v0: episode-level accuracy, {study['episodes']} episodes "
                 f"(reference: event, dt = {study['reference_dt_s']:g} s)", fontsize=10)
    ax.legend(fontsize=7, loc="lower left")
    return _save(fig, path)


def save_frames(frames, path, cols: int = 2) -> Path:
    """Tile rendered env frames (uint8 H x W x 3) into one PNG."""
    n = len(frames)
    rows = (n + cols - 1) // cols
    h, w = frames[0].shape[:2]
    fig, axes = _subplots(rows, cols, figsize=(cols * w / 100, rows * h / 100), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, fr in zip(axes.ravel(), frames):
        ax.imshow(fr)
    return _save(fig, path)
