"""The registered env versions: v1's defaults as registered, v0 as it was, scene comparison."""
import dataclasses

import gymnasium as gym
import pytest
import yaml

import microconveyor_env
from microconveyor_env.envs import ENV_IDS, EnvConfig, MicroConveyorVectorEnv, env_config, \
    scene_differences
from microconveyor_env.env_ids import MAX_ACTUATORS
from microconveyor_env.envs.core.versions import registered_kwargs
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.presets import load_preset


def test_both_versions_are_registered_with_their_yaml_defaults():
    assert ENV_IDS == ("MicroConveyor-v0", "MicroConveyor-v1")
    assert microconveyor_env.LATEST_ENV_ID == "MicroConveyor-v1"
    v0, v1 = gym.spec("MicroConveyor-v0"), gym.spec("MicroConveyor-v1")
    assert v0.kwargs == {} and v0.max_episode_steps is None      # v0 registered as it always was
    with open("configs/envs/MicroConveyor-v1.yaml") as fh:
        raw = yaml.safe_load(fh)
    assert v1.kwargs == {k: tuple(v) if isinstance(v, list) else v for k, v in raw.items()}
    assert v1.kwargs["preset"] == "conveyor"
    # the TimeLimit gym.make adds never cuts an episode short, whatever n_actuators is
    assert v1.max_episode_steps == MAX_ACTUATORS
    assert v1.vector_entry_point == v0.vector_entry_point


def test_v1_single_vector_and_env_config_agree():
    single = gym.make("MicroConveyor-v1").unwrapped.config
    vec = gym.make_vec("MicroConveyor-v1", 3)
    assert isinstance(vec, MicroConveyorVectorEnv)
    assert single == vec.config == env_config("MicroConveyor-v1")
    assert single.preset == "conveyor"
    assert env_config("MicroConveyor-v0") == EnvConfig.from_yaml()
    # user kwargs override the registered ones, as gym.make does
    assert env_config("MicroConveyor-v1", n_actuators=3).n_actuators == 3
    assert gym.make("MicroConveyor-v1", n_actuators=3).unwrapped.config.n_actuators == 3


def test_v0_is_chapter_3_and_v1_chapter_4():
    v0, v1 = env_config("MicroConveyor-v0"), env_config("MicroConveyor-v1")
    assert load_preset(v0.preset).contact.surface.dgamma == 1.0
    assert load_preset(v1.preset).contact.surface.dgamma == 0.5
    assert v0.preset == "feasibility" and v0.target_range == (0.5e-3, 3e-3)
    assert v0.n_actuators == 5 and v0.spacing == 0.5e-3


def test_unknown_versions_and_short_time_limits_are_refused():
    with pytest.raises(ParameterError, match="registered: MicroConveyor-v0, MicroConveyor-v1"):
        env_config("MicroConveyor-v9")
    with pytest.raises(ParameterError, match="registered"):
        registered_kwargs("CartPole-v1")
    with pytest.raises(ValueError, match="max_episode_steps=2 is below"):
        gym.make_vec("MicroConveyor-v1", 2, max_episode_steps=2)


def test_scene_differences_ignore_runtime_and_randomisation():
    a = env_config("MicroConveyor-v1")
    same = dataclasses.replace(a, num_threads=1, max_steps=10 ** 6, action_noise=0.01,
                               friction_factor_range=(0.9, 1.1), mass_factor_range=(0.9, 1.1))
    assert scene_differences(a, same) == {}
    other = dataclasses.replace(a, n_actuators=7, tolerance=1e-4)
    assert scene_differences(a, other) == {"n_actuators": (a.n_actuators, 7),
                                           "tolerance": (a.tolerance, 1e-4)}
    assert "preset" in scene_differences(a, env_config("MicroConveyor-v0"))


def test_registering_stays_light():
    """``import microconveyor_env`` registers every id from the light env_ids module: no env,
    numba kernel or contact table is imported until an env is made."""
    import subprocess
    import sys

    code = ("import sys, microconveyor_env, gymnasium as gym; "
            "print(sorted(k for k in gym.registry if 'MicroConveyor' in k)); "
            "print(any(m.startswith(('microconveyor_env.envs', 'microconveyor_env.physics', "
            "'numba')) for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout.splitlines()
    assert out == ["['MicroConveyor-v0', 'MicroConveyor-v1', 'MicroConveyor2D-v0', "
                   "'MicroConveyor2D-v1', 'MicroConveyorGoal-v1']", "False"]
    assert registered_kwargs("MicroConveyorGoal-v1") == registered_kwargs("MicroConveyor-v1")
    # the subpackages are still one attribute away (the README's help(...) line)
    code = ("import microconveyor_env; "
            "print(microconveyor_env.envs.MicroConveyorEnv.__name__, "
            "microconveyor_env.presets.load_preset.__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert out == ["MicroConveyorEnv", "load_preset"]


def test_every_registered_id_builds_through_the_one_registry():
    """Each id of the registry is registered with Gymnasium as the registry says, its config
    comes from scene_config, and its single and batched envs build with that config."""
    import gymnasium as gym

    from microconveyor_env.env_ids import DEFAULT_ENV_ID, REGISTRY
    from microconveyor_env.envs.core.versions import config_class, registered_kwargs, scene_config

    assert DEFAULT_ENV_ID == "MicroConveyor-v1" and DEFAULT_ENV_ID in REGISTRY
    for env_id, reg in REGISTRY.items():
        spec = gym.spec(env_id)
        assert (spec.entry_point, spec.vector_entry_point, spec.max_episode_steps) == \
            (reg.entry_point, reg.vector_entry_point, reg.max_episode_steps), env_id
        assert spec.kwargs == registered_kwargs(env_id)
        cfg = scene_config(env_id)
        assert isinstance(cfg, config_class(env_id))
        env = gym.make(env_id)
        assert env.unwrapped.config == cfg, env_id
        env.close()
        if reg.vector_entry_point is not None:
            venv = gym.make_vec(env_id, num_envs=2)
            assert venv.unwrapped.config == cfg, env_id
            venv.close()
