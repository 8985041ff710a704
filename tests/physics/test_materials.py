"""MEMS material presets (docs/physics.md §9): their tables, forces and windows, the validity bounds
of the contact inputs (§2.1), and what a preset file with unknown or missing keys is told."""
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from microconveyor_env.physics.contact_table import ContactTable, consistent, tabulation_error
from microconveyor_env.physics.materials import ContactParams, ParameterError, Surface
from microconveyor_env.physics.rough_surface import Normalised, SurfaceIntegrals
from microconveyor_env.presets import (PresetError, PresetWarning, available_presets, load_preset,
                                       params_from_dict)
from support.ke_reference import reference_integrals
from support.scripts import load_script

ROOT = Path(__file__).resolve().parents[2]
MEMS = ("silicon", "polysilicon", "silicon_oxide", "silicon_nitride", "gold")


def _doc_rows():
    """preset -> the cells of its row in the materials table of docs/physics.md."""
    text = (ROOT / "docs" / "physics.md").read_text()
    table = text.split("<!-- materials-table:start", 1)[1].split("<!-- materials-table:end", 1)[0]
    rows = {}
    for line in table.splitlines():
        m = re.match(r"\| `(\w+)` \| (.*) \|$", line)
        if m:
            rows[m.group(1)] = [c.strip() for c in m.group(2).split(" | ")]
    return rows


def test_every_shipped_preset_is_complete_and_in_the_materials_table():
    assert set(MEMS) <= set(available_presets())
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # complete: no PresetWarning
        for name in available_presets():
            load_preset(name)
    assert set(_doc_rows()) == set(available_presets())


@pytest.mark.parametrize("name", MEMS)
def test_mems_preset_builds_its_table_with_finite_positive_forces(name):
    p = load_preset(name)
    c = p.contact
    assert p.calibration == {} and c.friction_scale == 1.0      # pure KE, as documented
    assert 1e-9 <= c.surface.sigma <= 10e-9 and c.asperity_radius >= c.surface.sigma
    table = ContactTable(c)
    assert consistent(table.base)
    table.check_weight()
    forces = p.forces()
    assert all(math.isfinite(v) and v > 0 for v in forces.values()), forces
    assert table.max_load > 1e3 * c.part.weight          # far above any load of a firing
    assert tabulation_error(table, samples=300)["max_rel_error_Q"] < 1e-6
    # converged: half the node spacing changes nothing that matters
    fine = ContactTable(c, spacing=0.005)
    assert fine.pull_off_force == pytest.approx(table.pull_off_force, rel=1e-8)
    assert float(fine.friction(c.part.weight)) == pytest.approx(forces["friction_at_weight_N"],
                                                                rel=1e-8)
    # the quadrature against scipy's adaptive one, at pull-off and at the most compressed node
    norm = Normalised.from_params(c)
    for d_star in (table.base.d_pull, table.base.d[-1]):
        got = SurfaceIntegrals(norm).evaluate([d_star])
        ref = reference_integrals(norm, d_star)
        for key in "PCQG":
            assert got[key][0] == pytest.approx(ref[key], rel=1e-9), (key, d_star)


@pytest.mark.parametrize("name", MEMS)
def test_mems_preset_window_or_reason_is_the_documented_one(name):
    """The window of the table's sweep (100 Hz-10 kHz, 25 Hz steps), or the reason there is none,
    is what docs/physics.md §9 says; and the force columns match Preset.forces()."""
    script = load_script("materials_table")
    row = script.row(name)
    doc = _doc_rows()[name]
    assert doc[4:9] == script.force_cells(row)
    w = row["sweep"]
    assert doc[9] == script.window_cell(w)
    if w["window_hz"] is None:
        assert w["no_window_reason"].startswith("no window: the part never moved 10 µm or more")
    else:
        lo, hi = w["window_hz"]
        assert lo <= hi and w["max_travel_m"] >= 10e-6


def test_nm_roughness_is_accepted_where_ke_holds():
    s = Surface(sigma=2e-9, psi=0.6, dgamma=0.1)
    assert s.sigma == 2e-9
    ContactParams(surface=Surface(sigma=1e-9, psi=0.5, dgamma=0.1))   # the floor itself
    table = ContactTable(load_preset("silicon").contact)            # sigma = 2 nm
    assert table.pull_off_force > 0


def test_roughness_below_the_asperity_model_says_why_and_names_the_reference():
    with pytest.raises(ParameterError) as info:
        Surface(sigma=0.5e-9)
    msg = str(info.value)
    assert "Surface.sigma = 5e-10" in msg and "[1e-09, 1e-06]" in msg
    assert "Greenwood & Williamson (1966)" in msg and "Kogut" in msg and "eps" in msg


def test_psi_outside_ke_says_why_and_names_the_reference():
    si = load_preset("silicon").contact
    with pytest.raises(ParameterError) as info:
        si.replace(surface__psi=20.0)         # asperity radius below sigma
    msg = str(info.value)
    assert "Surface.psi = 20.0" in msg and "Kogut & Etsion 2002" in msg
    assert "asperity radius" in msg and "at most 2E/(pi K H) = 9.44" in msg
    si.replace(surface__psi=9.0)              # just inside
    # the lower bound is numerical and says so
    with pytest.raises(ParameterError, match=r"Surface.psi = 0.05 .*\[0.1, 1000\].*a numerical "
                                             r"bound, not one of the KE model"):
        Surface(psi=0.05)
    ContactTable(si.replace(surface__psi=0.1))   # the floor builds


@pytest.mark.filterwarnings("ignore::microconveyor_env.presets.PresetWarning")  # partial files
def test_unknown_preset_keys_list_the_valid_ones(tmp_path):
    with pytest.raises(PresetError, match=r"unknown preset 'silicn' \(did you mean 'silicon'\?\); "
                                          r"available: .*silicon_nitride"):
        load_preset("silicn")
    cases = {
        "surfce: {}\n": r"unknown key 'surfce' \(did you mean 'surface'\?\); valid keys: "
                        r"calibration, description, dynamics, friction_scale, materials, name, part, "
                        r"surface",
        "materials: {hardnes: 1.0e+10}\n": r"materials: unknown key 'hardnes' \(did you mean "
                                           r"'hardness'\?\); valid keys: E1, E2, hardness, nu1, nu2",
        "calibration: {pull_of_force: 1.0e-6}\n": r"calibration: unknown key 'pull_of_force' \(did "
                                                  r"you mean 'pull_off_force'\?\); valid keys: "
                                                  r"friction_force, friction_load, measured_with, "
                                                  r"pull_off_force",
        "dynamics: {kinematic: exact}\n": r"dynamics: unknown key 'kinematic' \(did you mean "
                                          r"'kinematics'\?\); valid keys: kinematics",
    }
    for i, (text, match) in enumerate(cases.items()):
        f = tmp_path / f"bad{i}.yaml"
        f.write_text(text)
        with pytest.raises((PresetError, ParameterError), match=match):
            load_preset(str(f))
    with pytest.raises(ParameterError, match="valid keys: beta, dgamma, eps, psi, sigma"):
        params_from_dict({"surface": {"roughness": 2e-9}})


def test_a_missing_key_is_named_not_silently_filled(tmp_path):
    import yaml

    full = yaml.safe_load((ROOT / "configs" / "silicon.yaml").read_text())
    del full["surface"]["dgamma"], full["friction_scale"]
    f = tmp_path / "no_dgamma.yaml"
    f.write_text(yaml.safe_dump(full))
    with pytest.warns(PresetWarning, match=r"does not give surface.dgamma, friction_scale: the "
                                           r"defaults"):
        p = load_preset(str(f))
    assert p.contact.surface.dgamma == 1.0 and p.contact.friction_scale == 1.0   # the defaults
    # a value the calibration fits is not missing: beta from the pull-off force
    full = yaml.safe_load((ROOT / "configs" / "silicon.yaml").read_text())
    del full["surface"]["beta"]
    full["calibration"] = {"pull_off_force": 5e-4}
    g = tmp_path / "fitted_beta.yaml"
    g.write_text(yaml.safe_dump(full))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = load_preset(str(g))
    assert p.calibration["fitted"] == ["beta"]
    assert ContactTable(p.contact).pull_off_force == pytest.approx(5e-4, rel=1e-10)
    assert np.isfinite(p.forces()["friction_at_weight_N"])
