"""The SB3 adapter takes any registered scene: on MicroConveyor2D-v0 it has SB3's VecEnv
semantics (finished sub-envs reset in the same step, ``terminal_observation``,
``TimeLimit.truncated``) and gives the batched env's rollout."""
import numpy as np
import pytest

import microconveyor_env  # noqa: F401
from microconveyor_env.envs import MicroConveyor2DVectorEnv, MicroConveyorVectorEnv, PlaneEnvConfig
from microconveyor_env.envs.plane import task as plane_task

pytest.importorskip("stable_baselines3")
from stable_baselines3.common.vec_env import VecEnv  # noqa: E402

from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv  # noqa: E402


def test_the_adapter_builds_the_batched_env_of_the_id_or_config_it_is_given():
    assert type(MicroConveyorSB3VecEnv(2).venv) is MicroConveyorVectorEnv
    assert type(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1").venv) is \
        MicroConveyorVectorEnv
    plane = MicroConveyorSB3VecEnv(2, env_id="MicroConveyor2D-v0", nx=4)
    assert type(plane.venv) is MicroConveyor2DVectorEnv and plane.venv.config.nx == 4
    cfg = PlaneEnvConfig.from_yaml(max_firings=3)
    assert type(MicroConveyorSB3VecEnv(2, config=cfg).venv) is MicroConveyor2DVectorEnv
    with pytest.raises(ValueError, match="either env_id"):
        MicroConveyorSB3VecEnv(2, env_id="MicroConveyor2D-v0", config=cfg)
    with pytest.raises(ValueError, match="unknown keys"):
        MicroConveyorSB3VecEnv(2, env_id="MicroConveyor2D-v0", n_actuators=3)
    assert plane.action_space.shape == (5,)
    assert plane.observation_space.shape == (plane_task.OBS_DIM,)


def test_plane_vec_env_semantics_match_the_batched_env():
    n = 4
    env = MicroConveyorSB3VecEnv(n, env_id="MicroConveyor2D-v0", max_firings=2)
    assert isinstance(env, VecEnv)
    ref = MicroConveyor2DVectorEnv(n, autoreset_mode="SameStep",
                                   config=PlaneEnvConfig.from_yaml(max_firings=2))
    env.seed(3)
    obs = env.reset()
    ref_obs, _ = ref.reset(seed=3)
    np.testing.assert_array_equal(obs, ref_obs)
    assert set(env.reset_infos[0]) == {"is_success", "position_error_m", "distance_m",
                                       "outcome", "sim_time_s"}
    rng = np.random.default_rng(0)
    finished = 0
    for _ in range(4):
        a = (rng.uniform(-1, 1, (n, 5)) * 0.4).astype(np.float32)
        obs, rew, dones, infos = env.step(a)
        r_obs, r_rew, r_te, r_tr, r_info = ref.step(a)
        np.testing.assert_array_equal(obs, r_obs)
        np.testing.assert_array_equal(rew, r_rew.astype(np.float32))
        np.testing.assert_array_equal(dones, r_te | r_tr)
        assert rew.dtype == np.float32 and dones.dtype == bool
        for i in range(n):
            assert isinstance(infos[i]["actuator"], int) and len(infos[i]["position_error_m"]) == 2
            if dones[i]:
                finished += 1
                final = r_info["final_info"]
                np.testing.assert_array_equal(infos[i]["terminal_observation"],
                                              r_info["final_obs"][i])
                assert infos[i]["terminal_observation"][7] > 0.0   # a firing was used
                assert obs[i][7] == 0.0                             # the reset observation
                assert infos[i]["TimeLimit.truncated"] is bool(r_tr[i] and not r_te[i])
                assert infos[i]["outcome"] == final["outcome"][i]
                assert env.reset_infos[i]["outcome"] == "moving"
            else:
                assert "terminal_observation" not in infos[i]
                assert infos[i]["outcome"] == r_info["outcome"][i] == "moving"
    assert finished >= n   # every episode of two firings ended at least once


def test_plane_targets_as_reset_options_and_the_line_only_set_targets():
    env = MicroConveyorSB3VecEnv(2, env_id="MicroConveyor2D-v0")
    env.set_options({"target": (0.5e-3, 1.5e-3)})
    env.reset()
    assert env.venv.target.tolist() == [[0.5e-3, 1.5e-3]] * 2
    with pytest.raises(AttributeError, match="no set_targets"):
        env.set_targets([0], [(0.0, 0.0)])
    assert env.get_attr("config")[0].nx == 5
    assert env.env_is_wrapped(object) == [False, False]


def test_plane_truncation_is_flagged():
    env = MicroConveyorSB3VecEnv(2, env_id="MicroConveyor2D-v0", max_time=0.05,
                                 stop_at_target=False)
    env.seed(0)
    env.reset()
    # the longest delay (0.1 s) at the lowest stroke: the time limit ends the episode
    a = np.array([[0.0, 0.0, -1.0, -1.0, 1.0]] * 2, np.float32)
    _, _, dones, infos = env.step(a)
    assert dones.all()
    for i in range(2):
        assert infos[i]["outcome"] == "max_time" and infos[i]["TimeLimit.truncated"] is True
