"""MicroConveyor2D-v0 (issue 22 part 3): registration, spaces, the actuator pick, determinism,
single = batched bit for bit, both checkers, clear errors, rendering."""
import warnings

import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401  (registers the ids)
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.plane.env import MicroConveyor2DEnv
from microconveyor_env.envs.plane.task import constants, pick
from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv
from microconveyor_env.physics.materials import ParameterError

ENV_ID = "MicroConveyor2D-v0"


def _actions(seed, n, shape=(5,)):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1, 1, (n, *shape)).astype(np.float32)
    a[..., 2] = rng.uniform(-1, -0.2, a.shape[:-1])  # mostly below the detaching frequencies
    return a


def test_registered_make_and_make_vec():
    env = gym.make(ENV_ID)
    assert isinstance(env.unwrapped, MicroConveyor2DEnv)
    assert env.action_space == gym.spaces.Box(-1, 1, (5,), np.float32)
    assert env.observation_space.shape == (10,)
    assert env.spec.max_episode_steps >= env.unwrapped.config.max_firings
    venv = gym.make_vec(ENV_ID, 3, vectorization_mode="vector_entry_point")
    assert isinstance(venv, MicroConveyor2DVectorEnv) and venv.num_envs == 3
    cfg = env.unwrapped.config
    assert (cfg.nx, cfg.ny, cfg.spacing, cfg.preset) == (5, 5, 0.5e-3, "conveyor")


@pytest.mark.parametrize("checker", ["gymnasium", "stable_baselines3"])
def test_checkers_clean(checker):
    env = gym.make(ENV_ID).unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if checker == "gymnasium":
            from gymnasium.utils.env_checker import check_env

            check_env(env)
        else:
            from stable_baselines3.common.env_checker import check_env as sb3_check

            sb3_check(env, warn=True)
    assert not [str(w.message) for w in caught]


def test_pick_nearest_actuator_to_the_aim_point():
    cfg = PlaneEnvConfig.from_yaml()
    TC = constants(cfg)
    s = cfg.spacing
    assert pick(1.0e-3, 1.0e-3, 0.0, 0.0, TC) == 12          # under the part: the centre one
    assert pick(1.0e-3, 1.0e-3, 1.0, 0.0, TC) == 13          # one pitch to +x
    assert pick(1.0e-3, 1.0e-3, 0.0, -1.0, TC) == 7          # one pitch to -y
    assert pick(1.0e-3, 1.0e-3, 5.0, 5.0, TC) == 18          # clipped to the reach
    assert pick(0.1 * s, 0.1 * s, -1.0, -1.0, TC) == 0       # off the grid: the edge actuator
    assert pick(1.26e-3, 1.0e-3, 0.0, 0.0, TC) == 13         # nearest of two
    assert pick(2.0e-3, 2.0e-3, 1.0, 1.0, TC) == 24


def _rollout(env, seed, acts, render=False):
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    for a in acts:
        obs, r, term, trunc, info = env.step(a)
        rows.append(np.concatenate([obs, [r, term, trunc, info["actuator"]]]))
        if render:
            env.render()
        if term or trunc:
            break
    return np.concatenate(rows)


def test_deterministic_and_rendering_never_changes_a_step():
    acts = _actions(0, 8)
    a = _rollout(MicroConveyor2DEnv(), 7, acts)
    b = _rollout(MicroConveyor2DEnv(), 7, acts)
    c = _rollout(MicroConveyor2DEnv(render_mode="rgb_array"), 7, acts, render=True)
    assert np.array_equal(a, b) and np.array_equal(a, c)
    assert not np.array_equal(a, _rollout(MicroConveyor2DEnv(), 8, acts))


@pytest.mark.parametrize("num_threads", [1, 2])
@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_single_equals_batched_bit_for_bit(num_threads, mode):
    n, steps, seed = 5, 20, 3
    acts = _actions(1, steps, (n, 5))
    venv = MicroConveyor2DVectorEnv(n, num_threads=num_threads, autoreset_mode=mode)
    vobs, _ = venv.reset(seed=seed)
    singles = [MicroConveyor2DEnv() for _ in range(n)]
    sobs = np.stack([e.reset(seed=seed + i)[0] for i, e in enumerate(singles)])
    assert np.array_equal(vobs, sobs)
    done = np.zeros(n, bool)
    episodes = 0
    for k in range(steps):
        vobs, vr, vterm, vtrunc, vinfo = venv.step(acts[k])
        for i, e in enumerate(singles):
            if done[i] and mode == "NextStep":  # the batched env resets it on this step
                obs, _ = e.reset()
                assert np.array_equal(vobs[i], obs) and vr[i] == 0.0
                done[i] = False
                continue
            obs, r, term, trunc, info = e.step(acts[k, i])
            assert vr[i] == r and vterm[i] == term and vtrunc[i] == trunc
            vi = vinfo["final_info"] if (term or trunc) and mode == "SameStep" else vinfo
            assert vi["actuator"][i] == info["actuator"]
            assert vi["distance_m"][i] == info["distance_m"]
            if term or trunc:
                episodes += 1
                if mode == "SameStep":
                    assert np.array_equal(vinfo["final_obs"][i], obs)
                    obs, _ = e.reset()
                else:
                    done[i] = True
            assert np.array_equal(vobs[i], obs)
    assert episodes >= n  # the comparison went through autoresets


def test_episode_ends_after_max_firings_at_rest():
    env = MicroConveyor2DEnv(max_firings=3)
    env.reset(seed=0)
    a = np.array([0.0, 0.0, -1.0, -1.0, -1.0], np.float32)  # 200 Hz, 100 um under the part
    outs = [env.step(a)[2:4] for _ in range(3)]
    assert outs[-1] == (True, False) and env.fired == 3
    assert env.vx == env.vy == 0.0
    with pytest.raises(RuntimeError, match="reset"):
        env.step(a)


def test_stop_at_target_ends_the_episode_in_success():
    env = MicroConveyor2DEnv()
    env.reset(seed=0, options={"target": (1.0e-3, 1.0e-3)})  # the start: delivered at once
    _, r, term, _, info = env.step(np.array([0.0, 0.0, -1.0, -1.0, -1.0], np.float32))
    assert term and info["is_success"] and info["outcome"] == "rest"
    assert r > env.config.success_bonus - 1.0


def test_clear_errors():
    env = MicroConveyor2DEnv()
    env.reset(seed=0)
    for bad in (np.zeros(3), np.zeros((1, 5)), np.array([np.nan, 0, 0, 0, 0]),
                np.array(["a"] * 5)):
        with pytest.raises(ValueError):
            env.step(bad)
    for target in ((0.5, 0.0), (np.nan, 0.0), 1e-3, "ab"):
        with pytest.raises(ValueError, match="target"):
            env.reset(options={"target": target})
    for kw in ({"nx": 0}, {"start": (5e-3, 0.0)}, {"progress_horizon": 1e-4},
               {"freq_range": (2000.0, 200.0)}, {"tolerance": -1.0}, {"shape": "square"},
               {"max_firings": 1.5}, {"unknown_key": 1}, {"stop_at_target": "yes"}):
        with pytest.raises(ParameterError):
            PlaneEnvConfig.from_yaml(**kw)
    with pytest.raises(ParameterError, match="contact table"):
        MicroConveyor2DEnv(freq_range=(200.0, 2e5))
    with pytest.raises(ValueError, match="num_envs"):
        MicroConveyor2DVectorEnv(0)
    with pytest.raises(ValueError, match="render_mode"):
        MicroConveyor2DEnv(render_mode="human")


def test_render_frames_show_the_scene():
    env = MicroConveyor2DEnv(render_mode="rgb_array")
    env.reset(seed=1)
    first = env.render()
    env.step(np.array([0.6, 0.0, -0.5, 1.0, -1.0], np.float32))
    frame = env.render()
    for f in (first, frame):
        assert f.shape == (400, 480, 3) and f.dtype == np.uint8
        assert len(np.unique(f.reshape(-1, 3), axis=0)) > 50  # drawn, not blank
    assert not np.array_equal(first, frame)  # the bump's height map and the path appear
    venv = MicroConveyor2DVectorEnv(2, render_mode="rgb_array")
    venv.reset(seed=0)
    frames = venv.render()
    assert len(frames) == 2 and frames[0].shape == (400, 480, 3)
