"""Observation history (EnvConfig.observe_history): shapes, what the history holds, single =
batched bit for bit, off = unchanged, restarts from a saved state, checkers (issue 21, item 2)."""
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

from support.lockstep import assert_lockstep_with_sync
from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, MicroConveyorVectorEnv
from microconveyor_env.envs.core import actions
from microconveyor_env.envs.line import task
from microconveyor_env.envs.line.state import HISTORY_ROW
from microconveyor_env.physics.materials import ParameterError

RAND = dict(action_noise=0.003, friction_factor_range=(0.95, 1.05),
            mass_factor_range=(0.95, 1.05))
# firings of 300-1000 Hz, 150-180 um, no delay: a v0 part rests only after the fifth
GENTLE = np.array([[-0.36, 0.6, -1.0], [-0.65, 0.6, -1.0], [-0.18, 0.0, -1.0], [-0.79, 0.0, -1.0],
                   [-0.36, 0.6, -1.0]], np.float32)


def _v0(**kw):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*MicroConveyor-v0 is out of date",
                                category=DeprecationWarning)
        return gym.make("MicroConveyor-v0", **kw)


def test_default_is_off_and_bad_values_are_refused():
    assert EnvConfig().observe_history == 0
    assert EnvConfig.from_yaml().observe_history == 0
    assert EnvConfig(observe_history=4.0).observe_history == 4
    for bad in (-1, 5, 1.5, True, "2", None, float("nan")):
        with pytest.raises(ParameterError, match="observe_history .* is invalid"):
            EnvConfig(observe_history=bad)
    with pytest.raises(ParameterError, match=r"n_actuators - 1 = 1\]"):
        EnvConfig(n_actuators=2, observe_history=2)


@pytest.mark.parametrize("k", [0, 1, 4])
def test_spaces_follow_the_option(k):
    dim = task.OBS_DIM + k * HISTORY_ROW
    env = MicroConveyorEnv(observe_history=k)
    venv = MicroConveyorVectorEnv(3, observe_history=k)
    assert env.observation_space.shape == (dim,)
    assert venv.single_observation_space.shape == (dim,)
    assert venv.observation_space.shape == (3, dim)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (dim,) and obs.dtype == np.float32 and env.observation_space.contains(obs)
    vobs, _ = venv.reset(seed=0)
    assert vobs.shape == (3, dim)
    np.testing.assert_array_equal(vobs[0], obs)


def test_off_is_unchanged_bit_for_bit():
    """observe_history = 0 returns the compiled step's own rows, as before the option."""
    a, b = MicroConveyorEnv(), MicroConveyorEnv(observe_history=0)
    assert b.conveyor.obs is b.conveyor.out.obs
    for env in (a, b):
        env.reset(seed=5)
    for act in GENTLE:
        ra, rb = a.step(act), b.step(act)
        assert ra[0].shape == (task.OBS_DIM,)
        for x, y in zip(ra[:4], rb[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        if ra[2] or ra[3]:
            break


@pytest.mark.parametrize("randomised", [False, True])
def test_history_holds_the_previous_rows_and_commanded_actions(randomised):
    k = 3
    kw = RAND if randomised else {}
    env = MicroConveyorEnv(observe_history=k, **kw)
    plain = MicroConveyorEnv(**kw)  # the same episode without history: the rows to expect
    obs, _ = env.reset(seed=11)
    ref, _ = plain.reset(seed=11)
    np.testing.assert_array_equal(obs[:task.OBS_DIM], ref)
    assert not obs[task.OBS_DIM:].any()  # a new episode remembers nothing
    rows, commanded = [ref], []
    big = GENTLE.copy()
    big[1, 2] = -3.0  # beyond the box: remembered as decoded, i.e. clipped to -1
    for act in big:
        obs, r, te, tr, _ = env.step(act)
        ref, r_ref, te_ref, tr_ref, _ = plain.step(act)
        assert (r, te, tr) == (r_ref, te_ref, tr_ref)
        np.testing.assert_array_equal(obs[:task.OBS_DIM], ref)
        commanded.append(np.clip(act, -1, 1))
        hist = obs[task.OBS_DIM:].reshape(k, HISTORY_ROW)
        for j in range(k):  # slot j: the (j+1)-th latest firing, or empty
            if j < len(commanded):
                np.testing.assert_array_equal(hist[j, :task.OBS_DIM], rows[-1 - j])
                np.testing.assert_array_equal(hist[j, task.OBS_DIM:-1], commanded[-1 - j])
                assert hist[j, -1] == 1.0
            else:
                assert not hist[j].any()
        rows.append(ref)
        if te or tr:
            break
    assert len(commanded) == 5, "the test needs a full episode"
    obs, _ = env.reset()
    assert not obs[task.OBS_DIM:].any()


def test_restart_from_a_state_starts_with_an_empty_history():
    env = MicroConveyorEnv(observe_history=4, **RAND)
    env.reset(seed=2)
    env.step(GENTLE[0])
    state = env.get_state()
    rest = [env.step(a) for a in GENTLE[1:3]]
    obs, _ = env.reset(options={"state": state})
    assert not obs[task.OBS_DIM:].any()
    for a, (o, r, te, tr, _) in zip(GENTLE[1:3], rest, strict=True):
        o2, r2, te2, tr2, _ = env.step(a)
        np.testing.assert_array_equal(o2[:task.OBS_DIM], o[:task.OBS_DIM])  # same rows
        assert (r2, te2, tr2) == (r, te, tr)
    # after one firing from the state, the history holds that firing only
    obs, _ = env.reset(options={"state": state})
    o, *_ = env.step(GENTLE[1])
    hist = o[task.OBS_DIM:].reshape(4, HISTORY_ROW)
    np.testing.assert_array_equal(hist[0, :task.OBS_DIM], obs[:task.OBS_DIM])
    assert hist[0, -1] == 1.0 and not hist[1:].any()


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("num_threads", [1, 2])
def test_single_and_batched_agree_bit_for_bit(mode, num_threads):
    kw = dict(observe_history=4, **RAND)
    venv = MicroConveyorVectorEnv(5, autoreset_mode=mode, num_threads=num_threads, **kw)
    ended = assert_lockstep_with_sync(venv, kw, seed=7, steps=30, action_seed=3, bound=0.6,
                                      mode=mode)
    assert ended > 0  # autoresets were exercised


def test_batched_reset_from_states_and_pickle():
    venv = MicroConveyorVectorEnv(2, observe_history=2)
    venv.reset(seed=1)
    venv.step(GENTLE[:2])
    states = [venv.get_state(i) for i in range(2)]
    obs, _ = venv.reset(options={"state": states})
    assert not obs[:, task.OBS_DIM:].any()
    o1, *_ = venv.step(GENTLE[2:4])
    assert (o1[:, task.OBS_DIM:].reshape(2, 2, HISTORY_ROW)[:, 0, -1] == 1.0).all()
    clone = pickle.loads(pickle.dumps(venv))
    for a in (GENTLE[1:3], GENTLE[3:5]):
        r1, r2 = venv.step(a), clone.step(a)
        for x, y in zip(r1[:4], r2[:4], strict=True):
            np.testing.assert_array_equal(x, y)


def test_goal_env_refuses_the_history():
    with pytest.raises(ValueError, match="observe_history"):
        gym.make("MicroConveyorGoal-v1", observe_history=2)


@pytest.mark.parametrize("checker", ["gymnasium", "stable_baselines3"])
def test_checkers_pass_with_history_on(checker, monkeypatch):
    env = _v0(observe_history=4, **RAND).unwrapped
    v1 = gym.make("MicroConveyor-v1", observe_history=4, **RAND).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if checker == "gymnasium":
            from support.checkers import gymnasium_check_env

            for e in (env, v1):
                gymnasium_check_env(e, monkeypatch)
        else:
            sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
            for e in (env, v1):
                sb3.check_env(e, warn=True)


def test_sb3_vec_env_with_history():
    pytest.importorskip("stable_baselines3")
    from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

    env = MicroConveyorSB3VecEnv(4, env_id="MicroConveyor-v1", observe_history=4, **RAND)
    dim = task.OBS_DIM + 4 * HISTORY_ROW
    assert env.observation_space.shape == (dim,)
    obs = env.reset()
    assert obs.shape == (4, dim)
    rng = np.random.default_rng(0)
    for _ in range(12):
        obs, _, dones, infos = env.step(rng.uniform(-1, 1, (4, actions.ACTION_DIM)))
        for i in np.flatnonzero(dones):
            assert infos[i]["terminal_observation"].shape == (dim,)
            assert not obs[i, task.OBS_DIM:].any()  # reset in the same step: empty history
