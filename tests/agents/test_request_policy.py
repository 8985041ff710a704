"""A request-conditioned policy: one network that takes the requested tolerance (the env config's
``tolerance``) as an input (agents/rl/artefacts/policy_files.py, ``request``), trained by DAgger
over several requests (agents/imitation/dagger.py, ``requests``)."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from agents.imitation.dagger import DaggerSettings
from agents.rl.artefacts.policy_files import (PolicyError, bind_request, load_policy,
                                              read_policy_meta, request_range)
from agents.rl.artefacts.shipped import shipped_path
from agents.rl.evaluation.evaluate import fixed_targets, rollout
from microconveyor_env.envs.core.versions import nominal, scene_config

ENV_ID = "MicroPositioner-v0"
REQUESTED = shipped_path("dagger_request", ENV_ID)


def _config(tolerance: float, env_id: str = ENV_ID):
    return nominal(scene_config(env_id, tolerance=tolerance))


def test_the_action_changes_with_the_request_and_the_range_is_recorded():
    assert request_range(read_policy_meta(REQUESTED)) == (5e-6, 50e-6)
    loose = load_policy(REQUESTED, _config(50e-6))
    tight = load_policy(REQUESTED, _config(5e-6))
    assert loose.request_m == 50e-6 and tight.request_m == 5e-6
    # an observation (the scene's, one entry fewer than the network's input), mid-range
    o = np.full(loose.actor.obs_dim - 1, 0.5, np.float32)
    a50, a5 = loose.act(o[None]), tight.act(o[None])
    assert not np.array_equal(a50, a5)
    # bound to a config, the same policy acts for that config's request
    np.testing.assert_array_equal(bind_request(loose, _config(5e-6)).act(o[None]), a5)


@pytest.mark.parametrize("tolerance", [2e-6, 100e-6])
def test_a_request_outside_the_trained_range_is_refused(tolerance):
    with pytest.raises(PolicyError, match=r"requested tolerances in \[5, 50\] µm"):
        load_policy(REQUESTED, _config(tolerance))
    pol = load_policy(REQUESTED)
    with pytest.raises(PolicyError, match=r"\[5, 50\] µm"):
        rollout(pol, np.array([3e-3]), _config(tolerance))


def test_a_policy_without_a_request_acts_as_before_and_keeps_its_tolerance():
    plain = load_policy(shipped_path("dagger", ENV_ID))
    assert plain.request_m is None and bind_request(plain, _config(10e-6)) is plain
    # another tolerance: refused, naming what does take a request
    with pytest.raises(PolicyError, match="does not take the requested tolerance as an input"):
        load_policy(shipped_path("dagger", ENV_ID), _config(10e-6))


def test_a_malformed_request_is_refused(tmp_path):
    folder = tmp_path / "p"
    shutil.copytree(REQUESTED, folder)
    meta = json.loads((folder / "metadata.json").read_text())
    meta["request"]["tolerance_m"] = [50e-6, 5e-6]
    (folder / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyError, match="request must be"):
        load_policy(folder)


def test_the_settings_check_the_requests():
    s = DaggerSettings(requests=[5e-6, 50e-6])
    assert s.requests == (5e-6, 50e-6)
    for bad in ([50e-6, 5e-6], [0.0], [5e-6, 5e-6], []):
        with pytest.raises(ValueError, match="requests"):
            DaggerSettings(requests=bad)


def test_a_tighter_request_never_gives_a_looser_median_error():
    pol = load_policy(REQUESTED)
    targets = fixed_targets(_config(50e-6), 8, 7)
    med = [float(np.median(np.abs(rollout(pol, targets, _config(t), seed=7)["error_m"])))
           for t in (50e-6, 20e-6, 10e-6, 5e-6)]
    assert all(b <= a for a, b in zip(med, med[1:], strict=False)), med
    assert med[-1] < med[0]


# the goal of a request-conditioned positioner under its recipe's randomisation (sigma 3e-3,
# friction and mass factors in [0.95, 1.05]) on 1,000 held-out targets: docs/figures/
# request_seeds.json holds the figures of the three training seeds, the shipped one among them
FIGURES = Path(__file__).resolve().parents[2] / "docs" / "figures" / "request_seeds.json"
# the IQM over the three seeds measured 96.6 % within ±10 µm at a request of 10 µm (the goal:
# 90 %) and 97.8 % within ±50 µm at 50 µm (the goal, 99 %, not reached: the rest detach)
LEVEL_10UM, LEVEL_50UM = 0.95, 0.97


@pytest.mark.slow   # 2 x 1,000 episodes of the shipped policy, then the stored seeds' figures
def test_the_shipped_request_policy_reproduces_its_seed_and_holds_the_request():
    from microconveyor_env.envs.core.versions import scene_config as make

    data = json.loads(FIGURES.read_text())["scenes"][ENV_ID]
    meta = read_policy_meta(REQUESTED)
    seed = data["seeds"][str(meta["seed"])]["evaluations"]
    for key, t in (("randomised/50", 50e-6), ("randomised/10", 10e-6)):
        cfg = make(ENV_ID, **{**meta["env_kwargs"], "tolerance": t})
        res = rollout(load_policy(REQUESTED, cfg), fixed_targets(cfg, 1000, 1), cfg, seed=1)
        rest = res["outcome"] == "rest"
        now = float(np.mean(rest & (np.abs(res["error_m"]) <= t)))
        assert abs(now - seed[key]["success_rate"]) <= 0.002, (key, now)
    iqm = data["iqm"]
    # levels the three seeds hold (IQM): see the figures for the goal and what they reach
    assert iqm["randomised/10"]["success_rate_10um"]["iqm"] >= LEVEL_10UM
    assert iqm["randomised/50"]["success_rate_50um"]["iqm"] >= LEVEL_50UM


@pytest.mark.slow   # a two-round DAgger run: a few seconds
def test_a_short_request_dagger_run_spreads_its_episodes_and_loads_for_each_request(tmp_path):
    from agents.imitation.dagger import dagger

    s = DaggerSettings(rounds=2, episodes=4, epochs=2, frequencies=5, strokes=2, margin=2,
                       requests=(10e-6, 50e-6))
    meta = dagger(tmp_path / "p", s, progress=lambda line: None)
    assert meta["request"] == {"tolerance_m": [10e-6, 50e-6], "feature": "log_ratio",
                               "reference_m": 50e-6}
    assert [(r["tolerance_m"], r["episodes"]) for r in meta["rounds"][0]["per_request"]] == [
        (10e-6, 2), (50e-6, 2)]
    assert meta["expert"]["slack_m"] == {"1e-05": 5e-6, "5e-05": 5e-6}
    pol = load_policy(tmp_path / "p", _config(10e-6))
    assert pol.request_m == 10e-6 and pol.actor.obs_dim == len(
        json.loads((tmp_path / "p" / "normalization.json").read_text())["obs_rms"]["mean"])
