"""The shipped MicroPositioner-v0 policy (trained by DAgger) loads as data and reproduces its
recorded evaluations episode by episode, within the CPU tolerance that
tests/agents/test_shipped_policies.py derives (its module docstring); the held-out evaluation
at its training perturbation (1,000 targets) runs with the slow tests."""
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.shipped import default_policy_name, shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import load_policy  # noqa: E402

from support.shipped import _config, assert_reproduces  # noqa: E402

ENV_ID = "MicroPositioner-v0"
NAME = "dagger"


def test_positioner_policy_is_data_trained_under_perturbation():
    folder = shipped_path(NAME, ENV_ID)
    assert default_policy_name(ENV_ID) == NAME
    assert not list(folder.glob("*.pkl"))
    meta = load_policy(folder).metadata
    assert meta["env_id"] == ENV_ID and meta["trained_by"] == "dagger" and meta["files"]
    cfg = _config(meta, "trained")
    assert cfg.action_noise == 3e-3
    assert cfg.friction_factor_range == cfg.mass_factor_range == (0.95, 1.05)
    assert meta["wall_time_s"] <= 30 * 60 and meta["evaluation_provenance"]["package_version"]


@pytest.mark.parametrize("key", ["evaluation", "evaluation_nominal"])
def test_positioner_policy_reproduces_its_record(key):
    res = assert_reproduces(NAME, key, ENV_ID)
    assert res["n_targets"] == 100


@pytest.mark.slow
def test_positioner_policy_holds_held_out_targets_under_perturbation():
    """1,000 held-out targets (seed 1) at σ = 3e-3, r = 5 %: at rest within ±50 µm for at
    least 90 % of them, as recorded."""
    res = assert_reproduces(NAME, "evaluation_fresh", ENV_ID)
    assert res["n_targets"] == 1000 and res["success_rate_50um"] >= 0.9


def test_portable_inference_is_the_network_in_fixed_order_arithmetic():
    """The policy acts through the float64 fixed-order actor (its metadata asks for it); that
    actor is the network torch computes, within float32 rounding."""
    import numpy as np

    pol = load_policy(shipped_path(NAME, ENV_ID))
    assert pol.metadata["inference"] == "portable"
    obs = np.random.default_rng(0).normal(size=(16, 12)).astype(np.float32)
    normed = pol.normalizer(obs)
    portable = pol.actor.predict_portable(normed)
    np.testing.assert_array_equal(pol.act(obs), portable)
    np.testing.assert_allclose(portable, pol.actor.predict(normed), atol=2e-6)
