"""The batched env against gymnasium's SyncVectorEnv of single envs, step for step."""
import gymnasium as gym
import numpy as np


def assert_infos_equal(mine, ref):
    """Every key of SyncVectorEnv's info matches; extra keys of ours are fully masked out."""
    for key, val in ref.items():
        if key == "final_obs":
            for a, b in zip(mine[key], val, strict=True):
                assert (a is None and b is None) or np.array_equal(a, b)
        elif key == "final_info":
            assert_infos_equal(mine[key], val)
        else:
            np.testing.assert_array_equal(mine[key], val, err_msg=key)
    for key in set(mine) - set(ref):
        if key.startswith("_"):
            assert not mine[key].any(), key


def assert_lockstep_with_sync(batched, kw, seed, steps, action_seed, bound, mode=None) -> int:
    """Step ``batched`` and a SyncVectorEnv of single envs made with ``kw`` side by side on the
    same uniform actions in [-bound, bound]: every obs, reward, flag and info key equal, from the
    reset on. Returns how many episodes ended."""
    n = batched.num_envs
    extra = {} if mode is None else {"autoreset_mode": mode}
    sync = gym.vector.SyncVectorEnv([lambda: gym.make("MicroConveyor-v0", **kw) for _ in range(n)],
                                    **extra)
    o1, i1 = batched.reset(seed=seed)
    o2, i2 = sync.reset(seed=seed)
    np.testing.assert_array_equal(o1, o2)
    assert_infos_equal(i1, i2)
    rng = np.random.default_rng(action_seed)
    ended = 0
    for _ in range(steps):
        a = rng.uniform(-bound, bound, (n, 3)).astype(np.float32)
        r1, r2 = batched.step(a), sync.step(a)
        for k in range(4):
            np.testing.assert_array_equal(r1[k], r2[k])
        assert_infos_equal(r1[4], r2[4])
        ended += int(r1[2].sum() + r1[3].sum())
    return ended
