"""The plane's planner (agents/planning/plane.py): candidates ranked on the firing map and
confirmed on the full model, whose answer is the env's bit for bit; the delay lets the part
come to rest before the stroke; a tiny episode reaches its target; DAgger's labels."""
import dataclasses
import math

import numpy as np
import pytest

from agents.planning.plane import (NO_LABEL, PartStates, PlaneController, PlaneScene,
                                   PlaneSettings, dilate, play)
from microconveyor_env.envs.core.versions import scene_config
from microconveyor_env.envs.plane.vector import MicroConveyor2DVectorEnv
from microconveyor_env.physics import dynamics_kernel as k1
from microconveyor_env.physics.forces import I_FSCALE, I_MASS
from microconveyor_env.physics.plane import kernel as pk

ENV = "MicroConveyor2D-v1"
TARGETS = np.array([[0.35e-3, 1.62e-3], [1.8e-3, 0.2e-3], [1.1e-3, 0.93e-3], [0.05e-3, 0.1e-3]])
SMALL = PlaneSettings(frequencies=21, strokes=4)


def nominal():
    return dataclasses.replace(scene_config(ENV), action_noise=0.0, num_threads=1,
                               friction_factor_range=(1.0, 1.0), mass_factor_range=(1.0, 1.0))


@pytest.fixture(scope="module")
def controller():
    return PlaneController(nominal(), SMALL)


def rest_of(env, i):
    """Where part ``i`` of ``env`` comes to rest, its own constants (closed form)."""
    c = env.conveyor
    p = c.parts
    x, y, _, _, _, rest, _ = pk.coast(p.x[i], p.y[i], p.vx[i], p.vy[i], math.inf, c.consts.P[i],
                                      c.consts.tu, c.consts.tq, c.consts.tqu)
    assert rest
    return np.array([x, y])


@pytest.mark.parametrize("randomised", [False, True])
def test_the_choice_lands_where_the_full_model_said_bit_for_bit(controller, randomised):
    cfg = nominal()
    if randomised:   # the env's own factors, no execution noise: the model told those factors
        cfg = dataclasses.replace(cfg, friction_factor_range=(0.95, 1.05),
                                  mass_factor_range=(0.95, 1.05))
    env = MicroConveyor2DVectorEnv(len(TARGETS), config=cfg)
    env.reset(seed=11, options={"target": TARGETS})
    c = env.conveyor
    for _ in range(3):   # from rest, then from parts still coasting after a stroke
        live = np.ones(len(TARGETS), bool)
        acts, ok, landing = controller.act(env, live)
        s = PartStates.of(c.parts)
        ff, mf = np.array(c.friction_factor), np.array(c.mass_factor)
        told, _, code = controller.scene.fire(s, acts, ff, mf)
        assert np.all(code == k1.REST)
        if not randomised:
            assert np.array_equal(told, landing)
        _, _, term, _, _ = env.step(acts)
        for i in range(len(TARGETS)):
            assert np.array_equal(rest_of(env, i), told[i])
        if term.any():
            break


def test_the_model_factors_reach_the_model_part(controller):
    sc = controller.scene
    s = PartStates(*(np.array([v]) for v in (1.0e-3, 1.0e-3, 0.0, 0.0, 0.0, 0, 1.5e-3, 1.0e-3)))
    a = np.array([[1.0, 0.0, -0.3, 0.5, -1.0]], np.float32)
    base, _, _ = sc.fire(s, a)
    slow, _, _ = sc.fire(s, a, friction_factor=1.05, mass_factor=0.95)
    again, _, _ = sc.fire(s, a)
    assert np.array_equal(base, again) and not np.array_equal(base, slow)
    P = sc._container(1).consts.P[0]
    assert P[I_FSCALE] == pytest.approx(1.0 * sc.map.plane.params[I_FSCALE])
    assert P[I_MASS] == pytest.approx(sc.map.plane.params[I_MASS])


def test_the_delay_lets_a_part_of_any_allowed_factors_rest_before_the_stroke(controller):
    cfg = scene_config(ENV)
    env = MicroConveyor2DVectorEnv(len(TARGETS), config=dataclasses.replace(cfg, num_threads=1))
    env.reset(seed=3, options={"target": TARGETS})
    c = env.conveyor
    acts, _, _ = controller.act(env)
    env.step(acts)
    p = c.parts
    assert np.hypot(p.vx, p.vy).max() > 0.0              # still coasting after the stroke
    acts, _, _ = controller.act(env)
    delay = 0.1 * (acts[:, 4].astype(float) + 1.0) / 2.0
    delay -= 0.1 * 0.5 * 4.0 * cfg.action_noise          # four sigma of execution noise
    base = controller.scene.map.plane.params
    for i in range(len(TARGETS)):
        for ff in (0.95, 1.05):
            for mf in (0.95, 1.05):
                P = base.copy()
                P[I_FSCALE] *= ff
                P[I_MASS] *= mf
                t_stop = pk.coast(p.x[i], p.y[i], p.vx[i], p.vy[i], math.inf, P,
                                  *controller.scene.map.plane.tables)[4]
                assert 0.0 < t_stop < delay[i]


@pytest.mark.parametrize("randomised", [False, True])
def test_a_tiny_episode_reaches_its_target(controller, randomised):
    cfg = scene_config(ENV) if randomised else nominal()
    r = play(controller, cfg, TARGETS[:2], seed=5)
    assert r.success.all() and np.all(r.outcome == "rest")
    assert np.all(r.distance_m <= cfg.tolerance) and r.moving.sum() == 0
    assert np.all(r.firings <= cfg.max_firings)


def test_the_labels_of_a_batched_env(controller):
    env = MicroConveyor2DVectorEnv(4, config=dataclasses.replace(scene_config(ENV),
                                                                  num_threads=1))
    obs, _ = env.reset(seed=0, options={"target": TARGETS})
    live = np.array([True, False, True, True])
    labeller = PlaneController(scene_config(ENV), dataclasses.replace(SMALL, slack_m=5e-6),
                               scene=controller.scene)
    acts, has, fixed = labeller.label(obs, env, live)
    assert acts.shape == (4, 5) and acts.dtype == np.float32 and fixed is None
    assert has.dtype == bool and not has[1] and has[[0, 2, 3]].all()
    assert np.array_equal(acts[1], NO_LABEL)
    assert np.all(np.abs(acts) <= 1.0)
    # the gentlest within the slack: a wider slack never picks a higher frequency
    wide = PlaneController(scene_config(ENV), dataclasses.replace(SMALL, slack_m=40e-6,
                                                                  lookahead=False),
                           scene=controller.scene)
    near = PlaneController(scene_config(ENV), dataclasses.replace(SMALL, lookahead=False),
                           scene=controller.scene)
    a_wide, ok_wide, _ = wide.label(obs, env, live)
    a_near, _, _ = near.label(obs, env, live)
    assert np.all(a_wide[ok_wide, 2] <= a_near[ok_wide, 2])


def test_the_margin_grows_a_refusal_over_frequency_and_stroke():
    bad = np.zeros((1, 1, 7, 5), bool)
    bad[0, 0, 3, 2] = True
    grown = dilate(bad, 1)
    assert grown[0, 0, 2:5, 1:4].all() and grown.sum() == 9
    assert np.array_equal(dilate(bad, 0), bad)


def test_the_scene_serves_the_plane_only():
    with pytest.raises(ValueError, match="plane"):
        PlaneScene(scene_config("MicroPositioner-v0"))
    with pytest.raises(ValueError, match="delay_factor"):
        PlaneSettings(delay_factor=0.5)


def test_the_lookahead_sees_a_part_on_a_line_through_an_actuator_and_the_target(controller):
    sc = controller.scene
    act = np.array([1.0e-3, 1.0e-3])                  # an actuator
    target = act + np.array([0.2e-3, 0.0])
    on_line = act + np.array([0.35e-3, 0.0])          # pulled 150 µm towards it: on target
    off_line = act + np.array([0.35e-3, 0.03e-3])
    err, travel = sc.next_error(np.stack([on_line, off_line]), np.stack([target, target]),
                                SMALL)
    assert err[0] <= 1e-9 and travel[0] == pytest.approx(150e-6)
    assert 0.0 < err[1] <= 30e-6
    # and the full model agrees: some firing of that actuator lands within a micrometre
    s = PartStates(*(np.array([v]) for v in (*on_line, 0.0, 0.0, 0.0, 0, *target)))
    a = np.zeros((41 * 11, 5), np.float32)
    a[:, 0] = -0.7
    F, H = np.meshgrid(np.linspace(-1, 1, 41), np.linspace(-1, 1, 11), indexing="ij")
    a[:, 2], a[:, 3], a[:, 4] = F.ravel(), H.ravel(), -1.0
    land, _, code = sc.fire(s.take(np.zeros(len(a), int)), a)
    d = np.where(code == k1.REST, np.hypot(*(land - target).T), np.inf)
    assert d.min() <= 3e-6
