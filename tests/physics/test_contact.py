"""KE rough-surface integrals, the contact table, calibration and presets."""
import math

import numpy as np
import pytest

from microconveyor_env.physics.calibration import Calibration, calibrate
from microconveyor_env.physics.contact_table import (ContactTable, DetachmentError,
                                                     TableRangeError, tabulation_error)
from microconveyor_env.physics.materials import ContactParams
from microconveyor_env.physics.rough_surface import Normalised, SurfaceIntegrals, surface_forces
from support.ke_reference import reference_forces as _reference_forces
from support.ke_reference import reference_integrals as _reference_integrals
from support.ke_reference import reference_normal as _reference_normal


@pytest.mark.parametrize("d_star", [0.5, 2.0, 3.86, 4.35, 6.0])
def test_quadrature_matches_adaptive_reference(feasibility_preset, d_star):
    norm = Normalised.from_params(feasibility_preset.contact)
    got = SurfaceIntegrals(norm).evaluate([d_star])
    ref = _reference_integrals(norm, d_star)
    for key in "PCQG":
        assert got[key][0] == pytest.approx(ref[key], rel=1e-8), key


def test_derivatives_match_finite_differences(feasibility_preset):
    ints = SurfaceIntegrals(Normalised.from_params(feasibility_preset.contact))
    d, h = np.array([1.0, 3.0, 4.3]), 1e-4
    r = ints.evaluate(d, derivatives=2)
    rp, rm = ints.evaluate(d + h), ints.evaluate(d - h)
    for key in "PCQG":
        fd1 = (rp[key] - rm[key]) / (2 * h)
        fd2 = (rp[key] - 2 * r[key] + rm[key]) / h ** 2
        np.testing.assert_allclose(r["d" + key], fd1, rtol=1e-6)
        np.testing.assert_allclose(r["dd" + key], fd2, rtol=1e-4)


@pytest.mark.parametrize("d_star,F32", [(1.0, 7.56682e-2), (2.0, 6.64818e-3)])
def test_greenwood_williamson_limit(d_star, F32):
    """All-elastic fits: P = (4/3) eta A_n E R^1/2 sigma^3/2 F_3/2(d*)."""
    p = ContactParams()
    f = surface_forces(p, [d_star * p.surface.sigma], load_model="elastic")
    gw = (4 / 3 * p.asperity_count * p.materials.E * math.sqrt(p.asperity_radius)
          * p.surface.sigma ** 1.5 * F32)
    assert f["P_N"][0] == pytest.approx(gw, rel=2e-6)  # F_3/2 quoted to 6 digits


def test_table_error_against_quadrature_below_1e4(feasibility_table):
    err = tabulation_error(feasibility_table, samples=3000)
    assert err["max_rel_error_Q"] <= 1e-4
    assert err["max_abs_error_d_over_sigma"] <= 1e-6


def test_inversion_round_trip(feasibility_table):
    loads = np.concatenate([-feasibility_table.pull_off_force * np.array([1.0, 0.999999, 0.5, 0.0]),
                            np.geomspace(1e-9, 0.5 * feasibility_table.max_load, 50)])
    d = feasibility_table.separation(loads)
    back = surface_forces(feasibility_table.params, d)["N_N"]
    scale = np.maximum(np.abs(loads), feasibility_table.pull_off_force)
    assert np.max(np.abs(back - loads) / scale) < 1e-7
    assert np.all(np.diff(d[4:]) < 0)  # more load, smaller separation


def test_stable_branch_is_monotone(feasibility_table):
    b = feasibility_table.base
    assert np.all(np.diff(b.n) > 0) and np.all(np.diff(b.u) > 0) and np.all(np.diff(b.d) < 0)
    assert b.d[0] == pytest.approx(b.d_pull) and b.n[0] == pytest.approx(b.n_min)
    # the minimum is a minimum: N rises beyond d_A as well
    f = surface_forces(feasibility_table.params, np.array([b.d_pull + 0.05]) * feasibility_table.params.surface.sigma)
    assert f["N_N"][0] > -feasibility_table.pull_off_force


def test_feasibility_preset_reference_figures(feasibility_table):
    r = feasibility_table.report()
    assert 70e-9 <= r["balance_separation_m"] <= 80e-9
    assert 80e-9 <= r["pull_off_separation_m"] <= 90e-9
    assert r["pull_off_force_N"] == pytest.approx(6.2e-6, rel=0.05)
    assert r["friction_at_weight_N"] == pytest.approx(8e-8, rel=0.05)
    assert r["slip_acceleration_flat_m_s2"] == pytest.approx(40, rel=0.05)  # docs/physics.md §5


def test_conveyor_preset_figures_against_direct_ke_evaluation():
    """Chapter 4's surface (Table 4.2, dgamma 0.5 J/m^2) with chapter 3's beta and friction scale:
    its pull-off force (the minimum of N over the separation) and Q at the weight, found by
    scipy's bounded minimiser and root finder on the adaptive quadrature of the KE integrals,
    agree with the preset's table and report (docs/physics.md §8: 2.53 uN, 17.5 nN, 8.8 m/s^2)."""
    from scipy import optimize

    from microconveyor_env.presets import load_preset

    conv, feas = load_preset("conveyor"), load_preset("feasibility")
    c = conv.contact
    assert c.surface.dgamma == 0.5 and feas.contact.surface.dgamma == 1.0
    # beta and the friction scale are carried over exactly; everything else is Table 4.2's
    assert c.surface.beta == feas.contact.surface.beta
    assert c.friction_scale == feas.contact.friction_scale
    assert c.replace(surface__dgamma=1.0) == feas.contact
    assert conv.calibration["measured_with"] == {"dgamma": 1.0}
    table = ContactTable(c)
    res = optimize.minimize_scalar(lambda d: _reference_normal(c, d),
                                   bounds=(table.base.d_pull - 0.5, table.base.d_pull + 0.5),
                                   method="bounded", options={"xatol": 1e-9})
    pull_off = -res.fun
    weight = c.part.weight
    d_w = optimize.brentq(lambda d: _reference_normal(c, d) - weight, 0.0, table.base.d_pull,
                          xtol=1e-14, rtol=1e-14)
    q_w = _reference_forces(c, d_w)[1]
    forces = conv.forces()
    assert forces["pull_off_force_N"] == pytest.approx(pull_off, rel=1e-7)
    assert forces["friction_at_weight_N"] == pytest.approx(q_w, rel=1e-6)
    assert forces["slip_deceleration_m_s2"] == pytest.approx(q_w / c.part.mass, rel=1e-6)
    assert 2.4e-6 < pull_off < 2.7e-6 and 1.6e-8 < q_w < 1.9e-8   # the figures docs quote
    # less surface energy: less pull-off and less friction than chapter 3's surface
    assert pull_off < 6.2e-6 * 0.5 and q_w < 8e-8


@pytest.mark.filterwarnings("ignore::microconveyor_env.presets.PresetWarning")  # partial files
def test_measured_with_is_validated(tmp_path):
    from microconveyor_env.physics.materials import ParameterError
    from microconveyor_env.presets import load_preset

    for bad, match in (("{beta: 0.1}", "cannot set beta"), ("{dgama: 1.0}", "surface fields"),
                       ("[1.0]", "surface fields")):
        f = tmp_path / "bad.yaml"
        f.write_text(f"calibration: {{pull_off_force: 6.2e-6, measured_with: {bad}}}\n")
        with pytest.raises(ParameterError, match=match):
            load_preset(str(f))


def test_ke_preset_is_uncalibrated():
    from microconveyor_env.presets import load_preset

    ke = load_preset("ke")
    assert ke.calibration == {} and ke.contact.friction_scale == 1.0
    assert ke.contact.surface.beta == 0.04


def test_detachment_is_a_distinct_result_never_nan(feasibility_table):
    F = feasibility_table.pull_off_force
    with pytest.raises(DetachmentError) as info:
        feasibility_table.friction(-1.0001 * F)
    assert info.value.pull_off == pytest.approx(F)
    with pytest.raises(DetachmentError):
        feasibility_table.separation(np.array([0.0, -2 * F]))
    assert feasibility_table.is_detached(-1.01 * F) and not feasibility_table.is_detached(-0.99 * F)
    q = feasibility_table.friction(np.linspace(-F, 1e-3, 10001))
    assert np.all(np.isfinite(q)) and np.all(q > 0)
    with pytest.raises(TableRangeError):
        feasibility_table.friction(2 * feasibility_table.max_load)
    with pytest.raises(ValueError):
        feasibility_table.friction(float("nan"))


def test_calibration_fits_any_targets(feasibility_preset):
    base = ContactParams()
    target = Calibration(pull_off_force=3e-6, friction_force=2e-7, friction_load=1e-7)
    fitted, report = calibrate(base, target)
    t = ContactTable(fitted)
    assert t.pull_off_force == pytest.approx(3e-6, rel=1e-10)
    assert float(t.friction(1e-7)) == pytest.approx(2e-7, rel=1e-10)
    assert report["fitted"] == ["beta", "friction_scale"]
    assert feasibility_preset.calibration["fitted"] == ["beta", "friction_scale"]
    # calibration leaves the separations alone
    assert t.pull_off_separation == pytest.approx(ContactTable(base).pull_off_separation, rel=1e-12)


def test_friction_only_calibration_keeps_beta():
    base = ContactParams()
    fitted, report = calibrate(base, Calibration(friction_force=1e-7))
    assert fitted.surface.beta == base.surface.beta and report["fitted"] == ["friction_scale"]
    assert float(ContactTable(fitted).friction(base.part.weight)) == pytest.approx(1e-7, rel=1e-10)
