"""MicroPositioner-v0's DAgger with the expert ranked on the firing map: every label is confirmed
on the full model (its predicted landing is where the env puts the part, bit for bit), the map
search and the full-model search agree on what they may fire, the recipe runs end to end on a
tiny budget, and (slow tier) ten training seeds each reach the goal on 1,000 held-out targets
under the recipe's randomisation."""
from __future__ import annotations

import numpy as np
import pytest

from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState

pytest.importorskip("stable_baselines3")

from agents.imitation.dagger import DaggerSettings, dagger, recipe  # noqa: E402
from agents.mpc.experts import CONFIRM, BatchExpert  # noqa: E402

# resting parts: far from the target (the strongest firings, at the edge of detachment), a few
# pitches away, and within one firing's fine reach
X = np.array([-0.15e-3, 2.1e-3, 7.43e-3, 4.0e-3, 9.2e-3, 0.6e-3])
TARGET = np.array([9.9e-3, 1.2e-3, 7.5e-3, 4.3e-3, 8.95e-3, 0.5e-3])


def _env_rest(acts: np.ndarray, mass_factor: float = 1.0) -> tuple[np.ndarray, list[str]]:
    env = MicroPositionerEnv(mass_factor_range=(mass_factor, mass_factor))
    xs, outcomes = [], []
    for i, a in enumerate(acts):
        env.reset(options={"state": PositionerState(float(X[i]), 0.0, 0, float(TARGET[i]))})
        outcomes.append(env.step(a)[4]["outcome"])
        xs.append(env.x)
    return np.array(xs), outcomes


@pytest.mark.parametrize("search", ["map", "model"])
def test_the_label_lands_where_the_full_model_says(search: str) -> None:
    """The landing behind each label is the full model's for the float32 action the label is:
    the nominal env puts the part exactly there, and that is closer to the target."""
    cfg = PositionerConfig.from_yaml(None)
    expert = BatchExpert(cfg, frequencies=21, strokes=5, margin=2, slack=5e-6, heavier=0.1,
                         search=search)
    acts, ok, rest = expert.choose(X, np.zeros(len(X)), TARGET)
    assert ok.all() and acts.dtype == np.float32
    x_env, outcomes = _env_rest(acts)
    assert all(o in ("moving", "rest") for o in outcomes)
    assert np.array_equal(x_env, rest)   # bit for bit
    assert (np.abs(x_env - TARGET) < np.abs(X - TARGET)).all()


def test_the_map_expert_fires_few_candidates_and_chooses_as_the_full_search() -> None:
    """Ranked on the map, the expert fires at most 2 x CONFIRM candidates per part on the full
    model and as many again on the heavier part, not the whole grid; where the full-model search
    lands within the env's tolerance, so does the map's choice, within the slack plus the map's
    error of the full search's landing."""
    cfg = PositionerConfig.from_yaml(None)
    fast, full = (BatchExpert(cfg, 41, 6, 2, 5e-6, 0.1, search=search)
                  for search in ("map", "model"))
    t = np.zeros(len(X))
    a_map, ok_map, rest_map = fast.choose(X, t, TARGET)
    a_full, ok_full, rest_full = full.choose(X, t, TARGET)
    assert fast.full_firings <= len(X) * 4 * CONFIRM < full.full_firings / 20
    assert (ok_map == ok_full).all()
    finish = np.abs(rest_full - TARGET) <= cfg.tolerance
    assert finish.sum() >= 4
    e_map, e_full = np.abs(rest_map - TARGET), np.abs(rest_full - TARGET)
    assert (e_map[finish] <= e_full[finish] + 5e-6 + 10e-6).all()
    assert (e_map[finish] <= cfg.tolerance).all()


def test_the_map_expert_keeps_away_from_what_detaches_a_heavier_part() -> None:
    """Towards a far target the nearest landings sit at the edge of detachment; with no grid
    margin and no slack, ranked on the map (untrusted cells refused) and checked on a part 30 %
    heavier, none of its firings detaches that heavier part."""
    cfg = PositionerConfig.from_yaml(None)
    x = np.array([-0.15e-3, -0.1e-3, -0.05e-3, 2.1e-3, 4.45e-3, 0.7e-3])
    expert = BatchExpert(cfg, frequencies=21, strokes=3, margin=0, slack=0.0, heavier=0.3,
                         search="map")
    acts, ok = expert.act(x, np.zeros(6), np.full(6, 9.9e-3))
    assert ok.all()
    heavy = MicroPositionerEnv(mass_factor_range=(1.3, 1.3))
    for i in range(6):
        heavy.reset(options={"state": PositionerState(float(x[i]), 0.0, 0, 9.9e-3)})
        assert heavy.step(acts[i])[4]["outcome"] != "detached"


def test_search_is_checked() -> None:
    with pytest.raises(ValueError, match="search"):
        DaggerSettings(search="grid")
    with pytest.raises(ValueError, match="search"):
        BatchExpert(PositionerConfig.from_yaml(None), search="grid")
    assert recipe("MicroPositioner-v0").search == "map"


def test_an_expert_that_allows_nothing_is_refused_in_one_error(tmp_path) -> None:
    """A margin that spans the whole grid refuses every candidate: one ValueError, no folder."""
    s = DaggerSettings(rounds=1, episodes=2, epochs=1, frequencies=5, strokes=2, margin=4)
    with pytest.raises(ValueError, match="no firing"):
        dagger(tmp_path / "p", s, progress=lambda line: None)
    assert not (tmp_path / "p" / "model.zip").exists()


def test_the_recipe_runs_end_to_end_on_a_tiny_budget(tmp_path) -> None:
    """The positioner's recipe (its expert's grid and margins, its network) with two rounds of
    a few episodes: the expert acts in round 0 and lands its parts; the policy folder loads."""
    from agents.rl.evaluation.evaluate import load_policy

    s = recipe("MicroPositioner-v0", rounds=2, episodes=6, epochs=1)
    meta = dagger(tmp_path / "p", s, progress=lambda line: None)
    assert meta["expert"]["search"] == "map" and meta["expert"]["frequencies"] == s.frequencies
    assert meta["rounds"][0]["success_rate"] >= 5 / 6   # the expert acting
    assert load_policy(tmp_path / "p").env_id == "MicroPositioner-v0"


GOAL_SUCCESS, GOAL_MEDIAN_M = 0.90, 20e-6   # within ±50 µm; median |error|
GOAL_TARGETS, GOAL_TARGET_SEED = 1000, 10000


@pytest.mark.slow   # ten trainings of about 2.5 min of one core each, then 1,000 episodes each
@pytest.mark.parametrize("seed", range(10))
def test_the_recipe_reaches_the_goal(seed: int, tmp_path) -> None:
    """Each training seed of the recipe, from the simulator alone: >= 90 % of 1,000 held-out
    targets (seed 10000) within ±50 µm and a median |error| <= 20 µm, under the recipe's
    randomisation (σ = 3e-3, friction and mass ± 5 %)."""
    import torch

    from agents.rl.evaluation.evaluate import evaluate, load_policy

    torch.set_num_threads(1)
    dagger(tmp_path / "p", recipe("MicroPositioner-v0", seed=seed), progress=lambda line: None)
    res = evaluate(load_policy(tmp_path / "p"), GOAL_TARGETS, GOAL_TARGET_SEED)
    assert res["success_rate"] >= GOAL_SUCCESS, res
    assert res["median_abs_error_m"] <= GOAL_MEDIAN_M, res
