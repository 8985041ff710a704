"""``stop_at_target``: the conveyor stops firing once the part would come to rest at the target.

The rule ends an episode early; it must not change where a part can rest. The reference for that
is the same episode with the option off, continued with no-op firings (a long delay, then 200 Hz
and 100 um, which leave a resting part where it is).
"""
import numpy as np
import pytest

from microconveyor_env.envs import MicroConveyorEnv, MicroConveyorVectorEnv
from microconveyor_env.physics import dynamics_kernel as K
from microconveyor_env.physics.materials import ParameterError

THROW = np.array([-0.13, 1.0, -1.0], np.float32)   # ~1.1 kHz, 200 um, no delay: leaves it moving
NOOP = np.array([-1.0, -1.0, 1.0], np.float32)     # 0.1 s delay, 200 Hz, 100 um


def _rest_after_throw() -> float:
    """Where the part, left alone after THROW as the first firing, comes to rest [m]."""
    env = MicroConveyorEnv(stop_at_target=False)
    env.reset(seed=0, options={"target": 1e-3})
    env.step(THROW)
    assert env.v > 0.0  # still sliding when the stroke ends
    x_rest, _, _, rest, _ = K.coast(env.x, env.v, 10.0, env.conveyor.consts.P[0], *env.sim.tables)
    assert rest
    return x_rest


def _episode(target: float, stop: bool) -> tuple[list, float, dict]:
    env = MicroConveyorEnv(stop_at_target=stop)
    env.reset(seed=0, options={"target": target})
    rewards, done, action = [], False, THROW
    while not done:
        _, r, term, trunc, info = env.step(action)
        rewards.append(r)
        done, action = term or trunc, NOOP
    return rewards, env.x, info


def test_stop_ends_where_no_op_firings_would_leave_the_part():
    x_rest = _rest_after_throw()
    target = x_rest + 20e-6  # within the 50 um tolerance
    held, x_held, info_held = _episode(target, stop=False)
    stopped, x_stopped, info_stopped = _episode(target, stop=True)
    assert len(held) == 5 and len(stopped) == 1
    assert info_stopped["outcome"] == "rest" and info_stopped["is_success"]
    assert info_held["outcome"] == "rest" and info_held["is_success"]
    assert x_stopped == x_rest
    assert abs(x_held - x_stopped) < 1e-12
    # same potential and bonus; the held episode pays the time cost of its extra firings
    extra_time = info_held["sim_time_s"] - info_stopped["sim_time_s"]
    assert extra_time > 0.4
    assert sum(stopped) - sum(held) == pytest.approx(1.0 * extra_time, rel=1e-9)


def test_no_stop_outside_the_tolerance():
    x_rest = _rest_after_throw()
    rewards, _, info = _episode(x_rest + 60e-6, stop=True)  # beyond the 50 um tolerance
    assert len(rewards) == 5 and not info["is_success"]


def test_batched_env_stops_the_same_parts():
    x_rest = _rest_after_throw()
    targets = x_rest + np.array([20e-6, 60e-6, -45e-6, -55e-6])
    env = MicroConveyorVectorEnv(4, autoreset_mode="SameStep", num_threads=1)
    env.reset(seed=0, options={"target": targets})
    _, _, term, trunc, info = env.step(np.tile(THROW, (4, 1)))
    assert term.tolist() == [True, False, True, False] and not trunc.any()
    src = info["final_info"]
    assert src["is_success"][[0, 2]].all()
    assert np.allclose(src["position_error_m"][[0, 2]], x_rest - targets[[0, 2]], atol=1e-15)


@pytest.mark.parametrize("bad", [1, 0.0, "yes", None])
def test_stop_at_target_must_be_a_bool(bad):
    with pytest.raises(ParameterError, match="stop_at_target"):
        MicroConveyorEnv(stop_at_target=bad)


def _final(actions: np.ndarray, targets: np.ndarray, stop: bool) -> tuple[np.ndarray, np.ndarray]:
    """(success, final position [m]) of each schedule (n, 5, 3) run in the batched env."""
    n = len(actions)
    env = MicroConveyorVectorEnv(n, autoreset_mode="SameStep", num_threads=1, stop_at_target=stop)
    env.reset(seed=0, options={"target": targets})
    done, ok, x = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n)
    for k in range(actions.shape[1]):
        _, _, term, trunc, info = env.step(actions[:, k])
        src = info.get("final_info", info)
        new = (term | trunc) & ~done
        ok[new] = src["is_success"][new]
        x[new] = targets[new] + src["position_error_m"][new]
        done |= new
    assert done.all()
    return ok, x


def test_stopping_never_turns_a_success_into_a_failure():
    """Schedules with a late gentle trim: targets near where each ends (stop off). With the stop
    on, every success stays a success, and an episode that was never delivered early ends where
    it did."""
    rng = np.random.default_rng(7)
    n = 300
    acts = rng.uniform(-1, 1, (n, 5, 3))
    acts[:, :2, 0] = rng.uniform(-0.3, 0.0, (n, 2))   # ~0.8-1.4 kHz throws that rest downstream
    acts[:, 2:, :2] = rng.uniform(-1.0, -0.3, (n, 3, 2))  # then gentle firings
    _, x_full = _final(acts, np.full(n, 1e-3), stop=False)
    targets = x_full + rng.uniform(-100e-6, 100e-6, n)
    ok_full, x_full2 = _final(acts, targets, stop=False)
    ok_stop, x_stop = _final(acts, targets, stop=True)
    same = dict(rtol=0.0, atol=1e-15)  # x is rebuilt as target + error: rounding only
    assert np.allclose(x_full, x_full2, **same)  # the targets do not move the part
    assert ok_full.sum() > 50 and (ok_stop & ~ok_full).sum() > 0  # both cases occur
    assert not (ok_full & ~ok_stop).any()
    assert np.allclose(x_stop[~ok_stop], x_full[~ok_stop], **same)
