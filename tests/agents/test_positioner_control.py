"""MicroPositioner-v0's model-based controller and open-loop plans: a chosen firing lands where
the model says, the identified friction is the one the firings were made with, a plan search
returns a plan of the asked shape, and compare on the positioner writes every row and chart."""
import dataclasses
import json

import numpy as np
import pytest

from agents.mpc import MPC, OneStepSettings
from agents.mpc.identification import FrictionFit
from agents.openloop.target import plans_rollout, solve_target
from agents.planning import PositionerScene
from agents.planning.scene import FiringModel, RestFiringModel
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.vector import MicroPositionerVectorEnv
from microconveyor_env.envs.core.versions import scene_config
from support.cli import run_cli

ENV = "MicroPositioner-v0"


def test_candidates_aim_at_every_reachable_actuator_exactly():
    cfg = scene_config(ENV)
    acts, n = PositionerScene(cfg).candidates(2.05e-3, 3, 2)
    assert acts.shape == (n * 3 * 2, 3) and acts.dtype == np.float32
    aims = np.unique(acts[:, 0])
    picked = np.floor((2.05e-3 + aims * cfg.pick_reach) / cfg.spacing + 0.5)
    # 1.5-2.5 mm: the actuators nearest an aim point within 0.5 mm of the part
    assert list(picked) == [6, 7, 8, 9, 10]
    inner = np.abs(aims) < 1   # those within reach are aimed at exactly
    assert np.allclose(picked[inner] * cfg.spacing,
                       2.05e-3 + aims[inner].astype(float) * cfg.pick_reach, atol=1e-9)


def test_the_chosen_firing_lands_near_the_target_on_the_nominal_model():
    cfg = scene_config(ENV)
    env = MicroPositionerEnv(config=cfg)
    env.reset(seed=0, options={"target": 1.2e-3})
    ctl = MPC(cfg, OneStepSettings(model="nominal", search="model")).planner
    state = PositionerScene(cfg).observed(env.get_state())
    acts, x, allowed = ctl.predict(state)
    action = ctl.choose(state)
    assert action is not None and action.shape == (3,)
    i = np.flatnonzero((acts.reshape(-1, 3) == action).all(axis=1))[0]
    assert allowed.ravel()[i]
    _, _, term, _, info = env.step(action)
    assert env.x == pytest.approx(x.ravel()[i], abs=1e-12)   # the model is the env's scene
    assert abs(env.x - 1.2e-3) <= cfg.tolerance and term and info["is_success"]


@pytest.mark.parametrize("factors", [(1.0, 1.0), (1.04, 0.96)])
def test_a_choice_searched_on_the_map_is_the_full_models(factors):
    # the map ranks, the full model (with the model's factors) confirms: the chosen firing
    # lands exactly where the full model said, on a real part with those factors
    cfg = scene_config(ENV, friction_factor_range=(factors[0],) * 2,
                       mass_factor_range=(factors[1],) * 2)
    env = MicroPositionerEnv(config=cfg)
    env.reset(seed=0, options={"target": 6.3e-3})
    ctl = MPC(scene_config(ENV), OneStepSettings(model="nominal", search="map")).planner
    scene = PositionerScene(scene_config(ENV))
    for _ in range(cfg.max_firings):
        state = scene.observed(env.get_state())
        before = ctl.spent
        best, rests = ctl.ranked(state, factors)
        assert ctl.spent - before <= 2 * ctl.settings.check_best   # not every candidate
        action = ctl.choose(state, factors)
        if action is None:
            break
        i = int(np.flatnonzero((best == action).all(axis=1))[0])
        _, _, term, _, info = env.step(action)
        assert env.x == rests[i]                     # bit for bit: the full model's answer
        if term:
            break
    assert info["is_success"]


def test_the_rest_firing_model_writes_states_as_a_reset_would():
    cfg = scene_config(ENV)
    env = MicroPositionerEnv(config=cfg)
    env.reset(seed=0, options={"target": 7e-3})
    env.step(np.array([0.3, 0.2, 0.5], np.float32))
    state = PositionerScene(cfg).observed(env.get_state())
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (200, 3)).astype(np.float32)
    states = [dataclasses.replace(state, friction_factor=float(a), mass_factor=float(b))
              for a, b in rng.uniform(0.8, 1.2, (200, 2))]
    x_reset, ok_reset = FiringModel(cfg, MicroPositionerVectorEnv).rests(states, acts)
    x_fast, ok_fast = RestFiringModel(cfg).rests(states, acts)
    assert np.array_equal(x_reset, x_fast) and np.array_equal(ok_reset, ok_fast)
    assert 0.5 < ok_fast.mean() < 1.0          # both outcomes are in the sample


def test_the_identified_friction_is_the_one_the_firings_were_made_with():
    true = 1.07
    real = scene_config(ENV, friction_factor_range=(true, true))
    env = MicroPositionerEnv(config=real)
    env.reset(seed=0, options={"target": 9e-3})
    settings = OneStepSettings(model="identified")
    scene = PositionerScene(scene_config(ENV))
    fit = FrictionFit(scene.firing_model(), settings)
    chooser = MPC(scene_config(ENV), OneStepSettings(model="nominal")).planner
    for _ in range(2):
        before = scene.observed(env.get_state())
        assert before.friction_factor is None   # the controller never sees the factor
        action = chooser.choose(before)
        env.step(action)
        fit.add((before, action, scene.observed(env.get_state())))
    assert fit.estimate() == pytest.approx(true, abs=0.005)
    fit.reset()
    assert fit.estimate() == 1.0


def test_a_plan_search_returns_a_plan_of_the_asked_shape():
    cfg = scene_config(ENV)
    for method in ("de", "cmaes"):
        r = solve_target(3e-3, method, 40, 0, config=cfg, firings=4)
        assert r.plan.shape == (4, 3) and np.all(np.abs(r.plan) <= 1)
        assert 0 < r.episodes <= 40 and r.outcome in ("rest", "detached")
        assert r.error_m == pytest.approx(
            plans_rollout(r.plan[None])(cfg, np.array([3e-3]), 0)["error_m"][0], abs=1e-12)


def test_settings_refuse_an_unknown_model_or_search():
    with pytest.raises(ValueError, match="model"):
        OneStepSettings(model="exact")
    with pytest.raises(ValueError, match="search"):
        OneStepSettings(search="grid")


def test_compare_on_the_positioner_writes_every_row_and_the_chart(tmp_path):
    pytest.importorskip("cma")
    out = tmp_path / "cmp"
    r = run_cli("compare", "--env", ENV, "--targets", "2", "--budgets", "20", "--noise", "0",
                "--spread", "0", "--diagonal", "3e-3:0.05", "--plan-firings", "3", "--workers",
                "1", "--plot", out / "c.png", "--json")   # episodes do not depend on workers
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    names = [row["method"] for row in res["rows"]]
    assert names[-5:] == ["mpc_identified", "mpc_nominal", "de", "cmaes", "mpc_oracle"]
    assert res["rows"][-1]["reference"] == "reference (knows the hidden factors)"
    for row in res["rows"]:
        assert row["n_targets"] == 2 and 0 <= row["success_rate"] <= 1
        assert row["wall_s_per_target"] > 0 and 0 <= row["detach_rate"] <= 1
    pert = res["perturbation"]
    assert {"mpc_identified", "mpc_nominal", "mpc_oracle", "de_20_plan",
            "cmaes_20_plan"} <= set(pert)
    for tables in pert.values():
        assert [(lv["action_noise"], lv["spread"]) for lv in tables["combined"]] == [
            (0.0, 0.0), (3e-3, 0.05)]
        assert all(len(lv["success_ci95"]) == 2 for lv in tables["combined"])
    for name in ("c.png", "c_perturbation.png", "c_compute.png", "c.json"):
        assert (out / name).stat().st_size > 1000


@pytest.mark.slow
def test_compare_on_the_positioner_runs_the_full_grid():
    pytest.importorskip("cma")
    from agents.experiments.compare import compare
    from agents.experiments.compare_settings import CompareSettings

    res = compare(CompareSettings(env_id=ENV, n_targets=2, budgets=(20,), full_grid=True,
                                  noise_ladder=(0.0, 3e-3), spread_ladder=(0.0, 0.05),
                                  diagonal=((3e-3, 0.05),), plan_firings=3, progress=False))
    for tables in res["perturbation"].values():
        assert [(lv["action_noise"], lv["spread"]) for lv in tables["grid"]] == [
            (0.0, 0.0), (0.0, 0.05), (3e-3, 0.0), (3e-3, 0.05)]
