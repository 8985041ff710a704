"""Stretch-dependent roughness in the dynamics (docs/physics.md §4): the compiled sigma-dependent
lookup against the Python stretch tables, zero strain = constant roughness, the study and CLI."""
import json

import numpy as np
import pytest

from microconveyor_env.cli import main
from microconveyor_env.physics import forces
from microconveyor_env.physics.kinematics import stroke_eval, zone_strain
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.physics.schedule import ActuatorArray, Schedule
from microconveyor_env.presets import simulator
from microconveyor_env.studies.engine import same_rows
from microconveyor_env.studies.stretch_study import compare, stretch_rows

N_SIGMA = 5  # a coarse sigma grid keeps the tests' table builds short


@pytest.fixture(scope="module")
def stretched():
    return simulator("feasibility", roughness="stretch", n_sigma=N_SIGMA)


@pytest.mark.parametrize("kinematics", ["reduced", "exact"])
@pytest.mark.parametrize("mode", ["event", "karnopp"])
def test_zero_strain_equals_constant_roughness(kinematics, mode):
    """With the active zone shrunk to nothing the part never sees strain: bit-identical runs."""
    const = simulator("feasibility", kinematics=kinematics, mode=mode)
    zero = simulator("feasibility", kinematics=kinematics, mode=mode, roughness="stretch",
                     zone_length=1e-12, n_sigma=N_SIGMA)
    scheds = [Schedule.single(950.0, 200e-6),
              Schedule.sequence(ActuatorArray.uniform(3, 0.3e-3), 950.0, 200e-6, 1e-3)]
    for sched in scheds:
        for x0, v0 in ((0.125e-3, 0.0), (-0.15e-3, 0.1)):
            a, b = const.simulate(sched, x0=x0, v0=v0), zero.simulate(sched, x0=x0, v0=v0)
            assert (a.final_position_m, a.outcome, a.steps, a.events, a.end_time_s) == \
                (b.final_position_m, b.outcome, b.steps, b.events, b.end_time_s)


def test_compiled_lookup_matches_the_stretch_tables(stretched):
    sim = stretched
    P, (tu, tq, tqu) = sim.params, sim.tables
    f, h = 950.0, 200e-6
    for tl in np.linspace(0.0, 1.0 / f, 9):
        amp = stroke_eval(tl, f, h)[0]
        sigma = float(sim.stretch.sigma_at_strain(zone_strain(amp, 0, 0.6e-3, 0.6e-3)))
        n_min = forces.stretch_n_min(0.0, tl, 0.0, f, h, P)
        assert n_min == pytest.approx(-float(sim.stretch.pull_off_force(sigma)), rel=1e-5)
        for load in (0.9 * n_min, 0.0, 2e-6, 5e-5):
            ref = float(sim.stretch.friction(load, sigma))
            assert forces.stretch_friction(load, 0.0, tl, 0.0, f, h, P, tu, tq, tqu) == \
                pytest.approx(ref, rel=1e-5)
            # the plain-Python dispatch (used outside compiled code) agrees
            assert forces.friction_at(load, 0.0, tl, 0.0, f, h, P, tu, tq, tqu) == \
                pytest.approx(ref, rel=1e-5)
    # outside the active zone: the unstretched table
    assert forces.stretch_n_min(0.5e-3, 0.5 / f, 0.0, f, h, P) == P[forces.I_NMIN]


def test_strain_beyond_the_tables_is_refused():
    sim = simulator("feasibility", roughness="stretch", max_strain=0.1, n_sigma=2)
    with pytest.raises(ParameterError, match="max_strain"):
        sim.simulate(Schedule.single(950.0, 200e-6), x0=0.125e-3)
    with pytest.raises(ParameterError, match="roughness"):
        simulator("feasibility", roughness="wrinkled")


def test_stretch_study_parallel_equals_serial_and_compares(dask_client):
    kw = dict(freqs=(500.0, 950.0, 1400.0), repeats=1, sim_kw={"n_sigma": N_SIGMA})
    serial = stretch_rows(progress=False, **kw)
    assert same_rows(serial, stretch_rows(progress=False, client=dask_client, chunk_size=1, **kw))
    c = compare(serial)
    assert c["both_rest_runs"] == 2 and c["cost_ratio"] > 0
    assert {r["roughness"] for r in serial} == {"constant", "stretch"}


def test_cli_stretch_and_simulate_roughness(capsys, tmp_path):
    pytest.importorskip("pandas")  # --out writes a table
    assert main(["stretch", "--json", "--freq", "500,950", "--repeats", "1", "--n-sigma",
                 str(N_SIGMA), "--no-progress", "--out", str(tmp_path / "s.csv")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["peak_strain"] == pytest.approx(zone_strain(200e-6, 0, 0.6e-3, 0.6e-3))
    assert (tmp_path / "s.csv").exists() and out["both_rest_runs"] == 2
    assert main(["simulate", "--json", "--roughness", "stretch"]) == 0
    assert json.loads(capsys.readouterr().out)["outcome"] == "rest"
