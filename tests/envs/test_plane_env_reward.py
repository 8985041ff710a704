"""MicroConveyor2D-v0's reward ranks outcomes as a user does (envs/plane/task.py), for every
configuration validation accepts: any rest beats any detachment; a closer rest beats a farther one
and a success beats both. Episodes are composed from the compiled per-step reward over drawn
paths in the plane (any positions and times, ending at rest or detached), as
tests/properties/test_reward_ranking.py does for the line."""
import math

import numpy as np
from hypothesis import assume, given, settings, strategies as st

from microconveyor_env.envs.plane import task as plane_task
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.physics import dynamics_kernel as K
from microconveyor_env.physics.materials import ParameterError


def log_uniform(lo, hi):
    return st.floats(math.log(lo), math.log(hi)).map(math.exp)


CONFIGS = st.fixed_dictionaries({
    "nx": st.integers(1, 9), "ny": st.integers(1, 9),
    "spacing": log_uniform(1e-5, 1e-3),
    "tolerance": log_uniform(1e-8, 1e-3),
    "progress_scale": st.none() | log_uniform(1e-7, 1e-1),
    "time_cost": st.just(0.0) | log_uniform(1e-3, 1e6),
    "success_bonus": st.just(0.0) | log_uniform(1e-3, 1e6),
    "detach_penalty": log_uniform(1e-3, 1e6),
    "max_time": log_uniform(1e-2, 1e3),
    "start_jitter": st.just(0.0) | log_uniform(1e-6, 1e-3),
    "progress_horizon": st.none() | log_uniform(1e-5, 1.0),
})
UNIT = st.floats(0.0, 1.0)
POINT = st.tuples(st.floats(-0.01, 0.01), st.floats(-0.01, 0.01))


def _cfg(kw, u, v):
    kw = dict(kw, start=(u * (kw["nx"] - 1) * kw["spacing"], v * (kw["ny"] - 1) * kw["spacing"]))
    try:
        return PlaneEnvConfig(**kw)
    except ParameterError:
        assume(False)


def _episode(TC, start, target, path, end, end_t_frac, code, max_time):
    """Return of an episode from ``start`` through ``path`` [((x, y), time fraction)] ending
    with ``code`` at ``end``."""
    fracs = sorted({f for _, f in path} | {end_t_frac})
    times = [f * max_time * 0.999 for f in fracs]
    pts = [p for p, _ in path][:len(times) - 1] + [end]
    pts = [start] * (len(times) - len(pts)) + pts
    total, p, t = 0.0, start, 0.0
    for i, (q, tn) in enumerate(zip(pts, times, strict=True)):
        c = code if i == len(pts) - 1 else K.MOVING
        total += plane_task.reward(c, math.dist(p, target), math.dist(q, target), t, tn, TC)
        p, t = q, tn
    return total


@settings(max_examples=300, deadline=None)
@given(kw=CONFIGS, u=UNIT, v=UNIT, tu=UNIT, tv=UNIT,
       path_a=st.lists(st.tuples(POINT, UNIT), max_size=5),
       path_b=st.lists(st.tuples(POINT, UNIT), max_size=5), rest=POINT, det=POINT, ta=UNIT,
       tb=UNIT)
def test_any_rest_returns_more_than_any_detachment(kw, u, v, tu, tv, path_a, path_b, rest, det,
                                                   ta, tb):
    cfg = _cfg(kw, u, v)
    TC = plane_task.constants(cfg)
    (x0, x1), (y0, y1) = cfg.grid_box
    target = (x0 + tu * (x1 - x0), y0 + tv * (y1 - y0))
    r = _episode(TC, cfg.start, target, path_a, rest, ta, K.REST, cfg.max_time)
    d = _episode(TC, cfg.start, target, path_b, det, tb, K.DETACHED, cfg.max_time)
    assert math.isfinite(r) and math.isfinite(d)
    assert r > d, (r, d)


@settings(max_examples=300, deadline=None)
@given(kw=CONFIGS, u=UNIT, v=UNIT, tu=UNIT, tv=UNIT, d1=UNIT, d2=UNIT,
       a1=st.floats(0, 2 * math.pi), a2=st.floats(0, 2 * math.pi), t=UNIT)
def test_closer_rest_returns_more_and_success_most(kw, u, v, tu, tv, d1, d2, a1, a2, t):
    cfg = _cfg(kw, u, v)
    TC = plane_task.constants(cfg)
    (x0, x1), (y0, y1) = cfg.grid_box
    target = (x0 + tu * (x1 - x0), y0 + tv * (y1 - y0))
    h = cfg.progress_horizon
    near, far = sorted((d1 * h, d2 * h))
    assume(far - near > 1e-9 * h)

    def at(dist, angle):  # a rest point at this distance and bearing from the target
        return target[0] + dist * math.cos(angle), target[1] + dist * math.sin(angle)

    p_near, p_far = at(near, a1), at(far, a2)
    # the distance the reward sees (rounding of the polar point) must keep the order
    assume(math.dist(p_far, target) - math.dist(p_near, target) > 1e-12 * h)
    g_near = _episode(TC, cfg.start, target, [], p_near, t, K.REST, cfg.max_time)
    g_far = _episode(TC, cfg.start, target, [], p_far, t, K.REST, cfg.max_time)
    assert g_near > g_far
    g_at = _episode(TC, cfg.start, target, [], target, t, K.REST, cfg.max_time)
    if math.dist(p_near, target) > cfg.tolerance:
        assert g_at >= g_near + cfg.success_bonus
        assert g_at > g_near


def test_detaching_firings_return_less_than_gentle_ones():
    """In the env itself: episodes that detach (fast strokes) return less than any that rest."""
    from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv

    n = 32
    totals = {}
    for name, f in (("fast", 1.0), ("gentle", -1.0)):
        env = MicroConveyor2DVectorEnv(n, num_threads=1, autoreset_mode="SameStep")
        env.reset(seed=0)
        total, outcome, live = np.zeros(n), np.full(n, "", dtype=object), np.ones(n, bool)
        rng = np.random.default_rng(0)
        for _ in range(env.config.max_firings):
            a = rng.uniform(-1, 1, (n, 5)).astype(np.float32)
            a[:, 2], a[:, 3] = f, 1.0
            _, r, term, trunc, info = env.step(a)
            total += np.where(live, r, 0.0)
            ended = live & (term | trunc)
            outcome = np.where(ended, info["final_info"]["outcome"] if ended.any() else outcome,
                               outcome)
            live &= ~ended
        totals[name] = (total, outcome)
    fast, fast_out = totals["fast"]
    gentle, gentle_out = totals["gentle"]
    assert (fast_out == "detached").any() and (gentle_out == "rest").any()
    assert fast[fast_out == "detached"].max() < gentle[gentle_out == "rest"].min()
