"""The time-weighted cost written once (agents/planning/cost.py): the dissertation's problem
scores with it, on hand-computed cases."""
import numpy as np
import pytest

from agents.openloop.dissertation import DissertationProblem, dissertation_cost
from agents.planning.cost import EXPONENT, PENALTY, TIME_WEIGHT, time_weighted_cost


def test_time_weighted_cost_hand_computed_and_the_dissertations():
    assert (TIME_WEIGHT, EXPONENT, PENALTY) == (1e3, 10.0, 1e5)
    # at rest 20 µm short of a ±50 µm request after 37 ms: 37 + 0.4^10; 100 µm off: 2^10
    c = time_weighted_cost([-20e-6, 100e-6], [0.037, 0.05], [True, True], 1e3, 50e-6, 10.15e-3)
    assert c == pytest.approx([37.0 + 0.4 ** 10, 50.0 + 1024.0], rel=1e-12)
    # not at rest: the penalty on top of the start's error (10.15 mm = 203 T_d), whatever the
    # error (NaN included) and time
    det = time_weighted_cost([np.nan, 1e-6], [0.004, 0.0], [False, False], 1e3, 50e-6, -10.15e-3)
    assert det[0] == det[1] == pytest.approx(1e5 + 203.0 ** 10, rel=1e-12)
    # a tighter request: the same 20 µm error is now 2 T_d
    assert time_weighted_cost(20e-6, 0.01, True, 1e3, 10e-6, 1e-3) == pytest.approx(10.0 + 1024)
    # the dissertation's problem scores with it, bit for bit
    p = DissertationProblem()
    x = np.array([10.02e-3, 9.9e-3, 5e-3, -0.1e-3])
    t = np.array([0.037, 0.05, 0.004, 0.02])
    rest = np.array([True, True, False, True])
    want = time_weighted_cost(x - p.target_m, t, rest, p.time_weight, p.scale_m,
                              p.x0_m - p.target_m)
    assert np.array_equal(dissertation_cost(x, t, rest, p), want)
    assert dissertation_cost(10.02e-3, 0.037, True, p) == pytest.approx(37.0 + 0.4 ** 10,
                                                                         rel=1e-12)
