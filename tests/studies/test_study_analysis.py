"""The studies' analysis: Box-Cox, the regression, windows, the speed check, fidelity, the CLI."""
import json

import numpy as np
import pytest
from scipy import stats

from microconveyor_env.studies import engage, fidelity, regression
from microconveyor_env.studies.engine import simulator
from microconveyor_env.studies.sensitivity import find_window
from microconveyor_env.studies.sweep import Scene, feasible_window, sweep
from support.cli import run_cli


@pytest.mark.parametrize("shape", [0.5, 2.0, 8.0])
def test_boxcox_lambda_matches_scipy(shape):
    y = stats.gamma(shape).rvs(size=400, random_state=np.random.default_rng(1)) + 0.01
    ours = regression.boxcox_lambda(y)
    assert ours == pytest.approx(stats.boxcox_normmax(y, method="mle"), abs=1e-6)
    assert ours == pytest.approx(stats.boxcox(y)[1], abs=1e-6)
    assert np.allclose(regression.boxcox(y, ours), stats.boxcox(y, ours))


def _synthetic(lam=0.3, n_rep=6, noise=0.05, seed=0):
    """Distances [m] whose Box-Cox transform (in um) is exactly linear in the factors + log f."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    coef = {"dgamma": {1.0: -1.5, 2.0: -3.0}, "sigma_nm": {30.0: 2.0, 40.0: 3.5},
            "stroke_um": {150.0: 1.0, 200.0: 2.2, 250.0: 3.1}, "log_freq": 1.7, "const": 2.0}
    rows = []
    for dg in (0.5, 1.0, 2.0):
        for sg in (20.0, 30.0, 40.0):
            for st in (100.0, 150.0, 200.0, 250.0):
                for f in np.geomspace(200, 2000, n_rep):
                    z = (coef["const"] + coef["dgamma"].get(dg, 0.0)
                         + coef["sigma_nm"].get(sg, 0.0) + coef["stroke_um"].get(st, 0.0)
                         + coef["log_freq"] * np.log(f) + noise * rng.standard_normal())
                    d_um = (lam * z + 1.0) ** (1.0 / lam)
                    rows.append({"dgamma_J_m2": dg, "sigma_m": sg * 1e-9, "stroke_m": st * 1e-6,
                                 "mass_kg": 2e-9, "wavelength_m": 0.6e-3, "x0_wl": 0.2,
                                 "freq_hz": f, "phase": "design", "outcome": "rest",
                                 "distance_m": d_um * 1e-6})
    return pd.DataFrame(rows).to_dict("records"), coef


def test_regression_recovers_known_coefficients():
    pytest.importorskip("statsmodels")
    rows, coef = _synthetic()
    t = regression.table34(rows)
    assert t["boxcox_lambda"] == pytest.approx(0.3, abs=0.02)
    est = {r["term"]: r for r in t["terms"]}
    assert est["np.log(freq_hz)"]["estimate"] == pytest.approx(coef["log_freq"], rel=0.05)
    assert est["C(sigma_nm)[T.40.0]"]["estimate"] == pytest.approx(3.5, rel=0.05)
    assert est["C(dgamma)[T.2.0]"]["estimate"] == pytest.approx(-3.0, rel=0.05)
    assert est["C(stroke_um)[T.250.0]"]["estimate"] == pytest.approx(3.1, rel=0.05)
    assert t["r_squared"] > 0.99
    # signs: the synthetic data follow docs/physics.md's trends, so every claimed sign agrees
    assert all(r["sign_agrees"] in (True, None) for r in t["terms"])
    assert all(r["dissertation_estimate"] is None for r in t["terms"])  # never invented
    text = regression.table34_text(t)
    assert "not available" in text and "lambda" in text


def test_window_matches_the_sweep_window():
    scan = [float(f) for f in np.arange(200.0, 1500.0, 100.0)]
    sim = simulator("feasibility")
    window, runs = find_window(sim, 200e-6, 0.125e-3, scan, refine=0)
    res = sweep(Scene(), "freq", scan, progress=False)
    assert window == feasible_window(scan, res["displacement_m"], res["outcome"])
    refined, _ = find_window(sim, 200e-6, 0.125e-3, scan, refine=4)
    assert window[0] - 100 < refined[0] <= window[0] and window[1] <= refined[1] < window[1] + 100


def test_speed_statement_check_finds_the_pattern():
    v = np.round(np.arange(0.0, 0.5001, 0.01), 4)
    travel = np.where(v < 0.15, v, np.where(v < 0.32, 0.15 - (v - 0.15), 0.15 - 0.17 + (v - 0.32)))
    rows = [{"freq_hz": 500.0, "stroke_m": 150e-6, "x0_m": -1e-4, "v0_m_s": float(vi),
             "travel_along_m": float(t), "gain_along_m": 0.0, "detached": False}
            for vi, t in zip(v, travel, strict=True)]
    c = engage.check_speed_statement(rows)
    assert c["reproduced"]
    m = c["travel_along_m"]["matching"][0]
    assert m["max_at_m_s"] == pytest.approx(0.15) and m["min_at_m_s"] == pytest.approx(0.32)
    flat = [{**r, "travel_along_m": r["v0_m_s"]} for r in rows]
    assert not engage.check_speed_statement(flat)["reproduced"]


def test_engaging_part_and_coast_reference():
    rows = engage.map_column({"freq_hz": 500.0, "stroke_m": 0.0, "x0_m": 0.0,
                              "v0s": (-0.2, 0.0, 0.1)})
    for r in rows:  # no stroke: the firing changes nothing, the part just coasts
        assert r["travel_m"] == pytest.approx(r["coast_m"], rel=1e-9, abs=1e-15)
        assert abs(r["gain_m"]) < 1e-12


def test_fidelity_assessment_logic():
    def row(kin, mode, dt, pos, outcome="rest", wall=1.0, ref=False):
        return {"scene": "s", "kinematics": kin, "roughness": "constant", "mode": mode,
                "dt_s": dt, "reference": ref, "outcome": outcome, "position_m": pos,
                "steps": 1, "wall_time_s": wall}
    rows = [row("exact", "event", 1e-7, 1e-3, ref=True), row("reduced", "event", 1e-7, 2e-3, ref=True),
            row("exact", "event", 5e-5, 1e-3 + 2e-7, wall=1.0),
            row("exact", "event", 2.5e-5, 1e-3 + 1e-8, wall=2.0),
            row("exact", "karnopp", 5e-5, 1e-3 + 1e-7, wall=0.5),     # lucky hit ...
            row("exact", "karnopp", 2.5e-5, 1e-3 + 5e-6, wall=0.9),   # ... not kept at finer dt
            row("reduced", "event", 5e-5, 2e-3, wall=0.1)]
    a = fidelity.assess(rows)
    pick = a["per_scene"]["s"]["cheapest_within_tolerance_of_faithful"]
    assert (pick["kinematics"], pick["mode"], pick["dt_s"]) == ("exact", "event", 5e-5)
    assert a["physics_disagreements"][0]["level"].startswith("reduced kinematics")
    num = a["per_scene"]["s"]["cheapest_numerically_converged"]
    assert num["kinematics"] == "reduced"  # numerically fine, physically another answer


def _cli(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def test_cli_studies_json_table_plot(tmp_path):
    pytest.importorskip("pyarrow")  # --out FILE.parquet
    r = _cli("fidelity", "--json", "--scenes", "single", "--repeats", "1",
             "--out", str(tmp_path / "fid.parquet"), "--plot", str(tmp_path / "fid.png"))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["per_scene"]["single"]["faithful"]["outcome"] == "detached"  # exact kinematics
    assert (tmp_path / "fid.parquet").stat().st_size > 0
    assert (tmp_path / "fid.png").read_bytes()[:4] == b"\x89PNG"
    r = _cli("engage", "--json", "--freqs", "500", "--x0=-0.2e-3,0.1e-3", "--v0", "0,0.15,0.3",
             "--spacing", "0.5e-3", "--delay", "0,1e-3", "--out", str(tmp_path / "eng.csv"),
             "--plot", str(tmp_path / "eng.png"))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["map_runs"] == 6 and out["two_actuators"]["runs"] == 2
    assert (tmp_path / "eng_two.csv").exists() and (tmp_path / "eng.png").exists()
    r = _cli("engage", "--json", "--freqs", "500:100:1")
    assert r.returncode == 2 and "start:stop:step" in json.loads(r.stdout)["error"]


@pytest.mark.slow
def test_full_sensitivity_design():
    """The whole Table 3.2 design (432 combinations): every combination scanned, the fit made,
    and docs/physics.md's three stated travel trends (energy -, roughness +, stroke +) recovered."""
    from microconveyor_env.studies.sensitivity import sensitivity_rows, windows

    rows = sensitivity_rows(progress=False)
    assert len(windows(rows)) == 432
    t = regression.table34(rows)
    assert t["n"] > 1000
    stated = [r for r in t["terms"] if r["factor"] in ("dgamma", "sigma_nm", "stroke_um")]
    assert len(stated) == 7 and all(r["sign_agrees"] for r in stated)
