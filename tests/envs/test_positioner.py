"""MicroPositioner-v0: registered defaults, the pick of the actuator, the physics' direction,
episode ends, single = batched, saved-state continuation, randomisation streams, refusals."""
from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401  (registers the ids)
from microconveyor_env.envs.line.config import EnvConfig
from microconveyor_env.envs.positioner import task
from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.physics.materials import ParameterError

ENV_ID = "MicroPositioner-v0"
PERTURBED = dict(action_noise=3e-3, friction_factor_range=(0.95, 1.05),
                 mass_factor_range=(0.95, 1.05))
GENTLE = np.array([0.4, -0.6, 0.0], np.float32)  # ahead of the part, ~400 Hz, 150 um


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random firings that rarely detach (frequencies in the lower half of the range)."""
    a = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    a[:, 1] = rng.uniform(-1.0, -0.2, n)
    return a


def test_registered_defaults() -> None:
    spec = gym.spec(ENV_ID)
    assert spec.max_episode_steps == 1000
    env = gym.make(ENV_ID)
    cfg = env.unwrapped.config
    assert isinstance(cfg, PositionerConfig)
    assert (cfg.n_actuators, cfg.spacing, cfg.pick_reach, cfg.max_firings) == (43, 0.25e-3,
                                                                                0.5e-3, 24)
    assert cfg.preset == "conveyor" and cfg.target_range == (0.5e-3, 10e-3)
    assert cfg.freq_range == (200.0, 2000.0) and cfg.delay_range == (0.0, 0.0)
    assert not cfg.randomised
    assert env.observation_space.shape == (task.OBS_DIM,)
    assert env.action_space.shape == (3,)
    # the array covers the whole target range, with an actuator beyond the farthest target
    assert cfg.actuator_positions[-1] >= cfg.target_range[1] + cfg.spacing


@pytest.mark.parametrize("bad, word", [
    ({"delay_range": (0.0, 0.1)}, "delay_range"), ({"stop_at_target": False}, "stop_at_target"),
    ({"observe_history": 2}, "observe_history"), ({"max_firings": 0}, "max_firings"),
    ({"pick_reach": -1e-3}, "pick_reach"), ({"max_firings": 2.5}, "max_firings")])
def test_config_refusals(bad: dict, word: str) -> None:
    with pytest.raises(ParameterError, match=word):
        PositionerConfig.from_yaml(None, **bad)


def test_checkers_clean() -> None:
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make(ENV_ID).unwrapped, skip_render_check=True)
    from stable_baselines3.common.env_checker import check_env as sb3_check

    sb3_check(MicroPositionerEnv(), warn=True)


def test_pick_nearest_actuator_to_the_aim() -> None:
    tc = task.constants(PositionerConfig.from_yaml(None))
    s = 0.25e-3
    assert task.pick(1.0e-3, 0.0, tc) == 4            # on actuator 4 itself
    assert task.pick(1.0e-3, 0.5, tc) == 5            # 0.25 mm ahead
    assert task.pick(1.0e-3, -1.0, tc) == 2           # 0.5 mm behind
    assert task.pick(1.0e-3, 7.0, tc) == 6            # clipped to +1: 0.5 mm ahead
    assert task.pick(-0.15e-3, -1.0, tc) == 0         # off the array: the end actuator
    assert task.pick(10.4e-3, 1.0, tc) == 42
    assert task.pick(0.5 * s, 0.0, tc) == 1           # halfway: the downstream one


@pytest.mark.parametrize("aim, direction", [(0.4, 1.0), (-0.2, -1.0)])
def test_part_moves_towards_and_past_the_fired_actuator(aim: float, direction: float) -> None:
    """A resting part between two actuators (5.0 and 5.25 mm) moves downstream when the one
    ahead fires and upstream when the one behind fires (physics.md §6)."""
    env = MicroPositionerEnv()
    start = PositionerState(position_m=5.1e-3, time_s=0.0, fired=0, target_m=9e-3)
    env.reset(seed=0, options={"state": start})
    _, _, _, _, info = env.step(np.array([aim, -0.5, 0.5], np.float32))
    moved = env.x - 5.1e-3
    assert info["outcome"] == "moving" and np.sign(moved) == direction and abs(moved) > 20e-6
    fired = info["actuator"] * 0.25e-3
    assert np.sign(fired - 5.1e-3) == direction
    assert np.sign(env.x - fired) == direction        # past the actuator


def test_episode_ends_at_success_with_bonus() -> None:
    env = MicroPositionerEnv()
    env.reset(seed=0, options={"target": 5.0e-3})
    start = PositionerState(position_m=5.0e-3 - 20e-6, time_s=0.0, fired=3, target_m=5.0e-3)
    env.reset(options={"state": start})
    # the weakest firing of the actuator farthest from the part leaves it where it is
    obs, r, term, trunc, info = env.step(np.array([1.0, -1.0, -1.0], np.float32))
    assert abs(info["position_error_m"]) <= 50e-6
    assert term and not trunc and info["is_success"] and info["outcome"] == "rest"
    assert r > 9.0
    with pytest.raises(RuntimeError):
        env.step(GENTLE)


def test_episode_ends_after_max_firings() -> None:
    env = MicroPositionerEnv(max_firings=2)
    env.reset(seed=0, options={"target": 9e-3})
    _, _, term, _, info = env.step(np.array([1.0, -1.0, -1.0], np.float32))
    assert not term and info["outcome"] == "moving"
    _, _, term, trunc, info = env.step(np.array([1.0, -1.0, -1.0], np.float32))
    assert term and not trunc and info["outcome"] == "rest" and not info["is_success"]


def test_observation_holds_the_last_firing() -> None:
    env = MicroPositionerEnv()
    obs0, _ = env.reset(seed=1, options={"target": 6e-3})
    assert np.all(obs0[3:8] == 0.0)
    x0 = env.x
    obs, *_ = env.step(GENTLE)
    st = env.get_state()
    assert obs[7] == 1.0
    assert obs[4] == pytest.approx(GENTLE[1]) and obs[5] == pytest.approx(GENTLE[2])
    assert obs[3] == pytest.approx((env.x - x0) / task.STEP_SCALE, rel=1e-5)
    assert st.last_step_m == pytest.approx(env.x - x0)
    err = env.x - 6e-3
    assert obs[0] == pytest.approx(err / task.COARSE_SCALE, rel=1e-5)
    assert obs[1] == pytest.approx(np.sign(err) * np.log1p(abs(err) / 10e-6), rel=1e-5)


@pytest.mark.parametrize("kw", [{}, PERTURBED])
def test_single_equals_batched(kw: dict) -> None:
    n = 5
    venv = MicroPositionerVectorEnv(n, num_threads=2, **kw)
    singles = [MicroPositionerEnv(**kw) for _ in range(n)]
    obs, _ = venv.reset(seed=10)
    assert np.array_equal(obs, np.stack([e.reset(seed=10 + i)[0] for i, e in enumerate(singles)]))
    rng = np.random.default_rng(0)
    done = np.zeros(n, bool)
    for _ in range(25):
        a = _actions(rng, n)
        obs, rew, term, trunc, _ = venv.step(a)
        for i, e in enumerate(singles):
            if done[i]:
                o, r, te, tr = e.reset()[0], 0.0, False, False
            else:
                o, r, te, tr, _ = e.step(a[i])
            assert np.array_equal(o, obs[i]) and r == rew[i] and (te, tr) == (term[i], trunc[i])
        done = term | trunc


@pytest.mark.parametrize("batched", [False, True])
def test_saved_state_continues_bit_for_bit(batched: bool) -> None:
    rng = np.random.default_rng(3)
    acts = _actions(rng, 6)
    acts[:, 2] = -0.8  # short strokes: the episode goes on
    make = (lambda: MicroPositionerVectorEnv(1, **PERTURBED)) if batched else \
        (lambda: gym.make(ENV_ID, **PERTURBED).unwrapped)
    env = make()
    env.reset(seed=4)
    env.step(acts[:1] if batched else acts[0])
    saved = env.get_state(0) if batched else env.get_state()
    first = [env.step(a[None] if batched else a) for a in acts[1:]]
    other = make()
    other.reset(seed=123, options={"state": saved.to_dict()})
    again = [other.step(a[None] if batched else a) for a in acts[1:]]
    for r1, r2 in zip(first, again, strict=True):
        assert np.array_equal(r1[0], r2[0]) and np.array_equal(r1[1], r2[1])
        assert np.array_equal(r1[2], r2[2]) and np.array_equal(r1[3], r2[3])


def test_states_of_other_scenes_and_bad_values_refused() -> None:
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=0)
    line = gym.make("MicroConveyor-v1").unwrapped
    line.reset(seed=0)
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(options={"state": line.get_state().to_dict()})
    good = env.get_state().to_dict()
    for key, value, word in [("position_m", 10.0, "position_m"), ("fired", 24, "fired"),
                             ("last_frequency", 1.5, "last_frequency"),
                             ("time_s", -1.0, "time_s"), ("target_m", float("nan"), "target_m")]:
        before = env.get_state()
        with pytest.raises(ValueError, match=word):
            env.reset(options={"state": {**good, key: value}})
        assert env.get_state() == before
    other = dict(good, scene={**good["scene"], "spacing": 0.5e-3})
    with pytest.raises(ValueError, match="another scene"):
        env.reset(options={"state": other})


def test_randomisation_streams() -> None:
    """Off: no factors drawn and the episodes are those of the scene; on: the starts and
    targets are the same, a seed draws the same factors in the single and the batched env, and
    two noise levels use the same standard normals (common random numbers)."""
    plain = MicroPositionerEnv()
    noisy = MicroPositionerEnv(**PERTURBED)
    louder = MicroPositionerEnv(**{**PERTURBED, "action_noise": 1e-2})
    _, i0 = plain.reset(seed=7)
    _, i1 = noisy.reset(seed=7)
    louder.reset(seed=7)
    assert "friction_factor" not in i0 and plain.target == noisy.target
    assert 0.95 <= i1["friction_factor"] <= 1.05 and 0.95 <= i1["mass_factor"] <= 1.05
    assert noisy.get_state().noise == louder.get_state().noise
    venv = MicroPositionerVectorEnv(3, **PERTURBED)
    venv.reset(seed=5)
    assert venv.friction_factor[2] == MicroPositionerEnv(**PERTURBED).reset(seed=7)[1][
        "friction_factor"]
    _, _, _, _, fired = noisy.step(GENTLE)
    _, _, _, _, commanded = plain.step(GENTLE)
    z = noisy.get_state().noise[0]
    assert fired["frequency_hz"] != commanded["frequency_hz"]   # the noise is applied
    ratio = np.log(fired["frequency_hz"] / commanded["frequency_hz"]) / np.log(10.0)
    assert ratio == pytest.approx(3e-3 * z[0] / 2)              # log-uniform over a decade
    assert fired["stroke_m"] - commanded["stroke_m"] == pytest.approx(3e-3 * z[1] * 50e-6)
    assert np.array(noisy.get_state().noise).shape == (24, 3)


def test_scene_is_not_the_line() -> None:
    """A PositionerConfig is a line config subclass but its own scene: the versions module
    tells them apart and policies of one are refused in the other."""
    from microconveyor_env.envs.core.versions import scene_differences, vector_class_of

    pos = PositionerConfig.from_yaml(None)
    line = dataclasses.replace(EnvConfig.from_yaml(None), preset="conveyor")
    assert vector_class_of(pos) is MicroPositionerVectorEnv
    assert "geometry" in scene_differences(pos, line)
