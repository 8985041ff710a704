"""``evaluate --json``: one JSON contract on every scene, the line and the plane: the same keys
(the median error is ``median_abs_error_m`` on both), apart from the target set's
``target_range_m`` (line) or ``target_box_m`` (plane); the stored records keep their names."""
import json

import pytest

from microconveyor_env.cli import main

pytest.importorskip("stable_baselines3")

SCENE_KEYS = {"target_range_m", "target_box_m"}


def _evaluate(capsys, env_id):
    capsys.readouterr()
    assert main(["evaluate", "--env", env_id, "--targets", "3", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_evaluate_has_the_same_keys_on_the_line_and_in_the_plane(capsys):
    line = {e: _evaluate(capsys, e) for e in ("MicroConveyor-v0", "MicroConveyor-v1")}
    plane = _evaluate(capsys, "MicroConveyor2D-v0")
    assert set(line["MicroConveyor-v0"]) == set(line["MicroConveyor-v1"])
    assert set(line["MicroConveyor-v0"]) - SCENE_KEYS == set(plane) - SCENE_KEYS
    for res in (*line.values(), plane):
        assert {"median_abs_error_m", "p90_abs_error_m", "success_rate", "success_rate_50um",
                "detach_rate", "rest_rate", "mean_firings", "tolerance_m", "n_targets"} <= set(res)
        assert res["median_abs_error_m"] <= res["p90_abs_error_m"]
        assert 0 <= res["success_rate_50um"] <= 1 and 1 <= res["mean_firings"]
    assert "median_error_m" not in plane and "target_box_m" in plane


def test_the_stored_plane_record_maps_onto_the_contract():
    """The shipped plane policy's metadata keeps plane_summary's names (median_error_m); the
    evaluate command's names are derived from them."""
    from agents.rl.evaluation.evaluate import from_plane_record as plane_evaluation
    from agents.rl.artefacts.shipped import shipped_path

    meta = json.loads((shipped_path("ppo", "MicroConveyor2D-v0") / "metadata.json").read_text())
    stored = meta["evaluation"]
    mapped = plane_evaluation(stored)
    assert mapped["median_abs_error_m"] == stored["median_error_m"]
    assert mapped["p90_abs_error_m"] == stored["p90_error_m"]


def test_evaluate_reports_the_env_kwargs_it_ran_with(capsys):
    """``env_kwargs`` are the kwargs of the env evaluated (the policy's own updated by
    ``--env-kwargs``); ``trained_env_kwargs`` the policy's own."""
    from agents.rl.artefacts.shipped import shipped_path

    policy = str(shipped_path("ppo_randomised", "MicroConveyor-v1"))
    capsys.readouterr()
    assert main(["evaluate", "--policy", policy, "--targets", "2", "--json",
                 "--env-kwargs", "action_noise:0.0"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["env_kwargs"]["action_noise"] == 0.0
    assert res["trained_env_kwargs"]["action_noise"] == 0.003
    assert res["env_kwargs"]["friction_factor_range"] == [0.95, 1.05]   # the rest: its own
    assert main(["evaluate", "--policy", policy, "--targets", "2", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["env_kwargs"] == res["trained_env_kwargs"]
    assert res["env_kwargs"]["action_noise"] == 0.003
