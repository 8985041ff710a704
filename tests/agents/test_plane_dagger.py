"""MicroConveyor2D-v1's DAgger: the package's recipe trains the plane from the simulator alone
(no shipped policy), its labels are the plane's five action components, the recipe runs end to
end on a tiny budget into a policy folder that loads, and (slow tier) three training seeds each
hold the recipe's level on 1,000 held-out targets under v1's randomisation."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.imitation.dagger import DaggerSettings, _play, dagger, make_expert, recipe  # noqa: E402
from microconveyor_env.envs.core.versions import vector_class  # noqa: E402

ENV = "MicroConveyor2D-v1"


def test_the_plane_has_a_recipe_and_an_expert_without_a_seed_policy() -> None:
    s = recipe(ENV)
    assert s.seed_policy is None and s.env_kwargs == {}
    cfg = s.config()
    assert type(cfg).__name__ == "PlaneEnvConfig"
    _, meta = make_expert(s, cfg)
    assert meta["lookahead"] == s.lookahead and meta["frequencies"] == s.frequencies
    with pytest.raises(ValueError, match="not seeded by a policy"):
        DaggerSettings(env_id=ENV, seed_policy="ppo").config()
    with pytest.raises(ValueError, match="lookahead_within_m"):
        DaggerSettings(env_id=ENV, lookahead_within_m=-1e-3)


def test_a_round_labels_the_planes_five_components_and_scores_its_distance() -> None:
    """The expert acting for a round: five-component labels, every episode's figure the
    Euclidean distance (its parts land within the tolerance, as the expert does)."""
    s = recipe(ENV, episodes=4)
    cfg = s.config()
    venv = vector_class(ENV)(4, config=cfg)
    label, _ = make_expert(s, cfg)
    X, Y, fig = _play(venv, label, None, seed=3)
    assert Y.shape[1] == 5 and X.shape == (len(Y), venv.conveyor.obs_dim) and len(Y) >= 4
    assert np.all(np.abs(Y) <= 1.0)
    assert fig["success_rate"] >= 0.75 and 0.0 <= fig["median_abs_error_m"] <= cfg.tolerance


def test_the_recipe_runs_end_to_end_on_a_tiny_budget(tmp_path) -> None:
    """The plane's recipe (its expert, its network) with two rounds of a few episodes: the
    expert acts in round 0 and lands its parts; the policy folder loads and acts in the plane."""
    from agents.rl.evaluation.evaluate import evaluate, load_policy

    s = recipe(ENV, rounds=2, episodes=8, epochs=1)
    meta = dagger(tmp_path / "p", s, progress=lambda line: None)
    assert meta["env_id"] == ENV and meta["expert"]["lookahead"] == s.lookahead
    assert meta["rounds"][0]["success_rate"] >= 6 / 8   # the expert acting
    policy = load_policy(tmp_path / "p")
    assert policy.env_id == ENV
    res = evaluate(policy, 4, 1)
    assert res["n_targets"] == 4


# the level the recipe holds (three seeds measured at 87.7-88.7 % within ±50 µm, medians
# 37-40 µm on 1,000 held-out targets): below the positioner's, because the recipe's expert lands
# each part with one firing along a line through an actuator and stops at the first landing within
# the tolerance (the expert alone: 95 %, median 34 µm)
LEVEL_SUCCESS, LEVEL_MEDIAN_M = 0.85, 45e-6
LEVEL_TARGETS, LEVEL_TARGET_SEED = 1000, 10000


@pytest.mark.slow   # three trainings of a few minutes of one core each, then 1,000 episodes each
@pytest.mark.parametrize("seed", range(3))
def test_the_recipe_holds_its_level_on_held_out_targets(seed: int, tmp_path) -> None:
    """Each of three training seeds of the plane's recipe, from the simulator alone: >= 85 % of 1,000 held-out targets (seed 10000) within ±50 µm and a median distance
    <= 45 µm, under v1's randomisation (σ = 3e-3, friction and mass ± 5 %)."""
    import torch

    from agents.rl.evaluation.evaluate import evaluate, load_policy

    torch.set_num_threads(1)
    dagger(tmp_path / "p", recipe(ENV, seed=seed), progress=lambda line: None)
    res = evaluate(load_policy(tmp_path / "p"), LEVEL_TARGETS, LEVEL_TARGET_SEED)
    assert res["success_rate"] >= LEVEL_SUCCESS, res
    assert res["median_abs_error_m"] <= LEVEL_MEDIAN_M, res
