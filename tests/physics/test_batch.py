"""Batched runs (physics/batch.py): row for row the same as Simulator.simulate, serial or
parallel, each row with its own actuator positions; inputs checked."""
import numpy as np
import pytest

from microconveyor_env import presets
from microconveyor_env.physics.batch import simulate_batch
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.physics.schedule import ActuatorArray, Schedule


@pytest.fixture(scope="module")
def sim():
    return presets.simulator("feasibility", dt=1e-4, min_steps=48, max_time=1.0)


def test_rows_match_simulate_serial_and_parallel(sim):
    rng = np.random.default_rng(3)
    b, n = 12, 3
    f = rng.uniform(300, 1500, (b, n))
    h = rng.uniform(100e-6, 200e-6, (b, n))
    d = rng.uniform(0, 5e-3, (b, n))
    s = rng.uniform(0.3e-3, 0.8e-3, b)
    xa = np.arange(n)[None, :] * s[:, None]
    x0 = rng.uniform(-0.2e-3, -0.05e-3, b)
    par = simulate_batch(sim, xa, f, h, d, x0)
    ser = simulate_batch(sim, xa, f, h, d, x0, parallel=False)
    for i in range(b):
        one = sim.simulate(Schedule.sequence(ActuatorArray(tuple(xa[i])), f[i], h[i], d[i]),
                           x0[i])
        for res in (par, ser):
            assert res.final_position_m[i] == one.final_position_m
            assert res.end_time_s[i] == one.end_time_s and res.outcome[i] == one.outcome
    assert {"rest", "detached"} >= set(par.outcome)


def test_detachment_reported(sim):
    r = simulate_batch(sim, [[0.0]], 3000.0, 200e-6, 0.0, -0.1e-3)
    assert r.outcome[0] == "detached" and np.isfinite(r.event_position_m[0])


def test_bad_inputs(sim):
    with pytest.raises(ParameterError, match="xa must be"):
        simulate_batch(sim, [0.0, 1e-3], 1000.0, 1e-4, 0.0, 0.0)
    with pytest.raises(ParameterError, match=r"f\[0, 1\]"):
        simulate_batch(sim, [[0.0, 1e-3]], [[1000.0, -1.0]], 1e-4, 0.0, 0.0)
    with pytest.raises(ParameterError, match="delay"):
        simulate_batch(sim, [[0.0]], 1000.0, 1e-4, np.nan, 0.0)
