"""MicroConveyor2D-v1: MicroConveyor2D-v0's scene under per-episode randomisation (execution
noise, friction and mass factors; :mod:`microconveyor_env.envs.core.randomisation`) with 12
firings: its registered defaults, the randomisation streams (off: v0 bit for bit; a seed gives
its factors; common random numbers across levels), single = batched with randomisation on, saved
states carrying the draws, both checkers, and the refusal of bad values."""
import json
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401  (registers the ids)
from microconveyor_env.env_ids import PLANE_ENV_IDS, REGISTRY
from microconveyor_env.envs.core import randomisation
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.plane.env import MicroConveyor2DEnv
from microconveyor_env.envs.plane.part_state import PlaneState
from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv
from microconveyor_env.envs.core.versions import nominal, scene_config, scene_differences
from microconveyor_env.physics.materials import ParameterError

ENV_ID = "MicroConveyor2D-v1"
V1_KWARGS = {"action_noise": 3e-3, "friction_factor_range": (0.95, 1.05),
             "mass_factor_range": (0.95, 1.05), "max_firings": 12, "max_time": 1.5}
OFF = {"action_noise": 0.0, "friction_factor_range": (1.0, 1.0), "mass_factor_range": (1.0, 1.0)}
AS_V0 = {**OFF, "max_firings": 8, "max_time": 1.0}   # v1's kwargs undone: v0's config


def _actions(seed, n, shape=(5,)):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1, 1, (n, *shape)).astype(np.float32)
    a[..., 2] = rng.uniform(-1, -0.2, a.shape[:-1])  # mostly below the detaching frequencies
    return a


def _play(env, seed, actions, **reset):
    """Observations, rewards, infos of one episode of ``actions`` (stops at its end)."""
    obs, info = env.reset(seed=seed, **reset)
    rows = [(obs, 0.0, info)]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        rows.append((obs, r, info))
        if term or trunc:
            break
    return rows


def _same(rows_a, rows_b, keys=("distance_m", "sim_time_s", "outcome", "frequency_hz",
                                "stroke_m", "delay_s", "actuator")):
    assert len(rows_a) == len(rows_b)
    for (oa, ra, ia), (ob, rb, ib) in zip(rows_a, rows_b, strict=True):
        np.testing.assert_array_equal(oa, ob)
        assert ra == rb
        for k in keys:
            assert ia.get(k) == ib.get(k), k


def test_v1_registered_defaults():
    assert ENV_ID in PLANE_ENV_IDS and REGISTRY[ENV_ID].base == ENV_ID
    spec = gym.spec(ENV_ID)
    assert spec.kwargs == V1_KWARGS
    assert spec.max_episode_steps >= 12
    env = gym.make(ENV_ID)
    cfg = env.unwrapped.config
    assert isinstance(cfg, PlaneEnvConfig) and cfg.randomised
    for k, v in V1_KWARGS.items():
        assert getattr(cfg, k) == v, k
    # the scene is v0's: randomisation, firings and time aside, every field as v0's
    v0 = scene_config("MicroConveyor2D-v0")
    assert not v0.randomised and gym.spec("MicroConveyor2D-v0").kwargs == {}
    assert scene_differences(v0, cfg) == {"max_firings": (8, 12), "max_time": (1.0, 1.5)}
    assert nominal(cfg) == scene_config(ENV_ID, **OFF)
    assert env.action_space.shape == (5,) and env.observation_space.shape == (10,)
    _, info = env.reset(seed=0)
    assert {"friction_factor", "mass_factor"} <= set(info)


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


def test_randomisation_off_is_v0_bit_for_bit():
    """v1 with its kwargs undone, and v0 itself (its randomisation fields at their off
    defaults), give v0's episodes exactly: nothing is drawn, no stream is touched."""
    v0 = gym.make("MicroConveyor2D-v0").unwrapped
    v1_off = gym.make(ENV_ID, **AS_V0).unwrapped
    assert v1_off.config == v0.config
    for seed in range(4):
        acts = _actions(seed, 8)
        a, b = _play(v0, seed, acts), _play(v1_off, seed, acts)
        _same(a, b)
        assert "friction_factor" not in a[-1][2] and "friction_factor" not in b[-1][2]
    assert v0.conveyor.consts.noise.size == 0 and not v0.conveyor.randomised


def test_randomisation_leaves_start_and_target_draws_alone_and_a_seed_gives_its_factors():
    on = gym.make(ENV_ID).unwrapped
    off = gym.make(ENV_ID, **OFF).unwrapped
    for seed in (0, 5):
        _, i_on = on.reset(seed=seed)
        _, i_off = off.reset(seed=seed)
        assert on.target == off.target and (on.x, on.y) == (off.x, off.y)
        again = gym.make(ENV_ID).unwrapped
        _, i_again = again.reset(seed=seed)
        assert (i_on["friction_factor"], i_on["mass_factor"]) == \
            (i_again["friction_factor"], i_again["mass_factor"])
        assert np.array_equal(on.conveyor.consts.noise, again.conveyor.consts.noise)
        assert 0.95 <= i_on["friction_factor"] <= 1.05 and 0.95 <= i_on["mass_factor"] <= 1.05
    # the streams are derived from the part's generator: episodes differ, seeds differ
    f = [on.reset(seed=s)[1]["friction_factor"] for s in range(20)]
    assert len(set(f)) == 20 and min(f) < 0.97 and max(f) > 1.03
    on.reset(seed=3)
    f1 = on.friction_factor
    on.reset()
    assert on.friction_factor != f1
    # the noise covers the episode's firings: (max_firings, 3) standard normals
    assert on.conveyor.consts.noise.shape == (1, 12, 3)


def test_common_random_numbers_across_levels():
    """Two levels with one seed use the same uniforms and normals, scaled."""
    lo = gym.make(ENV_ID, action_noise=1e-3, friction_factor_range=(0.99, 1.01),
                  mass_factor_range=(0.98, 1.02)).unwrapped
    hi = gym.make(ENV_ID, action_noise=4e-3, friction_factor_range=(0.9, 1.1),
                  mass_factor_range=(0.8, 1.2)).unwrapped
    for seed in range(3):
        lo.reset(seed=seed)
        hi.reset(seed=seed)
        assert (lo.friction_factor - 1.0) * 10 == pytest.approx(hi.friction_factor - 1.0, abs=1e-12)
        assert (lo.mass_factor - 1.0) * 10 == pytest.approx(hi.mass_factor - 1.0, abs=1e-12)
        np.testing.assert_array_equal(lo.conveyor.consts.noise, hi.conveyor.consts.noise)
    # the fired firing is the commanded one plus sigma z on frequency, stroke and delay only
    env = gym.make(ENV_ID, **{**OFF, "action_noise": 0.02}).unwrapped
    ref = gym.make(ENV_ID, **OFF).unwrapped
    a = np.array([0.3, -0.2, -0.5, 0.0, -0.6], np.float32)
    env.reset(seed=1)
    ref.reset(seed=1)
    z = env.conveyor.consts.noise[0, 0]
    info = env.step(a)[4]
    ri = ref.step(a)[4]
    assert info["actuator"] == ri["actuator"]
    span = np.log(2000.0 / 200.0)
    assert np.log(info["frequency_hz"] / ri["frequency_hz"]) == pytest.approx(
        0.5 * 0.02 * z[0] * span, rel=1e-9)
    assert info["stroke_m"] - ri["stroke_m"] == pytest.approx(0.5 * 0.02 * z[1] * 100e-6,
                                                              rel=1e-6)
    assert info["delay_s"] - ri["delay_s"] == pytest.approx(0.5 * 0.02 * z[2] * 0.1, rel=1e-6)


@pytest.mark.parametrize("num_threads", [1, 2])
def test_single_equals_batched_with_randomisation(num_threads):
    n = 3
    venv = MicroConveyor2DVectorEnv(n, config=scene_config(ENV_ID, num_threads=num_threads))
    singles = [gym.make(ENV_ID).unwrapped for _ in range(n)]
    obs, infos = venv.reset(seed=7)
    for i, s in enumerate(singles):
        o, info = s.reset(seed=7 + i)
        np.testing.assert_array_equal(obs[i], o)
        assert infos["friction_factor"][i] == info["friction_factor"]
        assert infos["mass_factor"][i] == info["mass_factor"]
        np.testing.assert_array_equal(venv.conveyor.consts.noise[i], s.conveyor.consts.noise[0])
    acts = _actions(11, 12, (n, 5))
    live = np.ones(n, bool)
    for a in acts:
        obs, rew, term, trunc, infos = venv.step(a)
        for i, s in enumerate(singles):
            if not live[i]:
                continue
            o, r, t, tr, info = s.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert rew[i] == r and term[i] == t and trunc[i] == tr
            assert infos["frequency_hz"][i] == info["frequency_hz"]
            live[i] = not (t or tr)
        if not live.any():
            break


@pytest.mark.parametrize("batched", [False, True])
def test_saved_state_continues_a_randomised_episode_bit_for_bit(batched):
    acts = _actions(4, 12)
    acts[:, 3] = -0.8    # low strokes: several firings before the episode ends
    if batched:
        env = MicroConveyor2DVectorEnv(2, config=scene_config(ENV_ID, num_threads=1))
        env.reset(seed=21)
        for a in acts[:2]:
            env.step(np.stack([a, a]))
        state = env.get_state(1)
        ref = [env.step(np.stack([a, a])) for a in acts[2:5]]
        other = MicroConveyor2DVectorEnv(2, config=scene_config(ENV_ID, num_threads=1))
        other.reset(seed=99, options={"state": [state.to_dict(), state]})
        for (o, r, *_), a in zip(ref, acts[2:5], strict=True):
            o2, r2, *_ = other.step(np.stack([a, a]))
            np.testing.assert_array_equal(o2[1], o[1])
            np.testing.assert_array_equal(o2[0], o[1])
            assert r2[0] == r2[1] == r[1]
        return
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=21)
    for a in acts[:2]:
        env.step(a)
    state = env.get_state()
    assert state.friction_factor == env.friction_factor and state.mass_factor == env.mass_factor
    assert np.shape(state.noise) == (12, 3) and state.env_id == ENV_ID
    saved = json.loads(json.dumps(state.to_dict()))      # JSON-safe, read back
    assert PlaneState.from_dict(saved) == state
    ref = [env.step(a) for a in acts[2:6]]
    other = gym.make(ENV_ID).unwrapped
    other.reset(seed=1234, options={"state": saved})       # other draws, replaced by the state's
    assert (other.friction_factor, other.mass_factor) == (state.friction_factor, state.mass_factor)
    for (o, r, t, tr, info), a in zip(ref, acts[2:6], strict=True):
        o2, r2, t2, tr2, info2 = other.step(a)
        np.testing.assert_array_equal(o2, o)
        assert (r2, t2, tr2, info2["frequency_hz"]) == (r, t, tr, info["frequency_hz"])
        if t or tr:
            break
    # a state without the draws keeps the env's own; pickling keeps the env's draws
    bare = PlaneState(state.position_m, state.velocity_m_s, state.time_s, state.fired,
                      state.target_m)
    other.reset(seed=5, options={"state": bare})
    assert other.friction_factor == gym.make(ENV_ID).unwrapped.reset(seed=5)[1]["friction_factor"]
    clone = pickle.loads(pickle.dumps(other))
    assert clone.friction_factor == other.friction_factor
    np.testing.assert_array_equal(clone.conveyor.consts.noise, other.conveyor.consts.noise)


@pytest.mark.parametrize("kw, field", [
    ({"action_noise": -1e-3}, "action_noise"), ({"action_noise": 2.0}, "action_noise"),
    ({"action_noise": float("nan")}, "action_noise"),
    ({"friction_factor_range": (1.1, 0.9)}, "friction_factor_range"),
    ({"friction_factor_range": (0.05, 1.0)}, "friction_factor_range"),
    ({"mass_factor_range": (1.0, 11.0)}, "mass_factor_range"),
    ({"mass_factor_range": "wide"}, "mass_factor_range"),
    # a part 9 times heavier, at strokes of 60 kHz, loads beyond the contact table
    ({"mass_factor_range": (1.0, 9.0), "freq_range": (200.0, 6e4)}, "mass_factor_range"),
])
def test_bad_randomisation_values_are_refused_naming_the_field(kw, field):
    with pytest.raises(ParameterError, match=field):
        gym.make(ENV_ID, **kw)
    if "freq_range" in kw:   # the same strokes with the part's own mass are accepted
        gym.make(ENV_ID, freq_range=kw["freq_range"])


def test_bad_randomisation_in_a_saved_state_is_refused_clearly():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=0)
    saved = env.get_state().to_dict()
    with pytest.raises(ValueError, match=r"friction_factor = 1\.2 is invalid.*\[0\.95, 1\.05\]"):
        env.reset(options={"state": {**saved, "friction_factor": 1.2}})
    with pytest.raises(ValueError, match=r"noise must be \(12, 3\) numbers"):
        env.reset(options={"state": {**saved, "noise": [[0.0] * 3] * 8}})
    with pytest.raises(ValueError, match=r"noise\[0\]\[1\] = nan is invalid"):
        env.reset(options={"state": {**saved, "noise": [[0.0, float("nan"), 0.0]] * 12}})
    off = gym.make(ENV_ID, **OFF).unwrapped     # no randomisation: draws are refused
    with pytest.raises(ValueError, match=r"friction_factor = 1\.0\d* is invalid.*\[1, 1\]"):
        off.reset(options={"state": saved})
    bare = {k: v for k, v in saved.items() if k not in ("friction_factor", "mass_factor", "noise")}
    with pytest.raises(ValueError, match=r"mass_factor = 1\.02 is invalid"):
        off.reset(options={"state": {**bare, "mass_factor": 1.02}})
    with pytest.raises(ValueError, match="noise is given but the env has no execution noise"):
        off.reset(options={"state": {**bare, "noise": saved["noise"]}})
    off.reset(options={"state": bare})   # the part, its time and target alone: accepted


def test_the_rails_and_the_plane_check_randomisation_with_the_core_bounds():
    """One place per concept: every scene's config checks the randomisation fields with the
    core's bounds."""
    from microconveyor_env.envs.rail import config as rail_config
    from microconveyor_env.envs.plane import config as plane_config

    for module in (rail_config, plane_config):
        assert {k: module._RANGES[k] for k in randomisation.NOISE_RANGE} == randomisation.NOISE_RANGE
        assert {k: module._PAIRS[k] for k in randomisation.FACTOR_PAIRS} == randomisation.FACTOR_PAIRS


def test_sb3_adapter_reports_the_factors():
    from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

    venv = MicroConveyorSB3VecEnv(2, env_id=ENV_ID, num_threads=1)
    venv.seed(3)
    venv.reset()
    _, _, _, infos = venv.step(_actions(0, 2))
    assert all(0.95 <= i["friction_factor"] <= 1.05 for i in infos)
    assert MicroConveyor2DEnv is type(gym.make(ENV_ID).unwrapped)
