"""The frontier study's library (agents/experiments/frontier.py): its table from stored rows, and
one method's row on a couple of targets."""
import numpy as np

from agents.experiments.frontier import (RADII, frontier_row, frontier_table, methods_for,
                                         row_figures)

ROW = {"env_id": "MicroConveyor-v1", "level": "nominal", "method": "staged_expert",
       "request_tolerance_m": 10e-6, "n_targets": 500, "success_rate_50um": 1.0,
       "success_rate_20um": 0.99, "success_rate_10um": 0.95, "success_rate_5um": 0.5,
       "median_abs_error_m": 4.2e-6, "p90_abs_error_m": 9e-6, "detach_rate": 0.0,
       "median_placement_time_s": 0.0451, "p90_placement_time_s": None,
       "wall_s_per_target": 0.004}


def test_table_renders_stored_rows():
    text = frontier_table({"env_id": "MicroConveyor-v1", "rows": [ROW]})
    lines = text.splitlines()
    assert len(lines) == 3 and lines[0].count("|") == lines[2].count("|")
    assert "| nominal | staged_expert | 10 | 500 | 100 % | 99 % | 95 % | 50 % | 4.2 | 9.0 |" \
        in lines[2]
    assert "| 45.1 | – |" in lines[2]   # ms, and a missing figure as a dash


def test_figures_count_only_parts_at_rest():
    row = row_figures([1e-6, 30e-6, 1e-6], ["rest", "rest", "detached"], [0.04, 0.06, 0.01])
    assert row["success_rate_5um"] == 1 / 3 and row["success_rate_50um"] == 2 / 3
    assert row["median_placement_time_s"] == 0.05 and row["detach_rate"] == 1 / 3
    assert row_figures([1e-3], ["detached"], [0.01])["median_placement_time_s"] is None


def test_one_method_row_on_two_targets():
    (staged,) = methods_for("MicroConveyor-v1", ["staged_expert"])
    row = frontier_row("MicroConveyor-v1", "nominal", staged, 20e-6, np.array([3e-3, 8e-3]))
    assert {f"success_rate_{round(r * 1e6)}um" for r in RADII} <= set(row)
    for key in ("env_id", "level", "method", "request_tolerance_m", "n_targets",
                "median_abs_error_m", "p90_abs_error_m", "detach_rate",
                "median_placement_time_s", "p90_placement_time_s", "wall_s_per_target"):
        assert key in row
    assert row["n_targets"] == 2 and row["request_tolerance_m"] == 20e-6
    assert row["median_placement_time_s"] > 0 and row["success_rate_20um"] == 1.0
