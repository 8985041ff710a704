"""The line's placement-time lower bound (agents/planning/bounds.py): its closed form on a hand
case, and no cheap played episode beats it."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from agents.planning.bounds import flat_deceleration, line_time_bound_s, reach_m
from microconveyor_env.envs.core.versions import scene_config, vector_class

ENV = "MicroConveyor-v1"


def _cfg() -> Any:
    return dataclasses.replace(scene_config(ENV), num_threads=1)


def test_closed_form_on_a_hand_case() -> None:
    cfg = _cfg()
    a_f = flat_deceleration(cfg)
    assert 8.0 < a_f < 9.5                     # Q(m g0) / m on chapter 4's surface
    # nothing within the last bump's reach (2 mm + 0.4 mm), then the coast: a part that rests
    # a_f (20 ms)^2 / 2 past that point needs at least 20 ms
    assert np.isclose(reach_m(cfg), 0.4e-3)
    far = 2.4e-3 + 0.5 * a_f * 0.02 ** 2
    got = line_time_bound_s(cfg, [1e-3, 2.4e-3, far])
    assert got[:2].tolist() == [0.0, 0.0] and np.isclose(got[2], 0.02, rtol=1e-12)


def test_no_played_episode_beats_the_bound() -> None:
    cfg = dataclasses.replace(_cfg(), stop_at_target=False)   # every plan played whole
    rng = np.random.default_rng(3)
    n = 48
    plans = rng.uniform(-1.0, 1.0, (n, cfg.n_actuators, 3))
    plans[: n // 2, :, 2] = -1.0                        # half of them without delays
    # the staged expert's carrying plan (agents/mpc/staged.py), its third firing's frequency
    # over the stage: the part goes 7-11 mm, then the last two actuators fire under nothing
    plans[:4, :3] = [[-0.385, 0.64, -1.0], [-0.45, 1.0, -0.9], [-0.34, -1.0, -1.0]]
    plans[:4, 2, 0] = [-0.52, -0.46, -0.4, -0.34]
    plans[:4, 3:] = -1.0
    lo, hi = cfg.target_range
    targets = rng.uniform(lo, hi, n)
    env = vector_class(ENV)(n, config=cfg, autoreset_mode="NextStep")
    env.reset(seed=0, options={"target": targets})
    done = np.zeros(n, bool)
    x, t, rest = np.zeros(n), np.zeros(n), np.zeros(n, bool)
    for k in range(cfg.n_actuators):
        _, _, term, trunc, info = env.step(plans[:, k].astype(np.float32))
        end = ~done & (term | trunc)
        x[end] = targets[end] + info["position_error_m"][end]
        t[end], rest[end] = info["sim_time_s"][end], info["outcome"][end] == "rest"
        done |= end
    assert rest.sum() >= 10
    bound = line_time_bound_s(cfg, x[rest])
    assert (t[rest] >= bound).all()
    assert (bound > 0.5 * t[rest]).any()   # not trivially low: parts that went far
