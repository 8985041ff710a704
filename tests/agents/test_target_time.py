"""Open-loop plans on request (agents/openloop/target.py ``time_weight``): the time-weighted
search trades placement time for precision within the tolerance asked for."""
import pytest

from agents.openloop.target import solve_target
from agents.planning import LineRollouts
from microconveyor_env.envs.core.versions import scene_config


def test_time_weighted_de_rests_within_the_request_no_later():
    # measured: at 1 mm on MicroConveyor-v1 with 400 episodes, seeds 0-9 all rest within
    # ±50 µm with time weight 1e3 1/s, 17-42 ms against 32-111 ms for precision only
    roll = LineRollouts(scene_config("MicroConveyor-v1", num_threads=1))
    prec = solve_target(1e-3, "de", 400, 3, rollouts=roll)
    quick = solve_target(1e-3, "de", 400, 3, rollouts=roll, time_weight=1e3)
    assert quick.time_weight == 1e3 and prec.time_weight is None
    assert quick.outcome == "rest" and quick.success and quick.abs_error_m <= 50e-6
    assert quick.sim_time_s <= prec.sim_time_s
    with pytest.raises(ValueError, match="time_weight"):
        solve_target(1e-3, "de", 40, 0, rollouts=roll, time_weight=-1.0)
