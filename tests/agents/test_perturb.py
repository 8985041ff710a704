"""agents.experiments.perturb (success against perturbation) and agents.rl.evaluation.evaluate with randomisation on."""
import numpy as np
import pytest

from agents.rl.evaluation.evaluate import evaluate, rollout
from agents.experiments.perturb import Level, ladder, perturbation_table, plan_rollout, policy_rollout
from microconveyor_env.envs import EnvConfig, MicroConveyorEnv
from microconveyor_env.envs.core.actions import encode_actions

CFG = EnvConfig(n_actuators=2, num_threads=1)
PLAN = np.stack([encode_actions(950.0, 180e-6, 0.0, CFG)] * 2)  # (2 firings, 3)
LEVELS = [Level(0.0, 0.0), Level(0.05, 0.1), Level(0.1, 0.3)]


@pytest.fixture(scope="module")
def landing():
    env = MicroConveyorEnv(config=CFG)
    env.reset(seed=0, options={"target": 1e-3})
    for a in PLAN:
        env.step(a)
    return env.x


def test_plan_and_equivalent_policy_give_the_same_table(landing):
    targets = [landing, landing + 30e-6, landing + 200e-6]
    by_plan = perturbation_table(plan_rollout(PLAN), CFG, targets, LEVELS, per_episode=True)
    plans = np.broadcast_to(PLAN, (3, 2, 3))
    by_plans = perturbation_table(plan_rollout(plans), CFG, targets, LEVELS, per_episode=True)
    by_policy = perturbation_table(policy_rollout(lambda obs: np.tile(PLAN[0], (len(obs), 1))),
                                   CFG, targets, LEVELS, per_episode=True)
    assert by_plan == by_plans == by_policy
    assert len(by_plan) == len(LEVELS) * 3
    # level 0 is the unperturbed env: the first two targets are hit, the third missed
    assert [r["success"] for r in by_plan[:3]] == [True, True, False]
    assert all(r["friction_factor"] == 1.0 and r["mass_factor"] == 1.0 for r in by_plan[:3])


def test_summary_rows_factors_and_common_random_numbers(landing):
    targets = [landing, landing + 30e-6, landing + 200e-6]
    rows = perturbation_table(plan_rollout(PLAN), CFG, targets, LEVELS, repeats=2)
    assert [r["level"] for r in rows] == [0, 1, 2]
    r0 = rows[0]
    assert r0["n_episodes"] == 6 and r0["success_rate"] == pytest.approx(4 / 6)
    assert r0["success_ci95"][0] < 4 / 6 < r0["success_ci95"][1]
    assert rows[2]["friction_factor_range"] == [0.7, 1.3] and rows[2]["spread"] == 0.3
    assert rows == perturbation_table(plan_rollout(PLAN), CFG, targets, LEVELS, repeats=2)
    eps = perturbation_table(plan_rollout(PLAN), CFG, targets, LEVELS, repeats=2,
                             per_episode=True)
    for lv in LEVELS[1:]:
        mine = [e for e in eps if e["spread"] == lv.spread]
        assert all(1 - lv.spread <= e["friction_factor"] <= 1 + lv.spread for e in mine)
        assert all(1 - lv.spread <= e["mass_factor"] <= 1 + lv.spread for e in mine)
    # common random numbers: the same uniforms, scaled by the level's spread
    u1 = [(e["friction_factor"] - 1) / 0.1 for e in eps if e["level"] == 1]
    u2 = [(e["friction_factor"] - 1) / 0.3 for e in eps if e["level"] == 2]
    np.testing.assert_allclose(u1, u2, rtol=1e-12)


def test_bad_inputs():
    with pytest.raises(ValueError, match="plans of shape"):
        perturbation_table(plan_rollout(np.zeros((3, 3))), CFG, [1e-3], LEVELS[:1])
    with pytest.raises(ValueError, match="friction_factor_range"):
        perturbation_table(plan_rollout(PLAN), CFG, [1e-3], [Level(0.0, 0.95)])
    with pytest.raises(ValueError, match="repeats"):
        perturbation_table(plan_rollout(PLAN), CFG, [1e-3], LEVELS[:1], repeats=0)
    with pytest.raises(ValueError, match="noise levels"):
        ladder([0.0, 0.1], [0.0])
    assert ladder([0.0, 0.1], [0.0, 0.2])[1] == Level(0.1, 0.2)


class _Const:
    def act(self, obs):
        return np.tile(PLAN[0], (len(obs), 1))


def test_evaluate_and_rollout_accept_a_randomised_config():
    cfg = EnvConfig(n_actuators=2, action_noise=0.05, friction_factor_range=(0.8, 1.2),
                    mass_factor_range=(0.9, 1.1))
    res = rollout(_Const(), np.array([1e-3, 1.2e-3, 1.4e-3]), cfg, seed=4)
    assert np.all((res["friction_factor"] >= 0.8) & (res["friction_factor"] <= 1.2))
    assert np.all((res["mass_factor"] >= 0.9) & (res["mass_factor"] <= 1.1))
    assert "friction_factor" not in rollout(_Const(), np.array([1e-3]), CFG)
    out = evaluate(_Const(), n_targets=4, seed=1, config=cfg)
    assert out["n_targets"] == 4 and 0 <= out["success_rate"] <= 1
    assert out == evaluate(_Const(), n_targets=4, seed=1, config=cfg)  # reproducible


def test_the_comparisons_axes_share_their_levels(landing):
    from agents.experiments.perturb import axes_table, perturbation_levels, unique_levels

    axes = perturbation_levels([0.0, 0.05], [0.1], [(0.05, 0.1)], full=True)
    assert axes["action_noise"] == [Level(), Level(0.05, 0.0)]
    assert axes["spread"] == [Level(), Level(0.0, 0.1)]
    assert axes["combined"] == [Level(), Level(0.05, 0.1)]
    assert axes["grid"] == [Level(), Level(0.0, 0.1), Level(0.05, 0.0), Level(0.05, 0.1)]
    assert unique_levels(axes) == [Level(), Level(0.05, 0.0), Level(0.0, 0.1), Level(0.05, 0.1)]
    calls = []

    def run(cfg, targets, seed):
        calls.append((cfg.action_noise, cfg.friction_factor_range))
        return plan_rollout(PLAN)(cfg, targets, seed)

    table = axes_table(run, CFG, np.array([landing, landing + 30e-6]), axes)
    assert len(calls) == 4                                   # each distinct level once
    assert table["spread"][0] == table["action_noise"][0] == table["grid"][0]
    assert table["combined"][1] == table["grid"][3] and table["grid"][3]["level"] == 3
    alone = perturbation_table(plan_rollout(PLAN), CFG, [landing, landing + 30e-6],
                               [Level(0.05, 0.1)], tolerance=CFG.tolerance)[0]
    assert {**alone, "level": 3} == table["combined"][1]
