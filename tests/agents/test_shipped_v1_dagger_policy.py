"""The shipped MicroConveyor-v1 policy trained by DAgger (``microconveyor imitate``) loads as data,
names the expert it imitated, and reproduces its recorded evaluations episode by episode within
the CPU tolerance that tests/agents/test_shipped_policies.py derives (its module docstring); the
held-out evaluation (1,000 targets) runs with the slow tests and must meet v1's criterion."""
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from agents.rl.evaluation.evaluate import load_policy  # noqa: E402

from support.shipped import _config, assert_reproduces  # noqa: E402

ENV_ID = "MicroConveyor-v1"
NAME = "dagger"


def test_v1_dagger_policy_is_data_and_names_its_expert():
    folder = shipped_path(NAME, ENV_ID)
    assert not list(folder.glob("*.pkl"))
    pol = load_policy(folder)
    meta = pol.metadata
    assert meta["env_id"] == ENV_ID and meta["trained_by"] == "dagger" and meta["files"]
    assert meta["env_kwargs"] == {} and not _config(meta, "trained").randomised
    assert meta["inference"] == "portable"
    assert meta["expert"]["seed_policy"] == "ppo_refined"
    from agents.rl.artefacts.checkpoint import sha256
    # the seed policy it imitated is the one shipped beside it
    assert meta["expert"]["seed_policy_model_sha256"] == sha256(
        shipped_path("ppo_refined", ENV_ID) / "model.zip")
    assert meta["command"].startswith("microconveyor imitate --env MicroConveyor-v1 --seed 0")


def test_v1_dagger_policy_reproduces_its_record():
    res = assert_reproduces(NAME, "evaluation", ENV_ID)
    assert res["n_targets"] == 100


@pytest.mark.slow
def test_v1_dagger_policy_meets_the_criterion_on_held_out_targets():
    """1,000 held-out targets (seed 1): at least 90 % at rest within ±50 µm and a median
    |error| of at most 20 µm, as recorded."""
    res = assert_reproduces(NAME, "evaluation_fresh", ENV_ID)
    assert res["n_targets"] == 1000
    assert res["success_rate_50um"] >= 0.9 and res["median_abs_error_m"] <= 20e-6
