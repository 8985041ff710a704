"""Sweeps, feasible windows and the accuracy study's default choice (docs/physics.md §5 trends)."""
import numpy as np
import pytest

from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.studies.accuracy import pick_default
from microconveyor_env.studies.sweep import Scene, feasible_window, parse_values, sweep


def test_parse_values():
    assert parse_values("200:300:50", "freq") == [200.0, 250.0, 300.0]
    assert parse_values("1e-4,2e-4", "stroke") == [1e-4, 2e-4]
    assert parse_values("gaussian,sinusoidal", "profile") == ["gaussian", "sinusoidal"]
    for bad in ("300:200:50", "200:300:0", "a:b:c", "1,x"):
        with pytest.raises(ParameterError):
            parse_values(bad, "freq")


def test_feasible_window_rules():
    vals = [100, 200, 300, 400, 500]
    assert feasible_window(vals, [1e-6, 2e-5, 5e-5, 1e-4, 0.0],
                           ["rest", "rest", "rest", "rest", "detached"]) == [200, 400]
    assert feasible_window(vals, [1e-6] * 5, ["rest"] * 5) is None
    # the window ends below the first detachment even if later values do not detach
    assert feasible_window(vals, [2e-5] * 5, ["rest", "detached", "rest", "rest", "rest"]) == [100, 100]


def _travel(param, values, **base):
    res = sweep(Scene(**base), param, values, progress=False)
    return np.abs(res["displacement_m"]), res["outcome"], res


def test_more_roughness_less_friction_more_travel():
    travel, outcome, _ = _travel("sigma", [15e-9, 17.5e-9, 20e-9])
    assert all(o == "rest" for o in outcome)
    assert travel[0] < travel[1] < travel[2]


def test_more_surface_energy_less_travel():
    travel, outcome, _ = _travel("dgamma", [1.0, 1.25, 1.5])
    assert all(o == "rest" for o in outcome)
    assert travel[0] > travel[1] > travel[2]


def test_larger_mass_narrower_window_at_lower_frequencies():
    freqs = list(np.arange(200.0, 2001.0, 25.0))  # wide enough that every window ends in detachment
    runs = [_travel("freq", freqs, mass=m) for m in (1e-9, 2e-9, 4e-9)]
    assert all("detached" in outcome for _, outcome, _ in runs)
    windows = [res["window_hz"] for _, _, res in runs]
    widths = [hi - lo for lo, hi in windows]
    assert windows[0][1] > windows[1][1] > windows[2][1]  # upper bound falls
    assert widths[0] > widths[1] > widths[2]


def test_pick_default_requires_tolerance_at_all_finer_steps():
    rows = [
        {"mode": "karnopp", "kinematics": "reduced", "dt_s": 4e-5, "error_m": 1e-7, "wall_time_s": 1.0},
        {"mode": "karnopp", "kinematics": "reduced", "dt_s": 2e-5, "error_m": 5e-6, "wall_time_s": 2.0},
        {"mode": "event", "kinematics": "reduced", "dt_s": 4e-5, "error_m": 3e-7, "wall_time_s": 3.0},
        {"mode": "event", "kinematics": "reduced", "dt_s": 2e-5, "error_m": 1e-8, "wall_time_s": 4.0},
    ]
    d = pick_default(rows, "reduced", 1e-6)
    assert d["mode"] == "event" and d["dt_s"] == 4e-5  # the lucky Karnopp hit is not accepted
