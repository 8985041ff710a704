"""The shipped policies load as data and reproduce their recorded evaluations on any CPU.

Why tolerances, and these ones: the policies run in float32 through torch, whose matmul (MKL)
and activations take CPU-specific code paths. Measured on one machine by switching MKL's path
(``MKL_CBWR=COMPATIBLE`` against the default; SSE4_2, AVX and ``ATEN_CPU_CAPABILITY=default``
changed nothing): 74 of 300 action components move by up to 6 float32 ULP, the final position
of an episode by at most 1.5 nm (nominal policy, 93 of 100 episodes move) and 18 nm (randomised
policy), and no outcome changes. What the stored figures protect is success within +-50/100/250 um
and the median error against a 20 um bar, so each episode's final error must agree within
``EPISODE_TOL_M`` = 1 um: 55 times the largest deviation measured, 2 % of the tightest tolerance.
An episode may change success only if its recorded error lies within that distance of a tolerance
edge; the median moves by at most the largest per-episode change (it is 1-Lipschitz in the
sup-norm), so it gets the same bound. Outcomes (rest/detached) must match exactly.
"""
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.evaluation.evaluate import load_policy  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402

from support.shipped import _config, assert_reproduces  # noqa: E402


def test_shipped_policy_loads_and_reproduces_its_metadata():
    meta = load_policy(shipped_path("ppo", "MicroConveyor-v0")).metadata
    assert meta["steps"] > 0 and meta["wall_time_s"] <= 15 * 60 + 60 and meta["config_hash"]
    assert meta["evaluation_provenance"]["package_version"] and meta["files"]
    res = assert_reproduces("ppo", "evaluation")
    # issue 11's bar, on the final checkpoint
    assert res["success_rate_50um"] >= 0.9 and res["median_abs_error_m"] <= 20e-6


def test_randomised_policy_reproduces_its_metadata():
    """The PPO trained under randomisation: its evaluation on the randomised config it was
    trained on and on the nominal env."""
    meta = load_policy(shipped_path("ppo_randomised", "MicroConveyor-v0")).metadata
    cfg = _config(meta, "trained")
    assert cfg.action_noise > 0 and cfg.friction_factor_range[0] < 1 < cfg.friction_factor_range[1]
    for key in ("evaluation", "evaluation_nominal"):
        assert_reproduces("ppo_randomised", key)


def test_shipped_v1_policy_loads_and_reproduces_its_metadata():
    """MicroConveyor-v1's PPO (seed 0 of the five-seed run of the recipe with its exploration
    restart and shift, the median seed; re-run alone without periodic evaluations, bit-identical):
    its scene, budget and evaluation on the monitored targets. It does not meet issue 20's bar,
    and the test does not pretend it does: it protects the recorded figures (docs/agents.md)."""
    meta = load_policy(shipped_path("ppo", "MicroConveyor-v1")).metadata
    assert meta["env_id"] == "MicroConveyor-v1" and meta["algo"] == "ppo"
    assert meta["steps"] >= 6_000_000 and meta["wall_time_s"] <= 15 * 60
    assert meta["hyperparams"]["n_envs"] == 256 and meta["files"]
    assert meta["hyperparams"]["exploration_restart"] == {"at": 0.667, "log_std": -2.0}
    assert meta["hyperparams"]["exploration_shift"] == {"at": 0.833, "by": -1.0}
    res = assert_reproduces("ppo", "evaluation", "MicroConveyor-v1")
    assert res["n_targets"] == 100 and res["detach_rate"] == 0.0


def test_shipped_v1_refined_policy_meets_the_bar_and_reproduces_its_metadata():
    """MicroConveyor-v1's PPO refined by `microconveyor refine` (issue 20): seed 0 of the shipped
    ppo's recipe, trained from scratch on the 2-core machine, then refined. It names the run it
    came from (file hashes, evaluation), keeps the recipe's scene and hyperparameters, was
    trained and refined within 15 minutes, and meets the bar on the monitored targets."""
    meta = load_policy(shipped_path("ppo_refined", "MicroConveyor-v1")).metadata
    src = load_policy(shipped_path("ppo", "MicroConveyor-v1")).metadata
    assert meta["refined_from"]["files"]["model.zip"] != meta["files"]["model.zip"]
    assert meta["refined_from"]["evaluation"]["n_targets"] == 100
    assert meta["env_config"] == src["env_config"] and meta["hyperparams"] == src["hyperparams"]
    assert meta["config_hash"] == src["config_hash"] and meta["steps"] == src["steps"]
    rep = meta["refinement"]
    assert rep["settings"]["targets"] == 1000 and rep["kept_round"] >= 1
    assert meta["wall_time_s"] + rep["wall_time_s"] <= 15 * 60
    res = assert_reproduces("ppo_refined", "evaluation", "MicroConveyor-v1")
    assert res["n_targets"] == 100 and res["detach_rate"] == 0.0
    assert res["success_rate_50um"] >= 0.9 and res["median_abs_error_m"] <= 20e-6


def test_shipped_v1_randomised_policy_reproduces_its_metadata():
    """MicroConveyor-v1's robust PPO baseline (issue 21): trained at the goal's perturbation
    level (sigma = 3e-3, r = 5 %); its evaluations there and nominally reproduce. It does not
    meet the goal, and the test does not pretend it does."""
    meta = load_policy(shipped_path("ppo_randomised", "MicroConveyor-v1")).metadata
    cfg = _config(meta, "trained")
    assert cfg.action_noise == 3e-3
    assert cfg.friction_factor_range == cfg.mass_factor_range == (0.95, 1.05)
    assert meta["conf_file"] == "configs/ppo_randomised.yml" and meta["steps"] >= 6_000_000
    for key in ("evaluation", "evaluation_nominal"):
        assert_reproduces("ppo_randomised", key, "MicroConveyor-v1")


@pytest.mark.slow
def test_shipped_v1_policy_full_evaluation():
    res = assert_reproduces("ppo", "evaluation_fresh", "MicroConveyor-v1")
    assert res["n_targets"] == 1000


@pytest.mark.slow
def test_shipped_v1_refined_policy_full_evaluation():
    """1,000 fresh targets: the refined policy holds the bar there too (docs/agents.md)."""
    res = assert_reproduces("ppo_refined", "evaluation_fresh", "MicroConveyor-v1")
    assert res["n_targets"] == 1000 and res["detach_rate"] == 0.0
    assert res["success_rate_50um"] >= 0.9 and res["median_abs_error_m"] <= 20e-6


@pytest.mark.slow
def test_shipped_policy_full_evaluation():
    """1,000 fresh targets (not the set monitored in training): the bar holds and the figures are
    those in the metadata (``evaluation_fresh``) and the README."""
    res = assert_reproduces("ppo", "evaluation_fresh")
    assert res["n_targets"] == 1000 and res["detach_rate"] == 0.0
    assert res["success_rate_50um"] >= 0.9 and res["median_abs_error_m"] <= 20e-6


@pytest.mark.slow
def test_shipped_v1_randomised_policy_at_the_goal_level():
    """Issue 21's goal level (σ = 3e-3 together with r = 5 %): the robust PPO on 100 fixed
    targets × 3 perturbed replays (docs/agents.md: 17.7 %, far from the goal's 90 %). Two
    episodes of 300 may flip on another CPU (float32 policy outputs: module docstring)."""
    from agents.experiments.perturb import Level, perturbation_table, policy_rollout
    from agents.rl.evaluation.evaluate import fixed_targets

    pol = load_policy(shipped_path("ppo_randomised", "MicroConveyor-v1"))
    cfg = pol.config
    row = perturbation_table(policy_rollout(pol), cfg, fixed_targets(cfg, 100, 0),
                             [Level(action_noise=3e-3, spread=0.05)], repeats=3)[0]
    assert row["n_episodes"] == 300 and row["detach_rate"] == 0.0
    assert abs(row["success_rate"] - 0.177) <= 2 / 300 + 1e-12
