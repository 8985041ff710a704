"""Charts of the studies (matplotlib Agg, imported lazily; same style as :mod:`..plots`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..plots import _save, _subplots


def _sobol_bars(ax: Any, block: dict[str, Any], title: str) -> None:
    idx = block["indices"]
    x = np.arange(len(idx))
    w = 0.38
    ax.bar(x - w / 2, [i["S1"] for i in idx], w, yerr=[i["S1_conf"] for i in idx],
           label="first order S1", capsize=3)
    ax.bar(x + w / 2, [i["ST"] for i in idx], w, yerr=[i["ST_conf"] for i in idx],
           label="total ST", capsize=3)
    ax.set_xticks(x, [i["name"] for i in idx], rotation=30, ha="right", fontsize=8)
    ax.axhline(0, color="k", lw=0.6)
    ax.set_ylabel("Sobol' index")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)


def plot_sensitivity(table: dict[str, Any] | None, sobol: dict[str, Any] | None,
                     path: str | Path) -> str:
    """Left: our Table 3.4 estimates with +-2 standard errors (dissertation sign marked);
    middle/right: Sobol' first-order and total indices (confidence intervals) of the distance and
    of log10(distance)."""
    fig, axes = _subplots(1, 3, figsize=(18, 5.5), squeeze=False)
    ax1, ax2, ax3 = axes[0]
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
        ax1.set_xlabel(f"estimate on Box-Cox(distance [µm]), lambda = {table['boxcox_lambda']:.3f}")
        ax1.set_title(f"Box-Cox + OLS on indicator variables and log f, R^2 = {table['r_squared']:.3f}, n = {table['n']}"
                      "\ngreen: sign as the dissertation, red: opposite, grey: no claim",
                      fontsize=9)
    else:
        ax1.axis("off")
    if sobol:
        pct = int(sobol["conf_level"] * 100)
        _sobol_bars(ax2, sobol, f"Sobol' indices of the distance ({sobol['n_runs']} runs, "
                                f"{pct} % CI)")
        if "log10_distance" in sobol:
            _sobol_bars(ax3, sobol["log10_distance"], "Sobol' indices of log10(distance + 1 µm)")
        else:
            ax3.axis("off")
    else:
        ax2.axis("off")
        ax3.axis("off")
    return str(_save(fig, path))


def _grid(rows: list[dict[str, Any]], xkey: str, ykey: str,
          zkey: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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


def _heat(fig: Any, ax: Any, xs: np.ndarray, ys: np.ndarray, Z: np.ndarray, D: np.ndarray,
          cmap: str, label: str, sx: float = 1.0, sy: float = 1.0, sz: float = 1.0) -> None:
    lim = np.nanmax(np.abs(Z)) * sz if np.isfinite(Z).any() else 1.0
    im = ax.pcolormesh(xs * sx, ys * sy, Z * sz, cmap=cmap, vmin=-lim, vmax=lim,
                       shading="nearest")
    if D.any() and min(D.shape) >= 2:
        ax.contourf(xs * sx, ys * sy, D.astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=["xxx"])
    elif D.any():  # a single row or column: mark the detached cells
        jj, ii = np.nonzero(D)
        ax.plot(xs[ii] * sx, ys[jj] * sy, "kx")
    fig.colorbar(im, ax=ax, label=label)


def plot_engage(map_rows: list[dict[str, Any]], two_rows: list[dict[str, Any]],
                path: str | Path) -> str:
    """Top row: travel over (initial velocity, start position) per frequency (cf. Figs. 4.3-4.8);
    bottom row: the firing's gain over plain coasting. Last column: the two-actuator map, the
    second actuator's extra travel (top) and the final position (bottom), lengths [m] drawn in mm.
    Detachment hatched."""
    freqs = sorted({r["freq_hz"] for r in map_rows}) if map_rows else []
    n = max(len(freqs) + (1 if two_rows else 0), 1)
    fig, axes = _subplots(2, n, figsize=(5.2 * n, 8.6), squeeze=False)
    for k, f in enumerate(freqs):
        rows = [r for r in map_rows if r["freq_hz"] == f]
        for row, (key, label) in enumerate((("travel_m", "travel x_final - x0 [mm]"),
                                            ("gain_m", "gain over coasting [mm]"))):
            ax = axes[row][k]
            xs, ys, Z, D = _grid(rows, "v0_m_s", "x0_m", key)
            _heat(fig, ax, xs, ys, Z, D, "RdBu_r", label, sy=1e3, sz=1e3)
            ax.set_xlabel("initial velocity v0 [m/s]")
            ax.set_ylabel("start position x0 - x_actuator [mm]")
            ax.set_title(f"{f:g} Hz, h = {rows[0]['stroke_m'] * 1e6:g} µm: "
                         f"{'travel' if row == 0 else 'gain'} (hatched: detached)", fontsize=9)
    if two_rows:
        r0 = two_rows[0]
        for row, (key, label) in enumerate((
                ("extra_m", "extra travel from actuator 2 [mm] (> 0: carries on)"),
                ("final_position_m", "final position [mm]"))):
            ax = axes[row][len(freqs)]
            xs, ys, Z, D = _grid(two_rows, "delay_s", "spacing_m", key)
            _heat(fig, ax, xs, ys, Z, D, "PuOr" if row == 0 else "RdBu_r", label, sx=1e3,
                  sy=1e3, sz=1e3)
            ax.set_xlabel("delay [ms]")
            ax.set_ylabel("spacing [mm]")
            ax.set_title(f"two actuators, {r0['freq_hz']:g} Hz, h = {r0['stroke_m'] * 1e6:g} µm"
                         f", start {-r0['x0_m'] * 1e3:g} mm upstream", fontsize=9)
    return str(_save(fig, path))


def plot_fidelity(assessed: dict[str, Any], path: str | Path) -> str:
    """Per scene (columns): top, error against the most faithful level (physics + numerics)
    versus wall time; bottom, error against the level's own converged result (numerics only).
    A level that stays far off on top but converges below differs in physics, not numerics.
    Errors [m] drawn in µm, wall times [s] in µs."""
    import textwrap

    scenes = [s for s in assessed["scenes"] if any(r["scene"] == s for r in assessed["rows"])]
    fig, axes = _subplots(2, len(scenes), figsize=(5.4 * len(scenes), 8.8), squeeze=False)
    floor = 1e-12
    markers = {"event": "o", "karnopp": "s"}
    colors = {("reduced", "constant"): "tab:blue", ("exact", "constant"): "tab:orange",
              ("reduced", "stretch"): "tab:green", ("exact", "stretch"): "tab:red"}
    for k, sc in enumerate(scenes):
        rows = [r for r in assessed["rows"] if r["scene"] == sc]
        for row, key in enumerate(("error_vs_faithful_m", "numerical_error_m")):
            ax = axes[row][k]
            for (kin, rough), col in colors.items():
                for mode, mk in markers.items():
                    sel = sorted((r for r in rows if r["kinematics"] == kin
                                  and r["roughness"] == rough and r["mode"] == mode
                                  and not r["reference"]), key=lambda r: -r["dt_s"])
                    if not sel:
                        continue
                    w = [r["wall_time_s"] * 1e6 for r in sel]
                    e = [max(r[key], floor) * 1e6 for r in sel]
                    ls = "-" if mode == "event" else "--"
                    ax.loglog(w, e, mk + ls, color=col, ms=4, lw=1,
                              label=f"{kin} kin., {rough}, {mode}")
                    if row == 0:
                        bad = [(wi, ei) for wi, ei, r in zip(w, e, sel, strict=True)
                               if not r["outcome_matches_faithful"]]
                        if bad:
                            ax.plot(*zip(*bad, strict=True), "kx", ms=9)
            ax.axhline(assessed["tolerance_m"] * 1e6, color="r", ls=":", lw=0.8, label="1 µm")
            ax.set_xlabel("wall time per run [µs]")
            ax.set_ylabel("|position - most faithful| [µm] (x: other outcome)" if row == 0
                          else "|position - same level converged| [µm]")
            if row == 0:
                ax.set_title(f"{sc}: physics + numerics\n"
                             + textwrap.fill(assessed["scenes"][sc], 70), fontsize=7)
            else:
                ax.set_title(f"{sc}: numerics only", fontsize=8)
            ax.legend(fontsize=6)
    return str(_save(fig, path))


def plot_stretch(study: dict[str, Any], path: str | Path) -> str:
    """Travel [m, drawn in µm] versus frequency [Hz] with constant and stretch-dependent roughness
    (ch. 5)."""
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
    ax1.set_ylabel("travel [µm]")
    ax1.set_title("travel of the seed scene with constant and stretched roughness", fontsize=9)
    ax1.legend(fontsize=8)
    c = {r["freq_hz"]: r for r in study["rows"] if r["roughness"] == "constant"}
    pairs = [(r["freq_hz"], abs(r["displacement_m"]), abs(c[r["freq_hz"]]["displacement_m"]))
             for r in study["rows"] if r["roughness"] == "stretch" and r["freq_hz"] in c
             and r["outcome"] == c[r["freq_hz"]]["outcome"] == "rest"
             and abs(c[r["freq_hz"]]["displacement_m"]) >= 10e-6]
    if pairs:
        f, s_, c_ = (np.array(v) for v in zip(*pairs, strict=True))
        ax2.plot(f, (s_ / c_ - 1.0) * 100, "s-", ms=3)
    ax2.axhline(0, color="k", lw=0.6)
    ax2.set_xlabel("frequency [Hz]")
    ax2.set_ylabel("travel change with stretch [%]")
    peak = max((r.get("peak_strain", 0.0) for r in study["rows"]), default=0.0)
    ax2.set_title(f"stretch versus constant (both at rest; peak zone strain {peak:.3f})",
                  fontsize=9)
    return str(_save(fig, path))
