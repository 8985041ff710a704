"""Threads in the batched env: results never depend on them; the automatic choice measures."""
import pytest

from microconveyor_env.envs import MicroConveyorVectorEnv
from microconveyor_env.envs.core.threads import PROBE_EVERY, ThreadChooser

from support.lockstep import assert_lockstep_with_sync


@pytest.mark.parametrize("num_threads", [1, 2, None])
def test_threads_change_no_result_bit(num_threads):
    """Batched (serial, parallel, automatic) = SyncVectorEnv of single envs, every obs, reward,
    flag and info key, through autoresets."""
    batched = MicroConveyorVectorEnv(16, num_threads=num_threads, n_actuators=3)
    assert_lockstep_with_sync(batched, {"n_actuators": 3}, 3, 12, 7, 1.0)
    if num_threads is None:
        assert set(batched.threads.cost) == {1, batched.threads.parallel}


def test_chooser_fixed_and_small_batches():
    assert ThreadChooser(1, 64).choose() == 1
    assert ThreadChooser(2, 64).choose() == 2
    assert ThreadChooser(None, 2).choose() == 1  # a parallel region never pays for 2 parts


def test_chooser_follows_the_measurement_and_probes():
    c = ThreadChooser(None, 64)
    if c.parallel < 2:
        pytest.skip("numba has one thread here")
    first, second = c.choose(), None
    c.record(first, 1.0, 10)           # serial: 0.1 s per firing
    second = c.choose()
    assert second != first
    c.record(second, 0.01, 10)         # parallel: 10x faster
    picks = [c.choose() for _ in range(PROBE_EVERY * 2)]
    assert picks.count(second) >= len(picks) - 3 and first in picks  # mostly best, probes other
    for _ in range(20):                # the load changes: parallel becomes slow
        k = c.choose()
        c.record(k, 10.0 if k == second else 0.001, 10)  # parallel now 1 s per firing
    assert c.current == first
