"""Figures (matplotlib with the Agg backend, imported lazily so the simulator never needs it)."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # matplotlib is imported lazily at run time
    from matplotlib.figure import Figure

    from .physics.contact_table import ContactTable
    from .physics.simulator import Result


def _subplots(nrows: int = 1, ncols: int = 1, **kw: Any) -> tuple[Figure, Any]:
    """A stand-alone Agg figure (no pyplot, so the caller's matplotlib backend is untouched)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=kw.pop("figsize", None), layout="constrained")
    return fig, fig.subplots(nrows, ncols, **kw)


def plot_contact(table: ContactTable, path: str | Path, title: str = "") -> Path:
    """The contact law of a preset: P, F_s, N [N] versus separation [m] (pull-off marked), and Q [N],
    drawn in µN / nm and written to ``path``."""
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
    ax1.set_ylabel("force [µN]")
    ax1.set_title(f"load, adhesion and net load{' — ' + title if title else ''}")
    ax1.legend(fontsize=8)
    ax2.semilogy(dn, np.maximum(f["Q_N"], 1e-30), "tab:purple", label="max static friction Q")
    w = p.part.weight
    dw = float(table.separation(w)) * 1e9
    ax2.plot([dw], [float(table.friction(w))], "ko",
             label=f"at weight m g: Q = {float(table.friction(w)):.3g} N")
    ax2.axvline(dA, color="r", ls="--", lw=0.8, label="pull-off separation")
    ax2.set_xlabel("separation d [nm]")
    ax2.set_ylabel("Q [N]")
    ax2.set_title(f"maximum static friction{' — ' + title if title else ''}")
    ax2.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def _save(fig: Figure, path: str | Path) -> Path:
    """Write ``fig``; a name without an extension gets ``.png``. Returns the path written."""
    path = Path(path)
    if not str(path).strip() or path.name in ("", ".", ".."):
        raise ValueError(f"chart path {str(path)!r} is not a file name")
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def plot_firing(result: Result, freq: float, path: str | Path, delay: float = 0.0, title: str = "",
                stroke: float | None = None) -> Path:
    """One firing: friction force, velocity, position and normal load versus time, with the
    stroke's up and down phases shaded and stick intervals marked (``freq`` [Hz], ``stroke`` [m],
    ``delay`` [s] before the stroke); ``result`` must be recorded (``record=True``)."""
    tr = result.trajectory
    assert tr is not None, "plot_firing needs a recorded result (simulate(..., record=True))"
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
    ax3.set_ylabel("part position x [µm]", color="tab:red")
    ax3.set_xlabel("time [ms]  (orange: stroke up, blue: stroke down)")
    ax4 = ax3.twinx()
    ax4.plot(t_ms, tr["N_N"] * 1e6, color="0.35", lw=0.9)
    ax4.set_ylabel("normal load N [µN]", color="0.35")
    scene = f"{freq:g} Hz" + (f", {stroke * 1e6:g} µm stroke" if stroke else "") \
        + f", start {result.x0_m * 1e3:g} mm from the actuator"
    ax1.set_title(title or f"one firing ({scene}): {result.outcome}, travel "
                           f"{result.displacement_m * 1e6:.0f} µm")
    return _save(fig, path)


def plot_sweep(sweep: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Signed travel x_final - x0 [m, drawn in µm; negative: upstream] versus the swept
    parameter (in its own unit, ``sweep['unit']``); the line breaks at detachments (marked),
    the feasible window is shaded, or "no window" written with the reason."""
    vals = np.asarray(sweep[sweep["values_key"]], dtype=object)
    fig, ax = _subplots(figsize=(8, 4.5))
    numeric = sweep["param"] != "profile"
    x = np.asarray(vals, float) if numeric else np.arange(len(vals))
    unit, scale = sweep["unit"], 1.0
    if numeric and unit == "m":  # lengths in the unit people read, not metres with an offset
        big = float(np.max(np.abs(x))) if x.size else 0.0
        unit, scale = ("nm", 1e9) if big < 1e-6 else ("µm", 1e6) if big < 1e-2 else ("mm", 1e3)
    x = x * scale
    d = np.asarray(sweep["displacement_m"], float) * 1e6
    det = np.array([o == "detached" for o in sweep["outcome"]])
    ax.plot(x, np.where(det, np.nan, d), "o-", ms=3, label="travel x_final − x0 (rest)")
    if det.any():
        ax.plot(x[det], d[det], "rx", label="detached (travel until detachment)")
    ax.axhline(0.0, color="k", lw=0.6)
    key = "window" + sweep["values_key"][len(sweep["param"]):]
    win = sweep.get(key)
    if win:
        ax.axvspan(win[0] * scale, win[1] * scale, color="tab:green", alpha=0.1,
                   label=f"feasible window {win[0] * scale:g} .. {win[1] * scale:g} {unit}")
    elif sweep.get("no_window_reason"):
        ax.text(0.5, 0.5, sweep["no_window_reason"], transform=ax.transAxes, ha="center",
                va="center", color="tab:red", fontsize=10,
                bbox={"facecolor": "white", "edgecolor": "tab:red", "alpha": 0.9})
    if not numeric:
        ax.set_xticks(x, list(vals))
    ax.set_xlabel(f"{sweep['param']} [{unit}]")
    ax.set_ylabel("travel [µm] (negative: upstream)")
    ax.set_title(title or f"travel of one firing versus {sweep['param']}")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_accuracy(study: dict[str, Any], path: str | Path) -> Path:
    """Error of the final position [m, drawn in µm] versus wall time per firing [s, drawn in µs], per
    mode and kinematics level."""
    fig, ax = _subplots(figsize=(10, 5))
    styles = {("event", "reduced"): "o-", ("karnopp", "reduced"): "s-",
              ("event", "exact"): "o--", ("karnopp", "exact"): "s--"}
    floor = 1e-12  # m: errors below are drawn at the floor, marked with a downward triangle
    clipped_any = False
    for i, ((mode, kin), st) in enumerate(styles.items()):
        rows = [r for r in study["rows"] if r["mode"] == mode and r["kinematics"] == kin]
        if not rows:
            continue
        w = [r["wall_time_s"] * 1e6 for r in rows]
        e = [max(r["error_m"], floor) * 1e6 for r in rows]
        line, = ax.loglog(w, e, st, label=f"{mode}, {kin} kinematics")
        clipped = [(wi, ei) for r, wi, ei in zip(rows, w, e, strict=True) if r["error_m"] < floor]
        if clipped:
            clipped_any = True
            ax.plot(*zip(*clipped, strict=True), "v", color=line.get_color(), ms=9, mfc="none")
        for r, wi, ei in zip(rows, w, e, strict=True):  # dt labels, offset per series so they do not overlap
            ax.annotate(f"{r['dt_s']:.2g}", (wi, ei), fontsize=6, alpha=0.75,
                        xytext=(4, 6 - 7 * i), textcoords="offset points", color=line.get_color())
    if clipped_any:
        ax.plot([], [], "kv", mfc="none", label=f"error below {floor * 1e6:g} µm (at the floor)")
    ax.axhline(study["tolerance_m"] * 1e6, color="r", lw=0.8, ls=":",
               label=f"tolerance {study['tolerance_m'] * 1e6:g} µm")
    d = study.get("default")
    if d:
        ax.plot([d["wall_time_s"] * 1e6], [max(d["error_m"], floor) * 1e6], "r*", ms=16,
                label=f"default: {d['mode']}, dt = {d['dt_s']:g} s")
    ax.set_xlabel("wall time per firing [µs]  (labels: dt [s])")
    ax.set_ylabel("|final position − converged| [µm]")
    ax.set_title(f"speed versus accuracy of one firing: {study['freq_hz']:g} Hz, "
                 f"{study['stroke_m'] * 1e6:g} µm stroke, start {study['x0_m'] * 1e3:g} mm",
                 fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(fig, path)


def plot_episode_accuracy(study: dict[str, Any], path: str | Path) -> Path:
    """Episode-level error (95th percentile and max of the final position [m, drawn in µm]) versus
    cost per episode
    (RK4 steps: deterministic, unlike wall time on a shared machine)."""
    fig, ax = _subplots(figsize=(10, 5.5))
    floor = 1e-10
    rows = study["rows"]
    series = [("event", dt) for dt in sorted({r["dt_s"] for r in rows if r["mode"] == "event"})]
    series.append(("karnopp", None))
    for i, (mode, dt) in enumerate(series):
        sel = [r for r in rows if r["mode"] == mode and (dt is None or r["dt_s"] == dt)]
        sel.sort(key=lambda r: r["rk4_steps_per_episode"])
        x = [r["rk4_steps_per_episode"] for r in sel]
        colour = "C1" if mode == "karnopp" else f"C{[0, 2, 4, 5, 6][i % 5]}"
        label = (f"event, dt = {dt:g} s, >= 20 ... 64 steps/stroke" if mode == "event"
                 else "karnopp, >= 20 steps/stroke, dt = 5e-5 ... 7.8e-7 s")
        ax.loglog(x, [max(r["p95_error_m"], floor) * 1e6 for r in sel], "o-", color=colour,
                  label=label)
        ax.loglog(x, [max(r["max_error_m"], floor) * 1e6 for r in sel], "o", color=colour,
                  mfc="none", alpha=0.6)
        for r, xi in zip(sel, x, strict=True):
            note = f"{r['min_steps']}" if mode == "event" else f"{r['dt_s']:.2g} s"
            if r["outcome_disagreements"]:
                note += f", {r['outcome_disagreements']} outcome flips"
            ax.annotate(note, (xi, max(r["p95_error_m"], floor) * 1e6), fontsize=6, alpha=0.8,
                        xytext=(3, 4), textcoords="offset points")
    ax.axhline(study["error_bar_m"] * 1e6, color="r", lw=0.8, ls=":",
               label=f"bar: tolerance / 10 = {study['error_bar_m'] * 1e6:g} µm (95th percentile)")
    former = next((r for r in rows if r["mode"] == "event" and r["dt_s"] == 5e-5
                   and r["min_steps"] == 20), None)
    marks = [("env_default", "r*", "env default"), ("recommended", "g+", "cheapest meeting the bar")]
    for key, style, name in marks:
        d = study.get(key)
        if d:
            ax.plot([d["rk4_steps_per_episode"]], [max(d["p95_error_m"], floor) * 1e6], style,
                    ms=16, mew=2, label=f"{name}: {d['mode']}, dt = {d['dt_s']:g} s, "
                                        f">= {d['min_steps']} steps/stroke")
    if former:
        ax.plot([former["rk4_steps_per_episode"]], [former["p95_error_m"] * 1e6], "kx", ms=12,
                mew=2, label="former default settings (dt = 5e-5 s, >= 20 steps/stroke)")
    ax.set_xlabel("cost: RK4 steps per episode (numbers at the points: steps/stroke, or dt)")
    ax.set_ylabel("|final position − converged| [µm]\nfilled: 95th percentile, open: max")
    ax.set_title(f"MicroConveyor-v0 episode-level accuracy: {study['episodes']} seeded episodes "
                 f"vs event mode at dt = {study['reference_dt_s']:g} s", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(fig, path)


def save_frames(frames: Sequence[np.ndarray], path: str | Path, cols: int = 2,
                title: str = "") -> Path:
    """Tile rendered env frames (uint8 H x W x 3 [px]) into one PNG, ``cols`` [-] per row,
    under ``title``."""
    n = len(frames)
    rows = (n + cols - 1) // cols
    h, w = frames[0].shape[:2]
    fig, axes = _subplots(rows, cols, figsize=(cols * w / 100, rows * h / 100), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, fr in zip(axes.ravel(), frames, strict=False):  # spare cells stay blank
        ax.imshow(fr)
    if title:
        fig.suptitle(title, fontsize=9)
    return _save(fig, path)
