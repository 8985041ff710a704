"""The console script: one JSON object on stdout, clear errors."""
import json
import subprocess
import sys

import pytest
from support.cli import run_cli


def run(*args):
    """The command in this process (what it prints and its status; tests/support/cli.py)."""
    return run_cli(*args)


def run_process(*args):
    """The console script in its own interpreter (the process's contract)."""
    return subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                          capture_output=True, text=True, timeout=300)


def test_contact_json_and_plot(tmp_path):
    png = tmp_path / "contact.png"
    r = run("contact", "--preset", "feasibility", "--json", "--plot", str(png))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("pull_off_force_N", "pull_off_separation_m", "separation_at_weight_m",
                "friction_at_weight_N", "balance_separation_m", "asperity_radius_m",
                "critical_interference_m"):
        assert isinstance(out[key], float) and out[key] > 0
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_error_is_json_with_nonzero_status():
    r = run_process("contact", "--preset", "nope", "--json")
    assert r.returncode == 2
    assert "unknown preset" in json.loads(r.stdout)["error"]


def test_simulate_json_keys_and_plot(tmp_path):
    png = tmp_path / "firing.png"
    r = run("simulate", "--preset", "feasibility", "--freq", "950", "--stroke", "200e-6", "--x0",
            "0.125e-3", "--json", "--plot", str(png))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("displacement_m", "final_position_m", "final_velocity_m_s", "outcome",
                "rest_time_s", "wall_time_s"):
        assert key in out
    assert out["outcome"] == "rest" and out["final_velocity_m_s"] == 0.0
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_sweep_reports_window_and_progress_on_stderr(tmp_path):
    png = tmp_path / "sweep.png"
    r = run("sweep", "--freq", "200:1500:100", "--stroke", "200e-6", "--json", "--plot", str(png))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)  # stdout holds only the JSON object
    lo, hi = out["window_hz"]
    assert 200 <= lo < hi < 1500
    assert len(out["displacement_m"]) == 14 and "detached" in out["outcome"]
    assert png.stat().st_size > 5_000


def test_sweep_other_parameter_and_bad_spec():
    r = run("sweep", "--freq", "700", "--stroke", "150e-6,200e-6", "--json", "--no-progress")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)["displacement_m"]
    assert abs(d[1]) > abs(d[0])  # larger stroke, more travel
    r = run("sweep", "--freq", "1500:200:25", "--json")
    assert r.returncode == 2 and "start:stop:step" in json.loads(r.stdout)["error"]


def test_simulate_bad_input_is_a_clear_error():
    r = run("simulate", "--freq", "-5", "--json")
    assert r.returncode == 2 and "Firing.frequency" in json.loads(r.stdout)["error"]


def test_bench_without_reference_runs():
    r = run("bench", "--json", "--repeats", "5", "--skip-reference")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for mode in ("event", "karnopp"):
        assert out["modes"][mode]["median_wall_time_s"] > 0 and out["modes"][mode]["kernel_steps_per_s"] > 0


def test_bench_plane_reports_the_2d_cost_ratio():
    """``bench --plane``: the plane's firing on the line takes the 1-D firing's steps; the cost
    ratios are positive numbers (their size is a measurement: docs/validation.md)."""
    r = run("bench", "--json", "--repeats", "5", "--skip-reference", "--plane")
    assert r.returncode == 0, r.stderr
    plane = json.loads(r.stdout)["plane"]
    assert plane["plane_on_line"]["steps"] == plane["line"]["steps"]
    assert plane["plane_on_line_cost_ratio"] > 0 and plane["plane_off_axis_cost_ratio"] > 0


def test_demo_writes_charts_and_summary(tmp_path):
    """The demo on MicroConveyor-v0 (chapter 3's surface, whose figures are validated); the
    default env's demo: tests/cli/test_demo.py."""
    r = run("demo", "--env", "MicroConveyor-v0", "--out", str(tmp_path), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for name in ("contact.png", "firing.png", "sweep.png", "episode.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert out["window_hz"][0] < out["window_hz"][1]
    assert out["episode"]["outcome"] in ("rest", "detached", "max_time")
    # the charted numbers are the validated ones (docs/validation.md), not just non-empty files
    summary = json.loads((tmp_path / "summary.json").read_text())
    firing = summary["reference_firing"]
    assert firing["outcome"] == "rest"
    assert abs(firing["displacement_m"] + 1164e-6) < 2e-6       # 1164 µm towards the actuator
    assert firing["wall_time_s"] < 0.05                         # steady state, not the compile
    assert summary["window_hz"] == [225.0, 1250.0]


def test_a_missing_optional_package_names_the_extra_to_install():
    from microconveyor_env.cli.base import fail, missing_extra

    exc = ModuleNotFoundError("No module named 'pandas'", name="pandas")
    assert "pip install 'microconveyor-env[studies]'" in missing_extra(exc)
    assert missing_extra(ModuleNotFoundError("x", name="numpy_not_an_extra")) is None
    assert fail(["--json"], "stretch", exc) == 2


def test_negative_values_follow_their_option():
    """``--x0 -0.125e-3`` (an exponent makes argparse take it for an option) works as
    ``--x0=-0.125e-3``: the mirror image of the reference firing."""
    from microconveyor_env.cli.base import attach_negative_values

    assert attach_negative_values(["simulate", "--x0", "-0.125e-3", "--json"]) == \
        ["simulate", "--x0=-0.125e-3", "--json"]
    assert attach_negative_values(["--a", "-1", "-v", "--b=2", "-3e2"]) == \
        ["--a=-1", "-v", "--b=2", "-3e2"]          # short flags and "=" forms are left alone
    r = run("simulate", "--freq", "950", "--stroke", "200e-6", "--x0", "-0.125e-3", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["x0_m"] == -0.125e-3 and abs(out["displacement_m"] - 1164e-6) < 2e-6


def test_a_sweep_without_window_says_why(tmp_path):
    from microconveyor_env.studies.sweep import no_window_reason

    assert no_window_reason([0.0, 1e-6], ["rest", "rest"]).startswith(
        "no window: the part never moved 10 µm")
    assert no_window_reason([1e-3, 2e-3], ["detached", "detached"]) == \
        "no window: the part detached at every value"
    # pure KE (the uncalibrated `ke` preset) barely moves the part: text, JSON and chart say so
    png = tmp_path / "sweep.png"
    r = run("sweep", "--preset", "ke", "--freq", "200:800:300", "--stroke", "200e-6",
            "--no-progress", "--plot", str(png))
    assert r.returncode == 0, r.stderr
    assert "no window: the part never moved 10 µm or more" in r.stdout
    assert png.stat().st_size > 1000
    r = run("sweep", "--preset", "ke", "--freq", "200:800:300", "--stroke", "200e-6",
            "--no-progress", "--json")
    out = json.loads(r.stdout)
    assert out["window_hz"] is None and out["no_window_reason"].startswith("no window")


def test_simulate_exports_its_trajectory(tmp_path):
    import numpy as np

    csv = tmp_path / "firing.csv"
    r = run("simulate", "--freq", "950", "--stroke", "200e-6", "--trajectory", str(csv), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["trajectory_csv"] == str(csv)
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert csv.read_text().splitlines()[0] == "t_s,x_m,v_m_s"
    assert data[0, 1] == out["x0_m"] and np.all(np.diff(data[:, 0]) >= 0)
    assert data[-1, 1] == pytest.approx(out["x0_m"] + out["displacement_m"], abs=1e-12)
    pq = pytest.importorskip("pyarrow.parquet")
    par = tmp_path / "firing.parquet"
    r = run("simulate", "--freq", "950", "--stroke", "200e-6", "--trajectory", str(par), "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["trajectory_parquet"] == str(par)
    table = pq.read_table(par)
    assert table.column_names == ["t_s", "x_m", "v_m_s"]
    np.testing.assert_array_equal(table.column("x_m").to_numpy(), data[:, 1])  # same float64s
    r = run("simulate", "--trajectory", str(tmp_path / "firing.txt"), "--json")
    assert r.returncode == 2 and ".csv or .parquet" in json.loads(r.stdout)["error"]


def test_sweep_without_a_swept_parameter_sweeps_frequency_as_its_help_says():
    from microconveyor_env.cli.simulation import DEFAULT_SWEEP

    r = run("sweep", "--help")
    assert r.returncode == 0 and "frequency by default" in r.stdout
    assert DEFAULT_SWEEP == ("freq", "200:1500:25") and "200:1500:25" in r.stdout
    r = run("sweep", "--stroke", "150e-6", "--json", "--no-progress")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["param"] == "freq" and out["stroke_m"] == 150e-6
    assert out["freq_hz"][0] == 200.0 and out["freq_hz"][-1] == 1500.0
    assert len(out["freq_hz"]) == 53
    # a fixed --freq and nothing else swept: nothing to sweep, said in one line
    r = run("sweep", "--freq", "700", "--json")
    assert r.returncode == 2 and "--freq is fixed" in json.loads(r.stdout)["error"]
