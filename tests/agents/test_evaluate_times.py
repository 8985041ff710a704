"""The placement time every evaluation reports beside the error: the simulated time until the
part rests, over the episodes that ended at rest (median and 90th percentile, SI seconds)."""
import numpy as np
import pytest

from agents.rl.evaluation.evaluate import TOLERANCES, figures, placement_times


def test_placement_times_are_of_the_parts_that_rested():
    t = [0.040, 0.010, 0.050, 0.060, 0.030, 0.002]
    outcome = ["rest", "detached", "rest", "rest", "rest", "detached"]
    got = placement_times(t, outcome)
    assert got["median_placement_time_s"] == pytest.approx(0.045)   # of 0.03, 0.04, 0.05, 0.06
    assert got["p90_placement_time_s"] == pytest.approx(0.057)      # 0.05 + 0.7 * 0.01
    assert placement_times(t[:2], ["detached"] * 2) == {"median_placement_time_s": None,
                                                        "p90_placement_time_s": None}
    with pytest.raises(ValueError, match="one of each"):
        placement_times(t, outcome[:3])


def test_figures_report_the_time_and_the_tight_radii():
    res = {"error_m": np.array([4e-6, -8e-6, 15e-6, 2e-3]), "firings": np.array([3, 4, 4, 2]),
           "outcome": np.array(["rest", "rest", "rest", "detached"], dtype=object),
           "time_s": np.array([0.03, 0.05, 0.04, 0.01])}
    f = figures(res, 50e-6)
    assert {f"success_rate_{round(r * 1e6)}um" for r in TOLERANCES} >= {
        "success_rate_5um", "success_rate_10um", "success_rate_20um", "success_rate_50um"}
    assert (f["success_rate_5um"], f["success_rate_10um"], f["success_rate_20um"]) == \
        (0.25, 0.5, 0.75)
    assert f["median_placement_time_s"] == pytest.approx(0.04)
    # a stored record of errors alone (no times) is still summarised, without the times
    assert "median_placement_time_s" not in figures(
        {k: v for k, v in res.items() if k != "time_s"}, 50e-6)
