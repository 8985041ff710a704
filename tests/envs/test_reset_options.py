"""Reset options every env reads: ``"target"`` and ``"state"``. Any other key (a misspelled
``"targt"``) is refused in one line naming the known keys, in the single and the batched env of
every registered id, before anything changes; the episode is never drawn at random instead."""
import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401  (registers the ids)
from microconveyor_env.env_ids import ALL_ENV_IDS, REGISTRY

KNOWN = r"unknown keys \['targt'\] \(known keys: \['state', 'target'\]\)"
BATCHED_IDS = [i for i in ALL_ENV_IDS if REGISTRY[i].vector_entry_point is not None]


def _single(env_id):
    return gym.make(env_id).unwrapped


def _batched(env_id):
    return gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point").unwrapped


@pytest.mark.parametrize("env_id", ALL_ENV_IDS)
def test_single_env_refuses_an_unknown_option_and_keeps_its_episode(env_id):
    env = _single(env_id)
    env.reset(seed=3)
    before = env.get_state()
    with pytest.raises(ValueError, match=KNOWN) as err:
        env.reset(seed=4, options={"targt": 5e-3})
    assert "\n" not in str(err.value)
    assert env.get_state() == before
    with pytest.raises(ValueError, match=r"unknown keys \['seed'\]"):
        env.reset(options={"target": env.get_state().target_m, "seed": 1})
    with pytest.raises(ValueError, match="reset options must be a dict"):
        env.reset(options=[("target", 1e-3)])
    env.reset(seed=4, options={})  # empty options and None draw as before
    env.reset(seed=4, options=None)


@pytest.mark.parametrize("env_id", BATCHED_IDS)
def test_batched_env_refuses_an_unknown_option_and_keeps_every_sub_env(env_id):
    vec = _batched(env_id)
    vec.reset(seed=3)
    before = [vec.get_state(i) for i in range(2)]
    with pytest.raises(ValueError, match=KNOWN) as err:
        vec.reset(seed=4, options={"targt": [5e-3, 4e-3]})
    assert "\n" not in str(err.value)
    assert [vec.get_state(i) for i in range(2)] == before


def test_a_known_option_still_sets_the_target():
    env = _single("MicroConveyor-v1")
    env.reset(seed=0, options={"target": 5e-3})
    assert env.get_state().target_m == 5e-3
    vec = _batched("MicroConveyor-v1")
    vec.reset(seed=0, options={"target": np.array([4e-3, 5e-3])})
    assert [vec.get_state(i).target_m for i in range(2)] == [4e-3, 5e-3]
