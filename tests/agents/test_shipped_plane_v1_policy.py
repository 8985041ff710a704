"""The shipped MicroConveyor2D-v1 PPO (trained under per-episode randomisation) loads as data and
reproduces its recorded episodes: 1,000 held-out targets under its training randomisation
(``evaluation``) and the same targets without it (``evaluation_nominal``).

Tolerances as tests/agents/test_shipped_plane_policy.py derives them: each episode's final
Euclidean error within ``EPISODE_TOL_M`` = 1 µm, outcomes exact, success changing only for an
episode whose recorded error lies within that distance of a radius. The targets and each
episode's friction and mass factors are pure numpy draws: exact.
"""
import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.policy_files import PolicyError, load_policy, policy_env_kwargs  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import (  # noqa: E402
    ADDED_FIGURES,
    TOLERANCES,
    figures,
    fixed_targets,
    plane_record,
    rollout,
)
from microconveyor_env.envs.plane.config import PlaneEnvConfig  # noqa: E402
from microconveyor_env.envs.core.versions import scene_config  # noqa: E402

EPISODE_TOL_M = 1e-6
ENV_ID = "MicroConveyor2D-v1"
TRAINED_KWARGS = {"action_noise": 3e-3, "friction_factor_range": [0.95, 1.05],
                  "mass_factor_range": [0.95, 1.05]}


def test_v1_policy_is_data_and_names_its_env_and_randomisation(monkeypatch):
    import pickle

    folder = shipped_path("ppo", ENV_ID)
    assert not list(folder.glob("*.pkl"))

    def refuse(*a, **k):
        raise AssertionError("a pickle was opened while loading the shipped plane policy")

    monkeypatch.setattr(pickle, "load", refuse)
    monkeypatch.setattr(pickle, "loads", refuse)
    pol = load_policy(folder)
    assert isinstance(pol.config, PlaneEnvConfig) and pol.env_id == ENV_ID
    assert not pol.config.randomised and pol.config.max_firings == 12   # loaded nominal
    assert pol.actor.obs_dim == 10 and pol.actor.low.shape == (5,)
    a = pol.act(np.zeros((3, 10), np.float32))
    assert a.shape == (3, 5) and np.all(np.abs(a) <= 1)
    meta = pol.metadata
    kw = policy_env_kwargs(meta)
    assert {k: kw[k] for k in TRAINED_KWARGS} == TRAINED_KWARGS
    assert meta["algo"] == "ppo" and meta["files"] and meta["steps"] >= 8_000_000
    assert meta["evaluation"]["config"] == "trained"
    assert meta["evaluation_nominal"]["config"] == "nominal"
    # the v0 scene is another task length: refused, naming the field
    with pytest.raises(PolicyError, match="max_firings"):
        load_policy(folder, scene_config("MicroConveyor2D-v0"))


def assert_reproduces(key: str, n: int | None = None) -> dict:
    """Re-run the record ``key`` (its first ``n`` episodes; None: all: sub-env ``i`` is seeded
    ``seed + i`` whatever the batch, so a prefix replays as it was recorded) and compare it,
    episode by episode, with episodes.json; the summary of all the recorded episodes (which must
    be the metadata's)."""
    folder = shipped_path("ppo", ENV_ID)
    pol = load_policy(folder)
    meta = pol.metadata
    rec = json.loads((folder / "episodes.json").read_text())[key]
    level = {k: rec[k] for k in TRAINED_KWARGS}
    cfg = scene_config(ENV_ID, **{**policy_env_kwargs(meta), **level})
    assert cfg.randomised == (key == "evaluation")
    targets = fixed_targets(cfg, meta[key]["n_targets"], rec["seed"])
    np.testing.assert_array_equal(targets, rec["target_m"])        # pure numpy RNG: exact
    n = len(targets) if n is None else n
    res = rollout(pol, targets[:n], cfg, seed=rec["seed"])
    if cfg.randomised:
        np.testing.assert_array_equal(res["friction_factor"], rec["friction_factor"][:n])
        np.testing.assert_array_equal(res["mass_factor"], rec["mass_factor"][:n])
    err_all, out_all = np.array(rec["error_m"]), np.array(rec["outcome"], dtype=object)
    err0, out0 = err_all[:n], out_all[:n]
    np.testing.assert_array_equal(res["outcome"], out0)
    assert np.max(np.abs(res["error_m"] - err0)) <= EPISODE_TOL_M
    rest0 = out0 == "rest"
    for tol in TOLERANCES:
        flips = ((res["outcome"] == "rest") & (res["error_m"] <= tol)) != (rest0 & (err0 <= tol))
        assert np.all(np.abs(err0[flips] - tol) <= EPISODE_TOL_M), (tol, err0[flips])
    # (a record made before a figure of ADDED_FIGURES was reported lacks that figure alone)
    episodes = {"error_m": err_all, "outcome": out_all, "firings": rec["firings"],
                **({"time_s": rec["time_s"]} if "time_s" in rec else {})}
    stored = plane_record(figures(episodes, cfg.tolerance))
    for k, v in stored.items():
        if k in ADDED_FIGURES and k not in meta[key]:
            continue
        assert meta[key][k] == v, k
    return stored


@pytest.mark.parametrize("key", ["evaluation", "evaluation_nominal"])
def test_shipped_v1_policy_reproduces_its_record(key):
    """The first 100 episodes of each record (the whole record: the slow test below)."""
    stored = assert_reproduces(key, 100)
    assert stored["n_targets"] == 1000 and stored["detach_rate"] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("key", ["evaluation", "evaluation_nominal"])
def test_shipped_v1_policy_reproduces_its_whole_record(key):
    assert_reproduces(key)


def test_the_recipe_is_the_shipped_v1_policys():
    """configs/ppo.yml's MicroConveyor2D-v1 entry (with its `microconveyor:` keys) is what the
    shipped policy was trained with, one torch thread, for the whole step budget."""
    from agents.rl.training import hyperparams

    meta = json.loads((shipped_path("ppo", ENV_ID) / "metadata.json").read_text())
    hp = json.loads(json.dumps(hyperparams.load(None, ENV_ID), default=str))
    assert hyperparams.changed_keys(meta["hyperparams"], hp) == []
    assert hp["exploration_shift"] == {"at": 0.833, "by": -1.0}
    assert meta["steps"] >= hp["n_timesteps"]
