"""Charts of the studies (matplotlib Agg, imported lazily; same style as :mod:`..plots`)."""
from __future__ import annotations

import math

import numpy as np

from ..plots import _save, _subplots


def plot_sensitivity(table: dict | None, sobol: dict | None, path) -> str:
    """Left: our Table 3.4 estimates with +-2 standard errors (dissertation sign marked);
    right: Sobol' first-order and total indices with their confidence intervals."""
    fig, axes = _subplots(1, 2, figsize=(13, 5.5), squeeze=False)
    ax1, ax2 = axes[0]
    if table:
        terms = [t for t in table["terms"] if t["term"] != "Intercept"]
        y = np.arange(len(terms))
        est = np.array([t["estimate"] for t in terms])
        se = np.array([t["std_error"] for t in terms])
        colors = ["tab:green" if t["sign_agrees"] else "tab:red" if t["sign_agrees"] is False
                  else "0.5" for t in terms]
        ax1.barh(y, est, xerr=2 * se, color=colors, alpha=0.8)
        ax1.set_yticks(y, [t["term"].replace("np.log(freq_hz)", "log f") for t in terms],
                       fontsize=7)
        ax1.axvline(0, color="k", lw=0.8)
        ax1.invert_yaxis()
        ax1.set_xlabel(f"estimate on Box-Cox(distance [um]), lambda = {table['boxcox_lambda']:.3f}")
        ax1.set_title(f"OLS (eq. 3-48 analogue), R^2 = {table['r_squared']:.3f}, n = {table['n']}"
                      "\ngreen: sign as the dissertation, red: opposite, grey: no claim",
                      fontsize=9)
    else:
        ax1.axis("off")
    if sobol:
        idx = sobol["indices"]
        x = np.arange(len(idx))
        w = 0.38
        ax2.bar(x - w / 2, [i["S1"] for i in idx], w, yerr=[i["S1_conf"] for i in idx],
                label="first order S1", capsize=3)
        ax2.bar(x + w / 2, [i["ST"] for i in idx], w, yerr=[i["ST_conf"] for i in idx],
                label="total ST", capsize=3)
        ax2.set_xticks(x, [i["name"] for i in idx], rotation=30, ha="right", fontsize=8)
        ax2.axhline(0, color="k", lw=0.6)
        ax2.set_ylabel("Sobol' index")
        ax2.set_title(f"Sobol' indices of the travel ({sobol['n_runs']} runs, "
                      f"{int(sobol['conf_level'] * 100)} % CI)", fontsize=9)
        ax2.legend(fontsize=8)
    else:
        ax2.axis("off")
    return str(_save(fig, path))


def _grid(rows, xkey, ykey, zkey):
    xs = sorted({r[xkey] for r in rows})
    ys = sorted({r[ykey] for r in rows})
    xi = {v: i for i, v in enumerate(xs)}
    yi = {v: i for i, v in enumerate(ys)}
    Z = np.full((len(ys), len(xs)), np.nan)
    D = np.zeros((len(ys), len(xs)), bool)
    for r in rows:
        Z[yi[r[ykey]], xi[r[xkey]]] = r[zkey]
        D[yi[r[ykey]], xi[r[xkey]]] = r.get("detached", False)
    return np.array(xs), np.array(ys), Z, D


def plot_engage(map_rows, two_rows, path) -> str:
    """Heat maps of the travel over (initial velocity, start position) per frequency (cf. Figs.
    4.3-4.8; detachment hatched in black), and of the second actuator's effect over (delay,
    spacing)."""
    freqs = sorted({r["freq_hz"] for r in map_rows}) if map_rows else []
    n = len(freqs) + (1 if two_rows else 0)
    fig, axes = _subplots(1, max(n, 1), figsize=(5.2 * max(n, 1), 4.6), squeeze=False)
    for ax, f in zip(axes[0], freqs):
        rows = [r for r in map_rows if r["freq_hz"] == f]
        xs, ys, Z, D = _grid(rows, "v0_m_s", "x0_m", "travel_m")
        lim = np.nanmax(np.abs(Z)) * 1e3 if np.isfinite(Z).any() else 1.0
        im = ax.pcolormesh(xs, ys * 1e3, Z * 1e3, cmap="RdBu_r", vmin=-lim, vmax=lim,
                           shading="nearest")
        if D.any():
            ax.contourf(xs, ys * 1e3, D.astype(float), levels=[0.5, 1.5], colors="none",
                        hatches=["xxx"])
            ax.plot([], [], "ks", mfc="none", label="detached (hatched)")
            ax.legend(fontsize=7, loc="lower right")
        fig.colorbar(im, ax=ax, label="travel x_final - x0 [mm]")
        ax.set_xlabel("initial velocity v0 [m/s]")
        ax.set_ylabel("start position x0 - x_actuator [mm]")
        ax.set_title(f"{f:g} Hz, h = {rows[0]['stroke_m'] * 1e6:g} um", fontsize=9)
    if two_rows:
        ax = axes[0][len(freqs)]
        xs, ys, Z, D = _grid(two_rows, "delay_s", "spacing_m", "extra_m")
        lim = np.nanmax(np.abs(Z)) * 1e6 if np.isfinite(Z).any() else 1.0
        im = ax.pcolormesh(xs * 1e3, ys * 1e3, Z * 1e6, cmap="PuOr", vmin=-lim, vmax=lim,
                           shading="nearest")
        if D.any():
            ax.contourf(xs * 1e3, ys * 1e3, D.astype(float), levels=[0.5, 1.5], colors="none",
                        hatches=["xxx"])
        fig.colorbar(im, ax=ax, label="extra travel from actuator 2 [um] (>0 accelerates)")
        r0 = two_rows[0]
        ax.set_xlabel("delay [ms]")
        ax.set_ylabel("spacing [mm]")
        ax.set_title(f"two actuators, {r0['freq_hz']:g} Hz, h = {r0['stroke_m'] * 1e6:g} um",
                     fontsize=9)
    return str(_save(fig, path))


def plot_fidelity(assessed: dict, path) -> str:
    """Per scene: error against the most faithful level versus wall time, per level."""
    scenes = list(assessed["scenes"])
    scenes = [s for s in scenes if any(r["scene"] == s for r in assessed["rows"])]
    fig, axes = _subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.8), squeeze=False)
    floor = 1e-12
    markers = {"event": "o", "karnopp": "s"}
    colors = {("seed", "constant"): "tab:blue", ("exact", "constant"): "tab:orange",
              ("seed", "stretch"): "tab:green", ("exact", "stretch"): "tab:red"}
    for ax, sc in zip(axes[0], scenes):
        rows = [r for r in assessed["rows"] if r["scene"] == sc]
        for (kin, rough), col in colors.items():
            for mode, mk in markers.items():
                sel = sorted((r for r in rows if r["kinematics"] == kin and r["roughness"] == rough
                              and r["mode"] == mode and not r["reference"]),
                             key=lambda r: -r["dt_s"])
                if not sel:
                    continue
                w = [r["wall_time_s"] * 1e6 for r in sel]
                e = [max(r["error_vs_faithful_m"], floor) * 1e6 for r in sel]
                ls = "-" if mode == "event" else "--"
                ax.loglog(w, e, mk + ls, color=col, ms=4, lw=1,
                          label=f"{kin} kin., {rough}, {mode}")
                bad = [(wi, ei) for wi, ei, r in zip(w, e, sel) if not r["outcome_matches_faithful"]]
                if bad:
                    ax.plot(*zip(*bad), "kx", ms=9)
        ax.axhline(assessed["tolerance_m"] * 1e6, color="r", ls=":", lw=0.8, label="1 um")
        ax.set_xlabel("wall time per run [us]")
        ax.set_ylabel("|position - most faithful| [um]  (x: other outcome)")
        ax.set_title(sc + "\n" + assessed["scenes"][sc], fontsize=7)
        ax.legend(fontsize=6)
    return str(_save(fig, path))


def plot_stretch(study: dict, path) -> str:
    """Travel versus frequency with constant and stretch-dependent roughness (ch. 5)."""
    fig, (ax1, ax2) = _subplots(1, 2, figsize=(12, 4.5))
    for level, st in (("constant", "o-"), ("stretch", "s--")):
        rows = [r for r in study["rows"] if r["roughness"] == level]
        f = np.array([r["freq_hz"] for r in rows])
        d = np.array([abs(r["displacement_m"]) for r in rows]) * 1e6
        det = np.array([r["outcome"] == "detached" for r in rows])
        ax1.plot(f[~det], d[~det], st, ms=3, label=f"{level} roughness")
        if det.any():
            ax1.plot(f[det], d[det], "x", color="r" if level == "stretch" else "k",
                     label=f"{level}: detached")
    ax1.set_xlabel("frequency [Hz]")
    ax1.set_ylabel("travel [um]")
    ax1.set_title("travel with and without stretch (cf. ch. 5)", fontsize=9)
    ax1.legend(fontsize=8)
    rows = [r for r in study["rows"] if r["roughness"] == "stretch"]
    ax2.plot([r["freq_hz"] for r in rows], [r.get("max_strain", math.nan) for r in rows], "s-",
             ms=3)
    ax2.set_xlabel("frequency [Hz]")
    ax2.set_ylabel("largest strain of the active zone [-]")
    ax2.set_title("strain reached during the stroke", fontsize=9)
    return str(_save(fig, path))
