"""SB3 trains on MicroConveyor2D-v0 end to end: a short PPO run (SB3's DummyVecEnv over
``gym.make``) and SAC's first updates on the single env (both accept its Box action space)."""
import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401

sb3 = pytest.importorskip("stable_baselines3")


def test_ppo_trains_a_few_thousand_steps_end_to_end():
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env("MicroConveyor2D-v0", n_envs=8, seed=0)
    model = sb3.PPO("MlpPolicy", venv, n_steps=128, batch_size=256, n_epochs=2, seed=0,
                    device="cpu")
    model.learn(total_timesteps=3072)
    assert model.num_timesteps == 3072
    env = gym.make("MicroConveyor2D-v0")
    obs, _ = env.reset(seed=0)
    done, steps = False, 0
    while not done:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, term, trunc, info = env.step(action)
        done, steps = term or trunc, steps + 1
    assert 1 <= steps <= env.unwrapped.config.max_firings
    assert info["outcome"] in ("rest", "detached", "max_time", "too_many_events")


def test_sac_accepts_the_action_space():
    env = gym.make("MicroConveyor2D-v0")
    model = sb3.SAC("MlpPolicy", env, learning_starts=40, batch_size=32, seed=0, device="cpu")
    model.learn(total_timesteps=80)
    action, _ = model.predict(np.zeros(10, np.float32), deterministic=True)
    assert action.shape == (5,)
