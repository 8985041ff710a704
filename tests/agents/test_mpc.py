"""Model-predictive control: deterministic given its seeds, within its budgets, no worse than its
own first plan on an exact model, the same with one worker or two, and clear errors."""
import dataclasses

import numpy as np
import pytest

from agents.mpc import MPC, MPCSettings, mpc_rollout
from agents.openloop.target import solve_target
from agents.planning import LineRollouts, scene_of
from agents.rl.artefacts.shipped import require_shipped
from agents.experiments.perturb import policy_rollout
from agents.rl.evaluation.evaluate import load_policy
from agents.planning.scene import Rollouts
from microconveyor_env.envs import MicroConveyorEnv, env_config
from microconveyor_env.envs.core.versions import nominal

pytest.importorskip("cma")

TINY = MPCSettings(first_budget=40, replan_budget=20)


def test_mpc_is_deterministic_and_respects_its_budgets():
    cfg = env_config("MicroConveyor-v1")
    a = MPC(cfg, TINY).run(MicroConveyorEnv(config=cfg), 3e-3, seed=1)
    b = MPC(cfg, TINY).run(MicroConveyorEnv(config=cfg), 3e-3, seed=1)
    assert dataclasses.replace(a, wall_time_s=0.0) == dataclasses.replace(b, wall_time_s=0.0)
    assert 1 <= a.firings <= cfg.n_actuators
    # the first plan gets its budget, each re-plan its own; DE uses whole generations only
    assert a.episodes <= TINY.first_budget + (a.firings - 1) * TINY.replan_budget
    assert a.episodes >= 20 and a.wall_time_s > 0


@pytest.mark.parametrize("method", ["de", "cmaes"])
def test_mpc_on_an_exact_model_is_no_worse_than_its_first_plan(method):
    """Re-plans start from the previous plan's remainder (warm start) on the very model the part
    follows, and a restart from a state is exact: the final error can only improve."""
    cfg = env_config("MicroConveyor-v1")
    s = MPCSettings(method=method, first_budget=60, replan_budget=30, seed=4)
    for target in (1.2e-3, 6e-3):
        env = MicroConveyorEnv(config=cfg)
        ep = MPC(cfg, s).run(env, target, seed=0)
        first = solve_target(target, method, 60, seed=4, config=cfg)
        assert abs(ep.error_m) <= first.abs_error_m + 1e-12


def test_one_worker_or_two_give_the_same_episodes():
    cfg = env_config("MicroConveyor-v1", action_noise=3e-3, friction_factor_range=(0.95, 1.05),
                     mass_factor_range=(0.95, 1.05))
    targets = np.array([1e-3, 4e-3, 8e-3])
    one = mpc_rollout(TINY)(cfg, targets, 7)
    with mpc_rollout(TINY, workers=2) as run:
        two = run(cfg, targets, 7)
    for key in ("error_m", "episodes", "friction_factor", "mass_factor", "firings"):
        assert np.array_equal(one[key], two[key]), key
    assert list(one["outcome"]) == list(two["outcome"])
    # the factors reported are the episode's: as the env seeded seed + i draws them
    env = MicroConveyorEnv(config=cfg)
    env.reset(seed=8)
    assert one["friction_factor"][1] == env.friction_factor


def test_the_controller_sees_no_hidden_randomisation_and_plans_nominally():
    cfg = env_config("MicroConveyor-v1", action_noise=3e-3, friction_factor_range=(0.9, 1.1))
    env = MicroConveyorEnv(config=cfg)
    env.reset(seed=0)
    seen = scene_of(cfg).observed(env.get_state())
    assert seen.friction_factor is None and seen.noise is None
    assert not nominal(cfg).randomised
    with pytest.raises(ValueError, match="nominal"):
        MPC(cfg)
    with pytest.raises(ValueError, match="method"):
        MPCSettings(method="pso")
    with pytest.raises(ValueError, match="budget"):
        MPCSettings(first_budget=2)
    with pytest.raises(ValueError, match="workers"):
        mpc_rollout(workers=0)


def test_identification_recovers_the_episodes_friction_without_noise():
    """Without execution noise the observed firings are the model's with the true factors, so
    the grid search finds the true friction to within its finer grid's resolution (the mass
    factor is only weakly identifiable: adhesion dominates the weight, so the pair sits on a
    ridge; the friction-to-mass ratio is what a coast reveals)."""
    real = env_config("MicroConveyor-v1", friction_factor_range=(0.9, 1.1),
                      mass_factor_range=(1.0, 1.0))
    s = MPCSettings(first_budget=40, replan_budget=20, identify=True, factor_range=0.1)
    ctl = MPC(nominal(real), s)
    env = MicroConveyorEnv(config=real)
    found = 0
    for seed in range(6):
        ep = ctl.run(env, 9e-3, seed=seed)
        if ep.firings >= 2:  # identified from at least one observed firing
            found += 1
            step = 2 * 0.1 / (9 - 1) / 4  # the refined grid's spacing
            assert abs(ep.estimated_factors[0] / ep.estimated_factors[1]
                       - ep.friction_factor / ep.mass_factor) <= 2 * step, ep
    assert found >= 3


def test_plans_from_a_state_on_the_container_are_the_envs_bit_for_bit():
    # the line's rollouts from a saved state skip the env (planners re-plan from every state):
    # the same episodes as the env's reset-from-state path
    cfg = env_config("MicroConveyor-v1")
    rng = np.random.default_rng(0)
    env = MicroConveyorEnv(config=cfg)
    seen = set()
    for trial in range(4):
        env.reset(seed=trial, options={"target": float(rng.uniform(0.5e-3, 10e-3))})
        for _ in range(trial % 3):   # weak firings: the part stays on the surface
            env.step(np.array([-0.5, -1.0, -1.0], np.float32))
        start = env.get_state()
        plans = rng.uniform(-1, 1, (48, cfg.n_actuators - start.fired, 3))
        roll = LineRollouts(cfg)
        fast = roll.run(plans, 0.0, start=start)
        slow = Rollouts.run(roll, plans, 0.0, start=start)      # the env's path
        for k in ("target_m", "error_m", "success", "time_s"):
            assert np.array_equal(getattr(fast, k), getattr(slow, k)), k
        assert list(fast.outcome) == list(slow.outcome)
        seen |= set(fast.outcome)
    assert {"rest", "detached"} <= seen


def test_the_newton_mpc_corrects_its_priors_plan_on_the_model():
    # seeded by the shipped policy (its plan from each state, on the model), the minimum-norm
    # Gauss-Newton re-plan brings a nominal part to rest on the target, in a few dozen model
    # episodes a firing: within 2 µm where the last actuator fires; where the env stops a part
    # already delivered (within the tolerance) it ends there
    cfg = env_config("MicroConveyor-v1")
    prior = load_policy(require_shipped("MicroConveyor-v1", "ppo_refined"), cfg)
    s = MPCSettings(method="newton", first_budget=70, replan_budget=70)
    for target, firings in ((3.2e-3, 4), (8.6e-3, 5)):
        alone = policy_rollout(prior)(cfg, np.array([target]), 0)
        ep = MPC(cfg, s, prior).run(MicroConveyorEnv(config=cfg), target, seed=0)
        assert ep.firings == firings
        assert ep.success and ep.outcome == "rest" and abs(ep.error_m) <= cfg.tolerance
        if ep.firings == cfg.n_actuators:
            assert abs(ep.error_m) <= 2e-6 < abs(alone["error_m"][0])
        assert ep.episodes <= (70 + 2) * ep.firings      # + the prior's comparison each time
    with pytest.raises(ValueError, match="prior"):
        MPC(cfg, s).run(MicroConveyorEnv(config=cfg), 3e-3, seed=0)
    with pytest.raises(ValueError, match="noise_copies"):
        MPCSettings(method="newton", noise_copies=4, assumed_noise=3e-3)


def test_robust_settings_are_checked():
    with pytest.raises(ValueError, match="go together"):
        MPCSettings(noise_copies=4)
    with pytest.raises(ValueError, match="go together"):
        MPCSettings(assumed_noise=3e-3)
    with pytest.raises(ValueError, match="budget"):
        MPCSettings(noise_copies=8, assumed_noise=3e-3, first_budget=30)
    with pytest.raises(ValueError, match="factor_range"):
        MPCSettings(identify=True, factor_range=0.0)
    s = MPCSettings(first_budget=80, replan_budget=80, noise_copies=4, assumed_noise=3e-3)
    cfg = env_config("MicroConveyor-v1")
    ep = MPC(cfg, s).run(MicroConveyorEnv(config=cfg), 2e-3, seed=0)
    assert ep.episodes <= 80 * ep.firings and ep.episodes % 4 == 0


@pytest.mark.slow   # ~11 s; CI's slow tier runs it (.ci/run)
def test_a_dead_mpc_worker_costs_only_a_rerun_of_the_unfinished_batches():
    """A pool worker killed between calls breaks the pool: the next call runs its batches again
    in supervised processes of their own (the same episodes: results do not depend on the
    workers), counts the death, and the call after it starts a fresh pool. A batch whose own
    process dies too comes back as failed episodes."""
    import os
    import signal

    from agents.mpc import harness

    cfg = env_config("MicroConveyor-v1")
    targets = np.array([2e-3, 4e-3, 6e-3, 8e-3])
    with mpc_rollout(TINY, workers=2) as run:
        first = run(cfg, targets, 7)
        victim = next(iter(run._pool._processes))
        os.kill(victim, signal.SIGKILL)
        import time

        time.sleep(1.0)                              # the executor notices the death
        again = run(cfg, targets, 7)
        assert run.worker_deaths == 1 and run._pool is None
        np.testing.assert_array_equal(again["error_m"], first["error_m"])
        third = run(cfg, targets, 7)                 # a fresh pool
        np.testing.assert_array_equal(third["error_m"], first["error_m"])
    batch = harness.Batch(cfg, None, TINY, targets[:2], np.arange(2), np.arange(2))
    lost = harness._lost_episodes(batch, "died")
    assert [e.outcome for e in lost] == [harness.LOST] * 2 and np.isnan(lost[0].error_m)
