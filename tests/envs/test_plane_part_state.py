"""The plane's saved part state (MicroConveyor2D-v0): ``get_state()`` then
``reset(options={"state": s})`` continues an episode bit for bit, single and batched; a state of
another scene or id, a dict naming none and out-of-bounds values are refused before anything
changes."""
import json

import gymnasium as gym
import numpy as np
import pytest

import microconveyor_env  # noqa: F401
from microconveyor_env.envs import MicroConveyor2DEnv, MicroConveyor2DVectorEnv, PartState
from microconveyor_env.envs.plane.part_state import PlaneState

# seed 7 plays the longest episode (about 16 s): with the slow tier; 0 and 3 check the same
SEEDS = (0, 3, pytest.param(7, marks=pytest.mark.slow))


def _actions(seed, n=8, shape=(5,)):
    """Random actions with frequencies in the lowest quarter of the range (no detachment: the
    episodes run all their firings) and aims within 0.6 of the reach."""
    a = np.random.default_rng(seed).uniform(-1, 1, (n, *shape))
    a[..., 2] = -1.0 + 0.25 * (a[..., 2] + 1.0)
    a[..., :2] *= 0.6
    return a.astype(np.float32)


def _episode(env, acts, start=0):
    """The steps of ``acts[start:]`` until the episode ends."""
    out = []
    for a in acts[start:]:
        obs, rew, term, trunc, info = env.step(a)
        out.append((obs, rew, term, trunc, info))
        if term or trunc:
            break
    return out


def _same(a, b):
    assert len(a) == len(b)
    for (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) in zip(a, b, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert (r1, te1, tr1) == (r2, te2, tr2)
        assert i1 == i2


@pytest.mark.parametrize("seed", SEEDS)
def test_a_saved_state_continues_the_single_episode_bit_for_bit(seed):
    acts = _actions(seed)
    env = gym.make("MicroConveyor2D-v0").unwrapped
    env.reset(seed=seed)
    full = _episode(env, acts)
    assert len(full) >= 3, "the episode must have a middle to restart from"
    for k in range(1, len(full)):
        env.reset(seed=seed)
        _episode(env, acts[:k])
        saved = env.get_state()
        assert saved.fired == k and saved.env_id == "MicroConveyor2D-v0"
        # through JSON, into a fresh env seeded otherwise: the state alone decides the rest
        d = json.loads(json.dumps(saved.to_dict()))
        other = gym.make("MicroConveyor2D-v0").unwrapped
        obs, info = other.reset(seed=seed + 100, options={"state": d})
        np.testing.assert_array_equal(obs, full[k - 1][0])
        assert other.get_state() == saved and PlaneState.from_dict(d) == saved
        _same(_episode(other, acts, k), full[k:])


def test_saved_states_continue_every_sub_env_of_the_batch_bit_for_bit():
    n, k = 4, 2
    acts = _actions(11, shape=(n, 5))
    venv = MicroConveyor2DVectorEnv(n)
    venv.reset(seed=5)
    steps = [venv.step(acts[j]) for j in range(k)]
    assert not any(s[2].any() or s[3].any() for s in steps[:-1])
    alive = ~(steps[-1][2] | steps[-1][3])
    assert alive.any()
    states = [venv.get_state(i) for i in range(n)]
    rest = [venv.step(acts[k])]
    other = MicroConveyor2DVectorEnv(n)
    obs, _ = other.reset(seed=99, options={"state": [s.to_dict() for s in states]})
    np.testing.assert_array_equal(obs, steps[-1][0])
    obs2, rew2, te2, tr2, info2 = other.step(acts[k])
    obs1, rew1, te1, tr1, info1 = rest[0]
    # the sub-envs still in their episode fire the same firing; those that had finished were
    # autoreset by the first batch (NEXT_STEP) and started from the state by the second
    for i in np.flatnonzero(alive):
        np.testing.assert_array_equal(obs2[i], obs1[i])
        assert (rew2[i], te2[i], tr2[i]) == (rew1[i], te1[i], tr1[i])
        for key in ("actuator", "frequency_hz", "distance_m", "sim_time_s", "outcome"):
            assert info2[key][i] == info1[key][i]
    # one state for every sub-env
    one = MicroConveyor2DVectorEnv(n)
    one.reset(options={"state": states[0]})
    assert all(one.get_state(i) == states[0] for i in range(n))


def test_the_single_and_the_batched_env_save_the_same_state():
    acts = _actions(2)
    env = MicroConveyor2DEnv()
    venv = MicroConveyor2DVectorEnv(1)
    env.reset(seed=2)
    venv.reset(seed=2)
    env.step(acts[0])
    venv.step(acts[0][None])
    assert env.get_state() == venv.get_state(0)


def _mid_episode():
    env = gym.make("MicroConveyor2D-v0").unwrapped
    env.reset(seed=3)
    env.step(_actions(3)[0])
    return env


def test_a_state_of_another_scene_or_id_is_refused_with_a_clear_error():
    saved = _mid_episode().get_state().to_dict()
    wider = gym.make("MicroConveyor2D-v0", nx=6).unwrapped
    with pytest.raises(ValueError, match=r"another scene.*nx: saved 5, here 6"):
        wider.reset(options={"state": saved})
    # the line's state in the plane, the plane's in the line: another scene (and geometry)
    line = gym.make("MicroConveyor-v1").unwrapped
    line.reset(seed=0)
    line_state = line.get_state().to_dict()
    plane = MicroConveyor2DEnv()
    with pytest.raises(ValueError, match="saved in MicroConveyor-v1 is of another scene"):
        plane.reset(options={"state": line_state})
    with pytest.raises(ValueError, match="saved in MicroConveyor2D-v0 is of another scene"):
        line.reset(options={"state": saved})
    with pytest.raises(ValueError, match="must be a dict or PartState"):
        line.reset(options={"state": PlaneState.from_dict(saved)})
    with pytest.raises(ValueError, match="must be a dict or PlaneState"):
        plane.reset(options={"state": PartState.from_dict(line_state)})
    # a dict that names no scene cannot be checked
    bare = {k: v for k, v in saved.items() if k not in ("env_id", "scene")}
    with pytest.raises(ValueError, match=r"names no env id and scene.*PlaneState\(\*\*d\)"):
        plane.reset(options={"state": bare})
    with pytest.raises(ValueError, match=r"unknown keys \['noise_m'\]"):
        plane.reset(options={"state": {**saved, "noise_m": [[0.0] * 3]}})
    # v0 has no randomisation: a state carrying draws is refused (MicroConveyor2D-v1 takes them)
    with pytest.raises(ValueError, match=r"noise is given but the env has no execution noise"):
        plane.reset(options={"state": {**saved, "noise": [[0.0] * 3]}})


BAD = [
    ("fired", 8, r"fired = 8 is invalid: must be an integer in \[0, 7\]"),
    ("fired", 1.0, "fired = 1.0 is invalid"),
    ("time_s", 1.0, r"time_s = 1.0 \(1000 ms\) is invalid: must be finite and within \[0, 1000\)"),
    ("time_s", float("nan"), "time_s = nan"),
    ("position_m", [5.0, 0.0], r"position_m\[0\] = 5.0 \(5000 mm\) is invalid: must be finite "
                               r"and within \[-3.+, 3.+\] mm \(reachable from the start"),
    ("position_m", [0.001], r"position_m = \(0.001,\) is invalid: must be an \(x, y\) pair"),
    ("velocity_m_s", [0.0, 1e3], r"velocity_m_s\[1\] = 1000.0"),
    ("velocity_m_s", [2.5, 2.5], r"speed \|velocity_m_s\| = 3.5355.* \(3535.53 mm/s\) is invalid: "
                                 r"must be finite and within \[0, 3062.64\] mm/s"),
    ("target_m", [0.0, 0.011], r"target_m\[1\] = 0.011 \(11 mm\) is invalid: must be finite and "
                               r"within ±10 mm"),
    ("target_m", ["a", 0.0], r"target_m\[0\] = 'a'"),
    ("env_id", 3, "env_id = 3 is invalid"),
]


@pytest.mark.parametrize("key, value, message", BAD)
def test_bad_values_are_refused_before_anything_changes(key, value, message):
    env = _mid_episode()
    saved = env.get_state()
    bad = {**saved.to_dict(), key: value}
    rng_state = env.np_random.bit_generator.state
    with pytest.raises(ValueError, match=message):
        env.reset(seed=123, options={"state": bad})
    assert env.get_state() == saved and env.np_random.bit_generator.state == rng_state
    env.step(np.zeros(5, np.float32))   # the episode goes on
    venv = MicroConveyor2DVectorEnv(3)
    venv.reset(seed=1)
    before = [venv.get_state(i) for i in range(3)]
    with pytest.raises(ValueError, match="env 1: part state " + message.removeprefix("part state ")):
        venv.reset(seed=9, options={"state": [saved, bad, saved]})
    assert [venv.get_state(i) for i in range(3)] == before
    with pytest.raises(ValueError, match="2 part states for 3 envs"):
        venv.reset(options={"state": [saved, saved]})
    with pytest.raises(ValueError, match="'state' .* or 'target', not both"):
        env.reset(options={"state": saved, "target": (0.0, 0.0)})


def test_a_state_built_in_code_is_taken_as_the_envs_own():
    env = MicroConveyor2DEnv()
    s = PlaneState((1e-3, 1.2e-3), (0.0, 0.0), 0.0, 0, (0.5e-3, 0.5e-3))
    env.reset(options={"state": s})
    got = env.get_state()
    assert (got.position_m, got.target_m, got.env_id) == (s.position_m, s.target_m, None)
    assert env.target == (0.5e-3, 0.5e-3) and env.path == ((1e-3, 1.2e-3),)
