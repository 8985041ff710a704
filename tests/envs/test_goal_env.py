"""MicroConveyorGoal-v1: the Dict interface is the same env, its reward is compute_reward's, and
SB3's HER trains on it. (Both env checkers run on it in test_env.py, over every registered id.)"""
import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401
from microconveyor_env.envs import MicroConveyorEnv, env_config
from microconveyor_env.envs.line.goal import MicroConveyorGoalEnv
from microconveyor_env.envs.rail.step import LENGTH_SCALE


def _pair():
    cfg = env_config("MicroConveyor-v1")
    return MicroConveyorGoalEnv(config=cfg), MicroConveyorEnv(config=cfg)


def test_registered_with_v1s_scene():
    spec = gym.spec("MicroConveyorGoal-v1")
    assert spec.kwargs == gym.spec("MicroConveyor-v1").kwargs
    env = gym.make("MicroConveyorGoal-v1").unwrapped
    assert isinstance(env, MicroConveyorGoalEnv) and env.config == env_config("MicroConveyor-v1")
    assert set(env.observation_space.spaces) == {"observation", "achieved_goal", "desired_goal"}


def test_same_episodes_as_v1_and_reward_is_compute_reward():
    goal, base = _pair()
    rng = np.random.default_rng(0)
    worst, steps = 0.0, 0
    for ep in range(60):
        og, _ = goal.reset(seed=ep)
        base.reset(seed=ep)
        assert og["desired_goal"][0] == np.float32(base.target / LENGTH_SCALE)
        while True:
            a = rng.uniform(-1, 1, 3).astype(np.float32)
            o, r, te, tr, info = goal.step(a)
            _, rb, teb, trb, infob = base.step(a)
            steps += 1
            assert (te, tr, info["outcome"], info["is_success"]) == \
                (teb, trb, infob["outcome"], infob["is_success"])
            assert goal.x == base.x and goal.t == base.t              # same physics, bit for bit
            assert o["achieved_goal"][0] == np.float32(base.x / LENGTH_SCALE)
            # the step's reward is compute_reward's, exactly, single and batched
            assert r == goal.compute_reward(o["achieved_goal"], o["desired_goal"], info)
            batch = goal.compute_reward(np.stack([o["achieved_goal"]] * 2),
                                        np.stack([o["desired_goal"]] * 2), [info, info])
            assert batch.shape == (2,) and batch[0] == r
            worst = max(worst, abs(r - rb))
            if te or tr:
                break
    assert steps > 60
    assert worst < 1e-4   # float32 rounding of the observed positions only (module docstring)


def test_relabelled_goal_where_the_part_rested_pays_the_success_bonus():
    goal, _ = _pair()
    goal.reset(seed=3)
    while True:
        o, r, te, tr, info = goal.step(np.array([-0.2, 0.8, -1.0], np.float32))
        if te or tr:
            break
    assert info["outcome"] == "rest"
    here = goal.compute_reward(o["achieved_goal"], o["achieved_goal"], info)
    # a goal 0.5 mm further on: the same progress was made towards it, but no bonus
    far = goal.compute_reward(o["achieved_goal"], o["achieved_goal"] + np.float32(0.05), info)
    assert here - far == pytest.approx(goal.config.success_bonus, rel=1e-9)
    with pytest.raises(ValueError, match="copy_info_dict=True"):
        goal.compute_reward(o["achieved_goal"], o["desired_goal"], {})


def test_her_trains_a_few_hundred_steps(tmp_path):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make("MicroConveyorGoal-v1", n_actuators=3)
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future",
                                      "copy_info_dict": True},
                learning_starts=64, batch_size=32, policy_kwargs={"net_arch": [16]}, seed=0,
                device="cpu")
    model.learn(300)
    model.save(tmp_path / "her")
    assert model.replay_buffer.size() > 0 and model.num_timesteps == 300
