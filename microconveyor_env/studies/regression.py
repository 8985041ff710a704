"""Box--Cox + ordinary least squares on the sensitivity design (dissertation eq. 3-48, Table 3.4).

The response is the distance travelled [um] of the design runs that move (>= 10 um) and neither
detach nor leave the table. It is Box--Cox transformed, ``y(lam) = (y^lam - 1) / lam`` (``log y`` at
``lam = 0``), with ``lam`` chosen by maximum likelihood *for the linear model* (Box & Cox 1964: the
profile log-likelihood ``-n/2 log(RSS(lam)/n) + (lam - 1) sum(log y)``; with an intercept-only model
this is exactly scipy's ``boxcox`` estimate). The transformed distance is regressed on indicator
variables of every factor level (the lowest level is the reference) and on ``log(f)``, with
statsmodels' formula API.

The dissertation's numeric Table 3.4 is not available to us: the comparison column is the *sign*
each trend in docs/physics.md §5 implies (:data:`DISSERTATION_SIGNS`), never a number.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from .sweep import MIN_TRAVEL_M

if TYPE_CHECKING:
    import pandas as pd

FACTORS = {  # column -> (formula name, unit scale, label)
    "dgamma_J_m2": ("dgamma", 1.0, "surface energy [J/m^2]"),
    "sigma_m": ("sigma_nm", 1e9, "roughness sigma [nm]"),
    "stroke_m": ("stroke_um", 1e6, "stroke h [um]"),
    "mass_kg": ("mass_kg", 1.0, "part mass [kg]"),
    "wavelength_m": ("wl_mm", 1e3, "wavelength [mm]"),
    "x0_wl": ("x0_wl", 1.0, "start position [WL]"),
}
FORMULA = ("bc ~ C(dgamma) + C(sigma_nm) + C(stroke_um) + C(mass_kg) + C(wl_mm) + C(x0_wl)"
           " + np.log(freq_hz)")
# The dissertation's signs as docs/physics.md §5 states them (or as they follow from it); "" = no claim
DISSERTATION_SIGNS = {
    "dgamma": ("-", "less surface energy -> more travel"),
    "sigma_nm": ("+", "more roughness -> more travel"),
    "stroke_um": ("+", "larger stroke -> more travel"),
    "mass_kg": ("", "larger mass -> narrower window at lower frequencies (no travel claim)"),
    "wl_mm": ("", "no claim"),
    "x0_wl": ("-", "largest travel a little under WL/4 (so 0.2 WL is the best level; inferred)"),
    "log_freq": ("+", "travel grows with frequency inside the window (Fig. 3.17; inferred)"),
}


def boxcox(y: npt.ArrayLike, lam: float) -> np.ndarray:
    """Box--Cox transform ``(y^lam - 1) / lam`` (``log y`` at ``lam = 0``) of positive ``y`` (any unit;
    ``lam`` [-])."""
    y = np.asarray(y, float)
    return np.log(y) if lam == 0.0 else (y ** lam - 1.0) / lam


def boxcox_loglik(lam: float, y: npt.ArrayLike, X: np.ndarray | None = None) -> float:
    """Profile log-likelihood of ``lam`` for ``boxcox(y, lam) = X b + e`` (X None: intercept)."""
    y = np.asarray(y, float)
    n = y.size
    z = boxcox(y, lam)
    if X is None:
        rss = float(np.sum((z - z.mean()) ** 2))
    else:
        b, *_ = np.linalg.lstsq(X, z, rcond=None)
        rss = float(np.sum((z - X @ b) ** 2))
    return -0.5 * n * math.log(rss / n) + (lam - 1.0) * float(np.sum(np.log(y)))


def boxcox_lambda(y: npt.ArrayLike, X: np.ndarray | None = None,
                  bracket: tuple[float, float] = (-2.0, 2.0)) -> float:
    """Maximum-likelihood Box--Cox exponent of positive ``y`` for the linear model ``X``."""
    y = np.asarray(y, float)
    if y.size < 3 or np.any(y <= 0):
        raise ValueError("Box-Cox needs at least 3 positive values")
    res = minimize_scalar(lambda lam: -boxcox_loglik(lam, y, X), bracket=bracket, method="brent",
                          options={"xtol": 1e-10})
    return float(res.x)


def design_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """The regression's data: moving, attached design runs, factors in readable units (the
    :data:`FACTORS` scales: nm, um, mm; distance in um)."""
    import pandas as pd

    df = pd.DataFrame(rows)
    df = df[(df["phase"] == "design") & (df["outcome"] == "rest")
            & (df["distance_m"] >= MIN_TRAVEL_M)].copy()
    for col, (name, scale, _) in FACTORS.items():
        df[name] = np.round(df[col] * scale, 12)
    df["distance_um"] = df["distance_m"] * 1e6
    return df


def fit(df: pd.DataFrame, formula: str = FORMULA) -> tuple[Any, float]:
    """(statsmodels OLS result, lambda) for the Box--Cox transformed distance [um] in ``df``."""
    import statsmodels.formula.api as smf

    X = smf.ols("distance_um ~" + formula.split("~", 1)[1], data=df).exog  # the design matrix
    lam = boxcox_lambda(df["distance_um"].to_numpy(), X)
    df = df.assign(bc=boxcox(df["distance_um"].to_numpy(), lam))
    return smf.ols(formula, data=df).fit(), lam


def formula_for(df: pd.DataFrame) -> str:
    """:data:`FORMULA` without the factors that have a single level in ``df``."""
    terms = [f"C({name})" for name, _, _ in FACTORS.values() if df[name].nunique() > 1]
    if df["freq_hz"].nunique() > 1:
        terms.append("np.log(freq_hz)")
    return "bc ~ " + (" + ".join(terms) if terms else "1")


def _term_factor(term: str) -> str:
    if term.startswith("np.log"):
        return "log_freq"
    if term.startswith("C("):
        return term[2:term.index(")")]
    return term


def table34(rows: list[dict[str, Any]], formula: str | None = None) -> dict[str, Any]:
    """Our Table 3.4: per term estimate, standard error, t, p, the dissertation's sign (from
    docs/physics.md §5), whether ours agrees; plus R^2, lambda and n."""
    df = design_frame(rows)
    formula = formula or formula_for(df)
    res, lam = fit(df, formula)
    terms = []
    for term in res.params.index:
        factor = _term_factor(term)
        sign, why = DISSERTATION_SIGNS.get(factor, ("", ""))
        est = float(res.params[term])
        ours = "+" if est > 0 else "-"
        terms.append({"term": term, "factor": factor, "estimate": est,
                      "std_error": float(res.bse[term]), "t": float(res.tvalues[term]),
                      "p": float(res.pvalues[term]), "dissertation_estimate": None,
                      "dissertation_sign": sign or None, "why": why,
                      "sign_agrees": (ours == sign) if sign and term != "Intercept" else None})
    return {"formula": formula, "response": "Box-Cox(distance travelled [um])",
            "boxcox_lambda": lam, "n": int(res.nobs), "r_squared": float(res.rsquared),
            "adj_r_squared": float(res.rsquared_adj), "terms": terms,
            "note": "the dissertation's numeric Table 3.4 estimates are not available to us; "
                    "'dissertation_sign' is the trend docs/physics.md §5 states (or implies)"}


def table34_text(t: dict[str, Any]) -> str:
    """:func:`table34`'s result as a plain-text table (estimates on the Box-Cox scale of um)."""
    lines = [f"Box-Cox lambda = {t['boxcox_lambda']:.4f}, n = {t['n']}, R^2 = "
             f"{t['r_squared']:.4f} (adj. {t['adj_r_squared']:.4f})",
             f"{'term':30s} {'estimate':>10s} {'std.err':>9s} {'t':>8s} {'p':>9s}  "
             f"{'diss.est.':>9s} {'diss.sign':>9s}  agree"]
    for r in t["terms"]:
        agree = {True: "yes", False: "NO", None: ""}[r["sign_agrees"]]
        lines.append(f"{r['term']:30s} {r['estimate']:10.4g} {r['std_error']:9.3g} {r['t']:8.2f} "
                     f"{r['p']:9.2e}  {'n/a':>9s} {r['dissertation_sign'] or 'no claim':>9s}  {agree}")
    lines.append("dissertation estimates: not available (signs from docs/physics.md §5)")
    return "\n".join(lines)
