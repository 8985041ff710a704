"""MicroConveyor-v0: API conformance, determinism, batching, bad input, reward definition."""
import multiprocessing as mp
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env
from support.lockstep import assert_lockstep_with_sync
from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, MicroConveyorVectorEnv
from microconveyor_env.envs.core import actions
from microconveyor_env.envs.line import task

# Warnings the checkers may legitimately raise for this env (none are expected today).
WARNING_WHITELIST: tuple = ()


def _heuristic(env):
    """Hand-written policy: 180 um strokes, faster (700 Hz) while the target is far, gentler
    (400 Hz) within 2 mm; fire as soon as the previous stroke ends (no delay)."""
    cfg = env.unwrapped.config
    e = env.unwrapped
    gap = abs(e.target - e.x)
    f = 700.0 if gap > 2e-3 else 400.0
    return actions.encode_actions(f, 180e-6, 0.0, cfg)


def test_v0_is_flagged_out_of_date_by_gymnasium():
    with pytest.warns(DeprecationWarning, match="MicroConveyor-v0 is out of date.*v1"):
        gym.make("MicroConveyor-v0")


def test_registered_and_idempotent():
    assert microconveyor_env.ENV_ID in gym.registry
    microconveyor_env.env_ids.register_all()  # a second registration is a no-op
    spec = gym.spec("MicroConveyor-v0")
    assert spec.vector_entry_point.endswith("MicroConveyorVectorEnv")
    venv = gym.make_vec("MicroConveyor-v0", num_envs=3)
    assert isinstance(venv, MicroConveyorVectorEnv) and venv.num_envs == 3


@pytest.mark.parametrize("checker", ["gymnasium", "stable_baselines3"])
@pytest.mark.parametrize("env_id", [k for k in gym.registry if "MicroConveyor" in k])
def test_checkers_pass_without_warnings(env_id, checker, monkeypatch):
    if checker == "gymnasium":
        from support.checkers import gymnasium_check_env

        def run_check(env):
            gymnasium_check_env(env, monkeypatch)
    else:
        sb3 = pytest.importorskip("stable_baselines3.common.env_checker")

        def run_check(env):
            sb3.check_env(env, warn=True)

    with warnings.catch_warnings():
        # Gymnasium's own notice that v0 has a successor: expected, and only from gym.make
        warnings.filterwarnings("ignore", message=".*MicroConveyor-v0 is out of date.*v1",
                                category=DeprecationWarning)
        env = gym.make(env_id).unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run_check(env)
    unexpected = [w for w in caught if not any(s in str(w.message) for s in WARNING_WHITELIST)]
    assert not unexpected, [str(w.message) for w in unexpected]


def _rollout(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, te, tr, info = env.step(a)
        out.append((obs, r, te, tr, info["position_error_m"], info["outcome"]))
        if te or tr:
            obs, _ = env.reset()
            out.append(obs)
    return out


def _equal(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if isinstance(x, tuple):
            np.testing.assert_array_equal(x[0], y[0])
            assert x[1:] == y[1:]
        else:
            np.testing.assert_array_equal(x, y)


def test_same_seed_same_rollout():
    acts = np.random.default_rng(0).uniform(-1, 1, (17, 3)).astype(np.float32)
    _equal(_rollout(gym.make("MicroConveyor-v0"), 7, acts),
           _rollout(gym.make("MicroConveyor-v0"), 7, acts))
    other = _rollout(gym.make("MicroConveyor-v0"), 8, acts)
    assert not np.array_equal(other[0], _rollout(gym.make("MicroConveyor-v0"), 7, acts)[0])


def test_pickle_round_trip_mid_episode():
    env = MicroConveyorEnv(start_jitter=20e-6)
    env.reset(seed=3)
    env.step(np.array([0.1, 0.5, -0.9], np.float32))
    clone = pickle.loads(pickle.dumps(env))
    acts = np.random.default_rng(1).uniform(-1, 1, (9, 3)).astype(np.float32)
    for a in acts:
        s1, s2 = env.step(a), clone.step(a)
        np.testing.assert_array_equal(s1[0], s2[0])
        assert s1[1:4] == s2[1:4]
        if s1[2] or s1[3]:
            np.testing.assert_array_equal(env.reset()[0], clone.reset()[0])


def _make_in_subprocess(queue):
    import gymnasium as gym  # no import of microconveyor_env here

    env = gym.make("microconveyor_env:MicroConveyor-v0")
    obs, _ = env.reset(seed=0)
    queue.put(obs.tolist())


def test_module_prefixed_id_in_spawned_process():
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_make_in_subprocess, args=(q,))
    p.start()
    obs = q.get(timeout=240)
    p.join(60)
    assert p.exitcode == 0
    np.testing.assert_array_equal(np.array(obs, np.float32),
                                  gym.make("MicroConveyor-v0").reset(seed=0)[0])


@pytest.mark.parametrize("mode", [gym.vector.AutoresetMode.NEXT_STEP,
                                  gym.vector.AutoresetMode.SAME_STEP])
def test_batched_env_equals_sync_vector_env_step_for_step(mode):
    kw = {"start_jitter": 30e-6, "n_actuators": 3}
    batched = MicroConveyorVectorEnv(4, autoreset_mode=mode, **kw)
    # several episodes per sub-env, through autoresets
    assert assert_lockstep_with_sync(batched, kw, 11, 14, 5, 1.2, mode) >= 4


def test_bad_actions_and_clipping():
    env = MicroConveyorEnv()
    for bad in ([np.nan, 0, 0], [0, np.inf, 0], [0, 0, -np.inf]):
        env.reset(seed=0)
        with pytest.raises(ValueError, match="NaN or inf"):
            env.step(np.array(bad, np.float32))
    with pytest.raises(ValueError, match="3 components"):
        env.step(np.zeros(2, np.float32))
    env.reset(seed=0)
    big = env.step(np.array([5.0, -7.0, 3.0], np.float32))
    env.reset(seed=0)
    edge = env.step(np.array([1.0, -1.0, 1.0], np.float32))
    np.testing.assert_array_equal(big[0], edge[0])
    assert big[4]["frequency_hz"] == pytest.approx(10000.0)
    assert big[4]["stroke_m"] == pytest.approx(100e-6) and big[4]["delay_s"] == pytest.approx(0.1)
    v = MicroConveyorVectorEnv(2)
    v.reset(seed=np.int64(0))
    with pytest.raises(ValueError, match="NaN or inf"):
        v.step(np.array([[0, 0, 0], [np.nan, 0, 0]], np.float32))


@pytest.mark.parametrize("kw,field", [
    ({"tolerance": -1e-6}, "tolerance"), ({"n_actuators": 0}, "n_actuators"),
    ({"freq_range": [500.0, 100.0]}, "freq_range"), ({"spacing": float("nan")}, "spacing"),
    ({"shape": "square"}, "shape"), ({"mode": "euler"}, "mode"), ({"bogus": 1}, "unknown keys"),
    ({"target_range": [1e-3]}, "target_range"), ({"preset": "nope"}, "unknown preset"),
    ({"start_jitter": 1e-3}, "start_jitter"), ({"progress_scale": 0.0}, "progress_scale"),
    ({"freq_range": [200.0, 1e6], "stroke_range": [1e-4, 1e-2]}, "freq_range / stroke_range"),
])
def test_bad_config_values_give_the_configs_error(kw, field):
    with pytest.raises(ValueError, match=field):
        gym.make("MicroConveyor-v0", **kw)


def _episode(env, policy, seed, options=None):
    obs, info = env.reset(seed=seed, options=options)
    e = env.unwrapped
    x0, total = e.x, 0.0
    while True:
        obs, r, te, tr, info = env.step(policy(env))
        assert env.observation_space.contains(obs)
        assert isinstance(r, float) and isinstance(te, bool) and isinstance(tr, bool)
        total += r
        if te or tr:
            return x0, total, info, e


@pytest.mark.parametrize("policy", ["random", "heuristic"])
def test_episode_end_to_end_and_reward_sum_is_potential_based(policy):
    env = gym.make("MicroConveyor-v0")
    env.action_space.seed(0)
    pol = (lambda en: en.action_space.sample()) if policy == "random" else _heuristic
    for seed in range(3):
        x0, total, info, e = _episode(env, pol, seed, options={"target": 2e-3})
        cfg = e.config
        h = cfg.progress_horizon
        if info["outcome"] == "detached":  # forfeits all progress and pays time up to max_time
            expected = (-h + min(abs(x0 - e.target), h)) / cfg.progress_scale \
                - cfg.time_cost * max(cfg.max_time, e.t) - cfg.detach_penalty
        else:
            expected = (-min(abs(e.x - e.target), h) + min(abs(x0 - e.target), h)) \
                / cfg.progress_scale - cfg.time_cost * e.t \
                + cfg.success_bonus * info["is_success"]
        assert total == pytest.approx(expected, rel=1e-9, abs=1e-9)
        assert info["outcome"] in ("rest", "detached", "max_time")
        assert e.target == 2e-3 and info["sim_time_s"] == e.t


def test_terminal_observation_inside_bounds_on_detachment():
    env = MicroConveyorEnv(start_offset=0.05e-3)
    env.reset(seed=0)
    obs, r, te, tr, info = env.step(np.array([0.3, 1.0, -1.0], np.float32))  # ~1.6 kHz, 200 um
    assert info["outcome"] == "detached" and te and r < -5
    assert env.observation_space.contains(obs)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3, np.float32))


def test_render_rgb_array():
    env = gym.make("MicroConveyor-v0", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 5  # not blank


def test_sb3_adapter_semantics():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import VecEnv

    from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

    env = MicroConveyorSB3VecEnv(4, n_actuators=2)
    assert isinstance(env, VecEnv)
    env.seed(0)
    obs = env.reset()
    assert obs.shape == (4, task.OBS_DIM)
    for _ in range(2):
        obs, rew, dones, infos = env.step(np.zeros((4, 3), np.float32))
    assert dones.all()  # two actuators: every episode ends on its 2nd step
    for i in range(4):
        assert infos[i]["terminal_observation"].shape == (task.OBS_DIM,)
        assert infos[i]["terminal_observation"][4] == 1.0   # all fired in the final obs
        assert obs[i][4] == 0.0                              # the returned obs is the reset one
        assert infos[i]["TimeLimit.truncated"] is False


def test_config_defaults_from_yaml_match_dataclass():
    assert EnvConfig.from_yaml() == EnvConfig()


def test_reset_target_option_validated():
    env = MicroConveyorEnv()
    for bad in (float("nan"), 1.0, -0.5):
        with pytest.raises(ValueError, match="options\\['target'\\]"):
            env.reset(seed=0, options={"target": bad})
    obs, _ = env.reset(seed=0, options={"target": 0.05})
    assert env.observation_space.contains(obs) and env.target == 0.05


def test_sb3_adapter_truncation_seeding_and_reset_infos():
    pytest.importorskip("stable_baselines3")
    from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

    def first_obs(seed):
        env = MicroConveyorSB3VecEnv(3, start_jitter=40e-6)
        env.seed(seed)
        return env.reset()

    np.testing.assert_array_equal(first_obs(4), first_obs(4))
    assert not np.array_equal(first_obs(4), first_obs(5))
    env = MicroConveyorSB3VecEnv(2, max_time=0.05)
    env.set_options({"target": 3e-3})
    obs = env.reset()
    assert np.allclose(obs[:, 5], 3e-3 / task.LENGTH_SCALE)
    obs, rew, dones, infos = env.step(np.array([[0, 0, 1.0], [0, 0, 1.0]], np.float32))  # 0.1 s
    assert dones.all()
    for i in range(2):
        assert infos[i]["outcome"] == "max_time" and infos[i]["TimeLimit.truncated"] is True
        assert env.reset_infos[i]["outcome"] == "moving"
        # the reset info of an autoreset carries the reset keys only (the vector env's masks),
        # not the step-only keys with placeholder values
        assert set(env.reset_infos[i]) == {"is_success", "position_error_m", "outcome",
                                           "sim_time_s"}
        assert infos[i]["frequency_hz"] > 0 and "terminal_observation" in infos[i]


def test_success_is_decided_once_by_the_task():
    """The env's is_success is the compiled task's verdict: at rest within tolerance."""
    env = gym.make("MicroConveyor-v0", n_actuators=1).unwrapped
    a = actions.encode_actions(950.0, 200e-6, 0.0, env.config)
    env.reset(seed=0)
    _, _, term, _, info = env.step(a)
    x_end = env.x
    for target, expected in ((x_end, True), (x_end + 0.9 * env.config.tolerance, True),
                             (x_end + 1.1 * env.config.tolerance, False)):
        env.reset(seed=0, options={"target": target})
        _, _, term, _, info = env.step(a)
        assert term and info["outcome"] == "rest" and info["is_success"] is expected
        assert info["position_error_m"] == pytest.approx(x_end - target, abs=1e-15)
