"""A reset the env refuses changes nothing: every part's options (targets, saved states) are
checked before any part is reset or reseeded, in the single and the batched env, on the line and
on the plane. After a refused reset the old episode continues bit for bit, and the next reset
draws what it would have drawn (the generators are untouched)."""
import math

import numpy as np
import pytest

from microconveyor_env.envs import MicroConveyorEnv, MicroConveyorVectorEnv, PartState, env_config
from microconveyor_env.envs.plane.env import MicroConveyor2DEnv
from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv

CFG = env_config("MicroConveyor-v1", action_noise=3e-3, friction_factor_range=(0.95, 1.05),
                 mass_factor_range=(0.95, 1.05), num_threads=1)
GENTLE = np.array([[-1.0, -1.0, -1.0], [-0.8, -1.0, -1.0], [-0.6, -1.0, -1.0]], np.float32)


def _same_steps(a, b):
    """Two step (or reset) results, bit for bit: arrays as bytes, infos key by key."""
    *arrays_a, info_a = a
    *arrays_b, info_b = b
    for x, y in zip(arrays_a, arrays_b, strict=True):
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes()
    assert info_a.keys() == info_b.keys()
    for key in info_a:
        assert np.asarray(info_a[key]).tolist() == np.asarray(info_b[key]).tolist(), key


def _bad_state(good: PartState) -> PartState:
    return PartState(good.position_m, math.nan, good.time_s, good.fired, good.target_m)


@pytest.mark.parametrize("bad", ["nan velocity", "nan target", "state and target",
                                 "misspelled option"])
def test_refused_single_reset_continues_the_old_episode(bad):
    env, twin = MicroConveyorEnv(config=CFG), MicroConveyorEnv(config=CFG)
    for e in (env, twin):
        e.reset(seed=4, options={"target": 5e-3})
        e.step(GENTLE[0])
    s = env.get_state()
    opts = {"nan velocity": {"state": _bad_state(s)}, "nan target": {"target": math.nan},
            "state and target": {"state": s, "target": 2e-3},
            "misspelled option": {"targt": 2e-3}}[bad]
    with pytest.raises(ValueError):
        env.reset(seed=123, options=opts)
    assert env.get_state() == s
    for a in GENTLE[1:]:
        _same_steps(env.step(a), twin.step(a))
    # the generator was neither reseeded nor drawn from: the next episode is the twin's
    _same_steps(env.reset(), twin.reset())
    _same_steps(env.step(GENTLE[0]), twin.step(GENTLE[0]))


@pytest.mark.parametrize("bad", ["state 3 of 3", "target 2 of 3", "target shape",
                                 "misspelled option"])
def test_refused_batched_reset_changes_no_sub_env(bad):
    vec, twin = (MicroConveyorVectorEnv(3, config=CFG) for _ in range(2))
    for v in (vec, twin):
        v.reset(seed=11, options={"target": 5e-3})
        v.step(GENTLE)
    before = [vec.get_state(i) for i in range(3)]
    opts = {"state 3 of 3": {"state": [before[0], before[1], _bad_state(before[2])]},
            "target 2 of 3": {"target": [1e-3, math.nan, 2e-3]},
            "target shape": {"target": [1e-3, 2e-3]},
            "misspelled option": {"state": before, "targets": [1e-3, 2e-3, 3e-3]}}[bad]
    with pytest.raises(ValueError):
        vec.reset(seed=500, options=opts)
    assert [vec.get_state(i) for i in range(3)] == before
    _same_steps(vec.step(GENTLE[::-1]), twin.step(GENTLE[::-1]))
    _same_steps(vec.reset(), twin.reset())


def test_refused_set_targets_changes_no_target():
    vec = MicroConveyorVectorEnv(3, config=CFG)
    vec.reset(seed=2)
    before = vec.target.copy()
    with pytest.raises(ValueError, match="target"):
        vec.set_targets([0, 1, 2], [1e-3, 2e-3, math.nan])
    assert vec.target.tobytes() == before.tobytes()


def test_refused_plane_resets_change_nothing():
    env, twin = MicroConveyor2DEnv(), MicroConveyor2DEnv()
    a = np.array([0.3, -0.2, -0.5, 0.0, -1.0], np.float32)
    for e in (env, twin):
        e.reset(seed=5)
        e.step(a)
    with pytest.raises(ValueError, match="target"):
        env.reset(seed=77, options={"target": (math.nan, 0.0)})
    _same_steps(env.step(a), twin.step(a))
    _same_steps(env.reset(), twin.reset())

    vec, vtwin = MicroConveyor2DVectorEnv(3, num_threads=1), MicroConveyor2DVectorEnv(
        3, num_threads=1)
    for v in (vec, vtwin):
        v.reset(seed=8)
    targets = vec.target.copy()
    with pytest.raises(ValueError, match="target"):
        vec.reset(seed=9, options={"target": [[1e-3, 1e-3], [1e-3, 1e-3], [math.nan, 0.0]]})
    assert vec.target.tobytes() == targets.tobytes()
    _same_steps(vec.step(np.tile(a, (3, 1))), vtwin.step(np.tile(a, (3, 1))))
    _same_steps(vec.reset(), vtwin.reset())
