"""Saved part states: an episode started from the state after firing k continues exactly as the
uninterrupted episode (bit for bit on the same machine), in the single and the batched env, with
and without per-episode randomisation; bad states are refused with the field named."""
import json
import math

import gymnasium as gym
import numpy as np
import pytest

from microconveyor_env.envs import MicroConveyorEnv, MicroConveyorVectorEnv, PartState, env_config

RANDOMISED = dict(action_noise=3e-3, friction_factor_range=(0.95, 1.05),
                  mass_factor_range=(0.95, 1.05))


def _episode(env, actions, seed, target):
    """The uninterrupted episode: (state before each firing, step results)."""
    env.reset(seed=seed, options={"target": target})
    states, results = [], []
    for a in actions:
        states.append(env.get_state())
        obs, r, term, trunc, info = env.step(a)
        results.append((obs, r, term, trunc, info))
        if term or trunc:
            break
    return states, results


def _same(a, b):
    obs_a, r_a, term_a, trunc_a, info_a = a
    obs_b, r_b, term_b, trunc_b, info_b = b
    assert obs_a.tobytes() == obs_b.tobytes()
    assert r_a == r_b and term_a == term_b and trunc_a == trunc_b
    assert info_a == info_b


@pytest.mark.parametrize("kwargs", [{}, RANDOMISED], ids=["nominal", "randomised"])
def test_restart_from_any_state_continues_bit_for_bit(kwargs):
    cfg = env_config("MicroConveyor-v1", **kwargs)
    rng = np.random.default_rng(3)
    checked = 0
    for ep in range(6):
        # slow, short strokes keep the part moving so episodes use several firings
        actions = rng.uniform(-1, 1, (cfg.n_actuators, 3)).astype(np.float32)
        actions[:, 2] = -1.0  # no delay: the part often still slides when the next fires
        env = MicroConveyorEnv(config=cfg)
        states, results = _episode(env, actions, seed=ep, target=float(rng.uniform(0.5e-3, 9e-3)))
        for k, state in enumerate(states):
            # a fresh env, another seed: everything the rest depends on is in the state
            other = MicroConveyorEnv(config=cfg)
            obs, _ = other.reset(seed=1000 + ep, options={"state": state.to_dict()})
            if k > 0:
                assert obs.tobytes() == results[k - 1][0].tobytes()
            for j in range(k, len(results)):
                _same(other.step(actions[j]), results[j])
                checked += 1
    assert checked > 12


def test_batched_env_restarts_each_part_from_its_state():
    cfg = env_config("MicroConveyor-v1", **RANDOMISED)
    rng = np.random.default_rng(5)
    actions = rng.uniform(-1, 1, (4, cfg.n_actuators, 3)).astype(np.float32)
    singles = []
    while len(singles) < 4:  # parts still on their way after the first firing
        i = len(singles)
        env = MicroConveyorEnv(config=cfg)
        env.reset(seed=10 + i, options={"target": 9e-3})
        if not any(env.step(actions[i, 0])[2:4]):
            singles.append((env.get_state(), env))
        else:
            actions[i] = rng.uniform(-1, 1, (cfg.n_actuators, 3))
    vec = MicroConveyorVectorEnv(4, config=cfg)
    vec.reset(seed=99, options={"state": [s for s, _ in singles]})
    for i, (s, _) in enumerate(singles):
        assert vec.get_state(i) == s
    obs, rew, term, trunc, _ = vec.step(actions[:, 1])
    for i, (_, env) in enumerate(singles):
        o, r, te, tr, _ = env.step(actions[i, 1])
        assert o.tobytes() == obs[i].tobytes() and r == rew[i] and te == term[i]


def test_state_round_trips_through_json():
    cfg = env_config("MicroConveyor-v1", **RANDOMISED)
    env = MicroConveyorEnv(config=cfg)
    env.reset(seed=1)
    env.step(np.zeros(3, np.float32))
    s = env.get_state()
    assert s.noise is not None and s.friction_factor is not None
    back = PartState.from_dict(json.loads(json.dumps(s.to_dict())))
    assert back == s
    assert set(PartState(1e-3, 0.0, 0.0, 0, 2e-3).to_dict()) == {
        "position_m", "velocity_m_s", "time_s", "fired", "target_m"}


@pytest.mark.parametrize("change, match", [
    (dict(fired=5), "fired"), (dict(fired=-1), "fired"), (dict(fired=1.0), "fired"),
    (dict(position_m=float("nan")), "position_m"), (dict(velocity_m_s=float("inf")), "velocity"),
    (dict(time_s=-1e-3), "time_s"), (dict(time_s=1.0), "time_s"),
    (dict(target_m=1.0), "target"), (dict(friction_factor=1.2), "friction_factor"),
    (dict(noise=[[0.0] * 3] * 5), "noise"),
])
def test_bad_states_are_refused_naming_the_field(change, match):
    from microconveyor_env.envs.core.versions import scene_of

    cfg = env_config("MicroConveyor-v1")
    env = MicroConveyorEnv(config=cfg)
    saved = PartState(1e-3, 0.01, 1e-3, 1, 4e-3, env_id="MicroConveyor-v1", scene=scene_of(cfg))
    state = {**saved.to_dict(), **change}
    with pytest.raises(ValueError, match=match):
        env.reset(options={"state": state})


def test_state_and_target_together_are_refused():
    env = MicroConveyorEnv(config=env_config("MicroConveyor-v1"))
    with pytest.raises(ValueError, match="not both"):
        env.reset(options={"state": PartState(0.0, 0.0, 0.0, 0, 1e-3), "target": 1e-3})
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(options={"state": {"x": 0.0}})
    vec = MicroConveyorVectorEnv(2, config=env_config("MicroConveyor-v1"))
    with pytest.raises(ValueError, match="2 envs"):
        vec.reset(options={"state": [PartState(0.0, 0.0, 0.0, 0, 1e-3)] * 3})


GENTLE = np.array([-1.0, -1.0, -1.0], np.float32)


def _saved(env_id="MicroConveyor-v1", **kwargs):
    """A state after one gentle firing in ``gym.make(env_id, **kwargs)``."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=1, options={"target": 5e-3})
    env.step(GENTLE)
    return env.unwrapped.get_state()


@pytest.mark.parametrize("field, value, shown", [
    ("velocity_m_s", 1e300, r"velocity_m_s = 1e\+300 .*within ±15062.6 mm/s"),
    ("velocity_m_s", -16.0, r"velocity_m_s = -16.0 .*within ±15062.6 mm/s"),
    ("position_m", 20.0, r"position_m = 20.0 .*within \[-15062.8, 15062.5\] mm"),
    ("noise", 1e300, r"noise\[0\]\[0\] = 1e\+300 .*within ±13 "),
    ("noise", -14.0, r"noise\[0\]\[0\] = -14.0 .*within ±13 "),
])
def test_values_beyond_the_scene_are_refused_naming_field_value_and_range(field, value, shown):
    """Finite but impossible values: faster than the scene's fastest surface can move a part,
    farther than it can go in the episode's time, noise draws no standard normal gives."""
    state = _saved(**RANDOMISED)
    d = state.to_dict()
    if field == "noise":
        d["noise"][0][0] = value
    else:
        d[field] = value
    env = MicroConveyorEnv(config=env_config("MicroConveyor-v1", **RANDOMISED))
    with pytest.raises(ValueError, match=shown) as err:
        env.reset(options={"state": d})
    assert "\n" not in str(err.value)


def test_state_bounds_follow_the_scene():
    """The bounds (module docstring of part_state): twice the stroke's peak surface speed
    (15/4) h f plus a slide down the highest bump sqrt(2 g h); the distance at that speed for
    the whole episode from the start; standard normals within 13."""
    from microconveyor_env.envs.core.randomisation import NOISE_BOUND
    from microconveyor_env.envs.rail.part_state import state_bounds

    cfg = env_config("MicroConveyor-v1", stroke_range=(100e-6, 150e-6), freq_range=(200.0, 4e3))
    b = state_bounds(cfg)
    speed = 2 * 3.75 * 150e-6 * 4e3 + math.sqrt(2 * 9.81 * 150e-6)
    assert b.speed_m_s == pytest.approx(speed, rel=1e-12)
    assert b.position_m == pytest.approx((-cfg.start_offset - cfg.start_jitter - speed * cfg.max_time,
                                          -cfg.start_offset + cfg.start_jitter + speed * cfg.max_time))
    assert NOISE_BOUND == 13.0


def test_json_names_env_id_and_scene():
    from microconveyor_env.envs.core.versions import scene_of

    d = json.loads(json.dumps(_saved().to_dict()))
    assert d["env_id"] == "MicroConveyor-v1"
    assert d["scene"] == json.loads(json.dumps(scene_of(env_config("MicroConveyor-v1"))))
    assert d["scene"]["n_actuators"] == 5 and "action_noise" not in d["scene"]
    vec = gym.make_vec("MicroConveyor-v1", num_envs=2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    assert vec.unwrapped.get_state(1).to_dict()["env_id"] == "MicroConveyor-v1"
    assert PartState.from_dict(d) == _saved()  # and back, equal


def test_state_of_another_scene_is_refused_saying_what_differs():
    state = _saved()
    for env, differs in ((gym.make("MicroConveyor-v0"), r"preset: saved 'conveyor', here "
                                                         r"'feasibility'"),
                         (gym.make("MicroConveyor-v1", n_actuators=7),
                          r"n_actuators: saved 5, here 7"),
                         (MicroConveyorVectorEnv(2, config=env_config(
                             "MicroConveyor-v1", tolerance=20e-6)), "tolerance")):
        for given in (state, state.to_dict(), json.loads(json.dumps(state.to_dict()))):
            states = [given, given] if isinstance(env, MicroConveyorVectorEnv) else given
            with pytest.raises(ValueError, match="saved in MicroConveyor-v1.*" + differs) as e:
                env.reset(options={"state": states})
            assert "\n" not in str(e.value)
    # randomisation and runtime knobs are not the scene: the same scene takes the state
    for kwargs in ({"action_noise": 0.01}, {"max_steps": 10**6}):
        env = gym.make("MicroConveyor-v1", **kwargs)
        env.reset(options={"state": state.to_dict()})
        assert env.unwrapped.get_state().position_m == state.position_m


def test_json_without_env_id_and_scene_is_refused_state_built_in_code_is_taken():
    state = _saved()
    old = {k: v for k, v in state.to_dict().items() if k not in ("env_id", "scene")}
    env = gym.make("MicroConveyor-v1")
    with pytest.raises(ValueError, match=r"names no env id and scene .*PartState\(\*\*d\)"):
        env.reset(options={"state": old})
    with pytest.raises(ValueError, match="names no env id and scene"):
        PartState.from_dict(old)
    obs, _ = env.reset(options={"state": PartState(**old)})  # code vouches for its scene
    assert env.unwrapped.get_state().velocity_m_s == state.velocity_m_s


def test_state_of_another_env_id_of_the_same_scene_is_refused_naming_both():
    """The env id a state names must be the env's: a state of MicroConveyor-v1 is not taken by
    MicroConveyorGoal-v1 (its scene) nor by MicroConveyor-v0 made with v1's scene, and a dict
    whose env_id was edited is refused, in the single and the batched env."""
    from microconveyor_env.env_ids import overrides

    state = _saved()
    edited = {**state.to_dict(), "env_id": "MicroConveyor-v0"}
    cases = [(gym.make("MicroConveyorGoal-v1"), state, "MicroConveyor-v1", "MicroConveyorGoal-v1"),
             (gym.make("MicroConveyor-v0", **overrides("MicroConveyor-v1")), state,
              "MicroConveyor-v1", "MicroConveyor-v0"),
             (gym.make("MicroConveyor-v1"), edited, "MicroConveyor-v0", "MicroConveyor-v1")]
    vec = gym.make_vec("MicroConveyor-v1", num_envs=2, vectorization_mode="vector_entry_point")
    cases.append((vec, [state, edited], "MicroConveyor-v0", "MicroConveyor-v1"))
    for env, given, saved, here in cases:
        env.reset(seed=0)
        with pytest.raises(ValueError, match=f"saved in {saved} cannot start an episode in "
                                             f"{here}") as e:
            env.reset(options={"state": given})
        assert "\n" not in str(e.value)
    # its own id takes it; an env made without an id (and a state saved in one) checks the scene
    for env in (gym.make("MicroConveyor-v1"), MicroConveyorEnv(config=env_config())):
        env.reset(options={"state": state})
        assert env.unwrapped.get_state().position_m == state.position_m
    no_id = MicroConveyorEnv(config=env_config())
    no_id.reset(seed=1, options={"target": 5e-3})
    no_id.step(GENTLE)
    gym.make("MicroConveyor-v1").reset(options={"state": no_id.get_state().to_dict()})
