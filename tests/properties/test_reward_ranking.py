"""The reward ranks outcomes as a user does (envs/line/task.py): resting at the target > resting near
it > resting far > detaching, for every configuration validation accepts.

Episodes are composed from the compiled per-step reward (``task.reward``) over drawn
trajectories: any positions and times, ending at rest or detached.
"""
import math

import numpy as np
from hypothesis import assume, given, settings, strategies as st

from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.line import task
from microconveyor_env.physics import dynamics_kernel as K
from microconveyor_env.physics.materials import ParameterError

from .strategies import log_uniform

CONFIGS = st.fixed_dictionaries({
    "target_range": st.tuples(log_uniform(1e-5, 0.1), log_uniform(1e-5, 0.1)).map(sorted).map(tuple),
    "tolerance": log_uniform(1e-8, 1e-2),
    "progress_scale": st.none() | log_uniform(1e-7, 1e-1),
    "time_cost": st.just(0.0) | log_uniform(1e-3, 1e6),
    "success_bonus": st.just(0.0) | log_uniform(1e-3, 1e6),
    "detach_penalty": log_uniform(1e-3, 1e6),
    "max_time": log_uniform(1e-2, 1e3),
    "start_offset": log_uniform(1e-6, 1e-2),
    "progress_horizon": st.none() | log_uniform(1e-5, 1.0),
})
POS = st.floats(-0.5, 0.5)
FRAC = st.floats(0.0, 1.0)


def _cfg(kw):
    try:
        return EnvConfig(**kw)
    except ParameterError:
        assume(False)


def _episode(TC, x0, target, path, end_x, end_t_frac, code, max_time):
    """Return of an episode from x0 through ``path`` [(x, time fraction)] ending with ``code``
    at ``end_x`` (times strictly increasing and below max_time)."""
    fracs = sorted({f for _, f in path} | {end_t_frac})
    times = [f * max_time * 0.999 for f in fracs]
    xs = [x for x, _ in path][:len(times) - 1] + [end_x]
    xs = [x0] * (len(times) - len(xs)) + xs
    total, x, t = 0.0, x0, 0.0
    for i, (xn, tn) in enumerate(zip(xs, times, strict=True)):
        c = code if i == len(xs) - 1 else K.MOVING
        total += task.reward(c, x, xn, t, tn, target, TC)
        x, t = xn, tn
    return total


@settings(max_examples=300, deadline=None)
@given(kw=CONFIGS, u=FRAC, path_a=st.lists(st.tuples(POS, FRAC), max_size=5),
       path_b=st.lists(st.tuples(POS, FRAC), max_size=5), rest_x=POS, det_x=POS, ta=FRAC, tb=FRAC)
def test_any_rest_returns_more_than_any_detachment(kw, u, path_a, path_b, rest_x, det_x, ta, tb):
    cfg = _cfg(kw)
    TC = task.constants(cfg)
    target = cfg.target_range[0] + u * (cfg.target_range[1] - cfg.target_range[0])
    x0 = -cfg.start_offset
    rest = _episode(TC, x0, target, path_a, rest_x, ta, K.REST, cfg.max_time)
    det = _episode(TC, x0, target, path_b, det_x, tb, K.DETACHED, cfg.max_time)
    assert math.isfinite(rest) and math.isfinite(det)
    assert rest > det, (rest, det)


@settings(max_examples=300, deadline=None)
@given(kw=CONFIGS, u=FRAC, d1=FRAC, d2=FRAC, s1=st.booleans(), s2=st.booleans(), t=FRAC)
def test_closer_rest_returns_more_and_success_most(kw, u, d1, d2, s1, s2, t):
    cfg = _cfg(kw)
    TC = task.constants(cfg)
    target = cfg.target_range[0] + u * (cfg.target_range[1] - cfg.target_range[0])
    x0 = -cfg.start_offset
    h = cfg.progress_horizon
    near, far = sorted((d1 * h, d2 * h))
    assume(far - near > 1e-9 * h)
    sign1, sign2 = (1 if s1 else -1), (1 if s2 else -1)
    g_near = _episode(TC, x0, target, [], target + sign1 * near, t, K.REST, cfg.max_time)
    g_far = _episode(TC, x0, target, [], target + sign2 * far, t, K.REST, cfg.max_time)
    assert g_near > g_far
    # at the target (within tolerance) beats near it, by at least the success bonus
    g_at = _episode(TC, x0, target, [], target, t, K.REST, cfg.max_time)
    if near > cfg.tolerance:
        assert g_at >= g_near + cfg.success_bonus
        assert g_at > g_near


def test_default_config_all_zero_action_no_longer_pays():
    """The issue's counterexample: the all-zero action (it detaches) must return less than a
    schedule that rests, whatever the target."""
    from microconveyor_env.envs import MicroConveyorVectorEnv

    env = MicroConveyorVectorEnv(64, num_threads=1)
    env.reset(seed=0)
    totals, outcome = np.zeros(64), np.full(64, "", dtype=object)
    for _ in range(5):
        _, r, term, trunc, info = env.step(np.zeros((64, 3), np.float32))
        totals += r
        outcome = np.where(term | trunc, info["outcome"], outcome)
    det = outcome == "detached"
    assert det.any()
    assert totals[det].max() < -env.config.detach_penalty  # forfeits all progress, and more
