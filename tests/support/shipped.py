"""Replaying a shipped policy's recorded evaluation, episode by episode, within the CPU tolerance
``tests/agents/test_shipped_policies.py`` derives (its module docstring)."""
import json

import numpy as np

from agents.rl.artefacts.policy_files import policy_scene
from agents.rl.artefacts.shipped import shipped_path
from agents.rl.evaluation.evaluate import (ADDED_FIGURES, TOLERANCES, fixed_targets, load_policy,
                                          placement_times, rollout, summarize)
from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.core.versions import nominal

EPISODE_TOL_M = 1e-6


def _config(meta: dict, which: str) -> EnvConfig:
    """The scene the policy was trained in (its env id and kwargs), with its randomisation
    ("trained") or without ("nominal")."""
    scene = policy_scene(meta)
    return scene if which == "trained" else nominal(scene)


def _successes(err: np.ndarray, outcome: np.ndarray, tol: float) -> np.ndarray:
    return (outcome == "rest") & (np.abs(err) <= tol)


def assert_reproduces(name: str, key: str, env_id: str = "MicroConveyor-v0") -> dict:
    """Re-run the evaluation ``key`` of shipped policy ``name`` of ``env_id`` and compare it,
    episode by episode, with the record in its ``episodes.json`` (tolerances: module
    docstring)."""
    pol = load_policy(shipped_path(name, env_id))
    meta = pol.metadata
    rec = json.loads((shipped_path(name, env_id) / "episodes.json").read_text())[key]
    cfg = _config(meta, rec["config"])
    targets = fixed_targets(cfg, meta[key]["n_targets"], rec["seed"])
    np.testing.assert_array_equal(targets, rec["target_m"])       # pure numpy RNG: exact
    res = rollout(pol, targets, cfg, seed=rec["seed"])
    err0, out0 = np.array(rec["error_m"]), np.array(rec["outcome"], dtype=object)
    np.testing.assert_array_equal(res["outcome"], out0)
    assert np.max(np.abs(res["error_m"] - err0)) <= EPISODE_TOL_M
    for tol in TOLERANCES:
        flips = _successes(res["error_m"], res["outcome"], tol) != _successes(err0, out0, tol)
        assert np.all(np.abs(np.abs(err0[flips]) - tol) <= EPISODE_TOL_M), (tol, err0[flips])
    now = summarize(res, cfg.tolerance)
    assert abs(now["median_abs_error_m"] - meta[key]["median_abs_error_m"]) <= EPISODE_TOL_M
    # the metadata's summary is the summary of the recorded episodes (the record is consistent);
    # a record made before a figure of ADDED_FIGURES was reported lacks that figure alone
    stored = summarize({"error_m": err0, "outcome": out0}, cfg.tolerance)
    if "time_s" in rec:
        stored.update(placement_times(rec["time_s"], out0))
    for k, v in stored.items():
        if k in ADDED_FIGURES and k not in meta[key]:
            continue
        assert meta[key][k] == v, k
    return now


