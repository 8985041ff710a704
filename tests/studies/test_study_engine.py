"""The studies' engine: serial = local Dask cluster = existing scheduler, row for row; tables."""
import math
from pathlib import Path

import pytest

from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.studies import engage, fidelity, sobol
from microconveyor_env.studies.engine import TIMING_COLUMNS, chunked, read_table, run_tasks, \
    same_rows, write_table
from microconveyor_env.studies.sensitivity import sensitivity_rows

TINY_LEVELS = {"dgamma_J_m2": (1.0,), "sigma_m": (20e-9, 30e-9), "stroke_m": (200e-6,),
               "mass_kg": (2e-9,), "wavelength_m": (0.6e-3,), "x0_wl": (0.2, 0.33)}
TINY_SCAN = tuple(float(f) for f in (150, 250, 400, 600, 900, 1300, 1900))


def _square(task):
    return [{"i": task["i"], "sq": task["i"] ** 2}]


def test_serial_rows_in_task_order_and_chunking():
    rows = run_tasks(_square, [{"i": i} for i in range(7)], progress=False)
    assert [r["i"] for r in rows] == list(range(7))
    assert chunked(list(range(7)), 3) == [[0, 1, 2], [3, 4, 5], [6]]
    with pytest.raises(ParameterError):
        run_tasks(_square, [], workers=-1, progress=False)


def test_same_rows_ignores_timing_only():
    a = [{"x": 1.0, "y": math.nan, "wall_time_s": 1.0}]
    assert same_rows(a, [{"x": 1.0, "y": math.nan, "wall_time_s": 2.0}])
    assert not same_rows(a, [{"x": 1.0 + 1e-15, "y": math.nan, "wall_time_s": 1.0}])
    assert "wall_time_s" in TIMING_COLUMNS


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_tables_round_trip(tmp_path, suffix):
    pytest.importorskip("pandas")
    if suffix == "parquet":
        pytest.importorskip("pyarrow")
    rows = [{"freq_hz": 500.0, "outcome": "rest", "distance_m": 1e-4},
            {"freq_hz": 700.0, "outcome": "detached", "distance_m": math.nan}]
    path = write_table(rows, tmp_path / f"t.{suffix}")
    df = read_table(path)
    assert list(df.columns) == ["freq_hz", "outcome", "distance_m"] and len(df) == 2
    assert df["distance_m"][0] == 1e-4 and math.isnan(df["distance_m"][1])
    with pytest.raises(ParameterError):
        write_table(rows, tmp_path / "t.txt")


def test_interrupted_table_write_leaves_nothing(tmp_path, monkeypatch):
    """A write cut short (here a Ctrl-C halfway) leaves neither the table nor a temporary file."""
    pd = pytest.importorskip("pandas")

    def half_then_ctrl_c(self, path, **kw):
        Path(path).write_text("freq_hz\n5")
        raise KeyboardInterrupt

    monkeypatch.setattr(pd.DataFrame, "to_csv", half_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        write_table([{"freq_hz": 500.0}], tmp_path / "t.csv")
    assert list(tmp_path.iterdir()) == []


def _studies():
    """Each study on a tiny grid: (name, function of engine keywords -> rows)."""
    return {
        "sensitivity": lambda **kw: sensitivity_rows(TINY_LEVELS, n_freq=3, scan_hz=TINY_SCAN,
                                                     **kw),
        "sobol": lambda **kw: sobol.sobol_rows(2, scan_hz=TINY_SCAN, **kw),
        "engage": lambda **kw: engage.engage_map_rows((500.0,), 150e-6, (-0.2e-3, 0.1e-3),
                                                      (-0.2, 0.0, 0.15, 0.3), **kw),
        "two": lambda **kw: engage.two_actuator_rows(spacings=(0.4e-3, 0.6e-3),
                                                     delays=(0.0, 1e-3), **kw),
        "fidelity": lambda **kw: fidelity.fidelity_rows(("single",), dts=(5e-5,),
                                                        modes=("event",), roughness=("constant",),
                                                        repeats=1, **kw),
    }


@pytest.mark.parametrize("name", list(_studies()))
def test_parallel_equals_serial(name, dask_client):
    study = _studies()[name]
    serial = study(progress=False)
    parallel = study(progress=False, client=dask_client, chunk_size=1)
    assert len(serial) > 0
    assert same_rows(serial, parallel)


def test_existing_scheduler_address(dask_client):
    study = _studies()["engage"]
    rows = study(progress=False, scheduler=dask_client.scheduler.address)
    assert same_rows(rows, study(progress=False))
