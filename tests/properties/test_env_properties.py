"""Hostile configs and actions on the single and the batched env: either a clear ValueError at
the boundary, or finite observations inside the observation space, finite rewards and infos."""
import math
import re

import numpy as np
import pytest
from hypothesis import assume, event, example, given, strategies as st
from hypothesis.extra import numpy as hnp

from microconveyor_env.envs import MicroConveyorEnv, MicroConveyorVectorEnv

from .strategies import env_overrides

OUTCOMES = {"moving", "rest", "detached", "max_time", "too_many_events"}

# the strategy draws the deprecated kinematics alias 'seed' on purpose (a config that still says
# it must give a finite episode too); tests/physics/test_parameters.py checks its warning
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*kinematics 'seed' is now called 'reduced':DeprecationWarning")


def _make(cls, overrides, *args):
    """The env, or None after checking that the refusal is a ValueError naming a given field."""
    try:
        env = cls(*args, **overrides)
        event("config accepted")
        return env
    except ValueError as exc:
        event("config refused")
        msg = str(exc)
        assert any(k in msg for k in overrides) or "unknown preset" in msg, msg
        return None


def _check_info(info, n=None):
    for key in ("position_error_m", "sim_time_s"):
        assert np.all(np.isfinite(info[key])), (key, info[key])
    outcomes = [info["outcome"]] if n is None else list(info["outcome"])
    assert set(outcomes) <= OUTCOMES, outcomes


@given(overrides=env_overrides, seed=st.integers(0, 2 ** 16),
       actions=st.lists(st.tuples(*[st.floats(-2.0, 2.0)] * 3), min_size=8, max_size=8))
@example(overrides={"tolerance": 5e-324}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)  # NaN rewards
@example(overrides={"progress_scale": 1e-320}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)
@example(overrides={"dt": 1e-12}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)  # 1e10 steps: a hang
@example(overrides={"dt": 1e-300, "freq_range": (1e-300, 1.0)}, seed=0,
         actions=[(0.0, 0.0, 0.0)] * 8)  # overflowing step count
@example(overrides={"target_range": (0.5, 0.9)}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)
@example(overrides={"tolerance": "1e-3"}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)
@example(overrides={"time_cost": True}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)
@example(overrides={"n_actuators": float("nan")}, seed=0, actions=[(0.0, 0.0, 0.0)] * 8)
def test_single_env_configs_give_clear_errors_or_finite_episodes(overrides, seed, actions):
    env = _make(MicroConveyorEnv, overrides)
    if env is None:
        return
    obs, info = env.reset(seed=seed)
    assert env.observation_space.contains(obs)
    for a in actions:
        obs, r, term, trunc, info = env.step(np.array(a, np.float32))
        assert env.observation_space.contains(obs) and np.all(np.isfinite(obs)), obs
        assert isinstance(r, float) and math.isfinite(r), r
        _check_info(info)
        if term or trunc:
            break


_DTYPES = st.sampled_from([np.float32, np.float64, np.int64, np.int8, np.uint8, np.float16,
                           np.bool_, np.complex128, "U3", object])


@st.composite
def any_array(draw, n):
    """Arrays of any small shape (biased towards the right and nearly right ones) and dtype."""
    shape = draw(st.sampled_from([(n, 3), (3,), (3, n), (n * 3,), (n, 3, 1), (1, n, 3), (n, 2),
                                  (n + 1, 3), ()]) | hnp.array_shapes(min_dims=0, max_dims=3,
                                                                      max_side=5))
    dtype = draw(_DTYPES)
    if dtype in ("U3", object):
        return np.full(shape, "0.1" if dtype == "U3" else None, dtype=dtype)
    elements = None
    if np.dtype(dtype).kind == "f":
        elements = st.floats(allow_nan=True, allow_infinity=True,
                             width=np.dtype(dtype).itemsize * 8)
    return draw(hnp.arrays(dtype, shape, elements=elements))


@pytest.fixture(scope="module")
def envs():
    return MicroConveyorEnv(), {n: MicroConveyorVectorEnv(n) for n in (1, 2, 4)}


@given(data=st.data(), n=st.sampled_from([None, 1, 2, 4]))
def test_any_action_array_is_refused_clearly_or_stepped_finitely(envs, data, n):
    single, batched = envs
    env = single if n is None else batched[n]
    a = data.draw(any_array(1 if n is None else n))
    env.reset(seed=0)
    right_shape = a.shape == ((3,) if n is None else (n, 3))
    real = a.dtype.kind in "iuf"
    finite = real and bool(np.all(np.isfinite(a.astype(np.float64)))) if a.size else real
    try:
        obs, r, term, trunc, info = env.step(a)
    except ValueError as exc:
        assert not (right_shape and real and finite), exc
        msg = str(exc)
        assert ("shape" in msg and str(a.shape) in msg) or "dtype" in msg or "NaN or inf" in msg, msg
        return
    assert right_shape and real and finite
    space = env.observation_space
    assert space.contains(obs) and np.all(np.isfinite(obs))
    assert np.all(np.isfinite(r))
    _check_info(info, n)


@given(overrides=env_overrides, n=st.integers(1, 6), seed=st.integers(0, 2 ** 16),
       data=st.data())
def test_batched_env_configs_give_clear_errors_or_finite_steps(overrides, n, seed, data):
    assume("n_actuators" not in overrides or overrides["n_actuators"] in (1, 2, 3, 4, 5))
    env = _make(MicroConveyorVectorEnv, overrides, n)
    if env is None:
        return
    obs, _ = env.reset(seed=seed)
    for _ in range(env.config.n_actuators + 1):
        a = data.draw(hnp.arrays(np.float32, (n, 3), elements=st.floats(-1.5, 1.5, width=32)))
        obs, r, term, trunc, info = env.step(a)
        assert env.observation_space.contains(obs) and np.all(np.isfinite(obs))
        assert np.all(np.isfinite(r)) and r.dtype == np.float64
        _check_info(info, n)


@pytest.mark.parametrize("n,shape", [(4, (3, 4)), (4, (12,)), (4, (1, 4, 3)), (1, (3,)),
                                     (None, (1, 3)), (None, (3, 1))])
def test_same_size_wrong_shape_is_refused(envs, n, shape):
    """The issue's example: N = 4 and a (3, 4) array used to be reshaped and fired."""
    single, batched = envs
    env = single if n is None else batched[n]
    env.reset(seed=0)
    with pytest.raises(ValueError, match=rf"shape \({'3,' if n is None else f'{n}, 3'}\).*"
                                         rf"got shape {re.escape(str(shape))}"):
        env.step(np.zeros(shape, np.float32))
