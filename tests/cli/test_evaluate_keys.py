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
        # the time to rest beside the error [s], and success at the tight radii
        assert {"median_placement_time_s", "p90_placement_time_s", "success_rate_5um",
                "success_rate_10um", "success_rate_20um"} <= set(res)
        if res["rest_rate"] > 0:
            assert 0 < res["median_placement_time_s"] <= res["p90_placement_time_s"] < 1
    assert "median_error_m" not in plane and "target_box_m" in plane


@pytest.mark.parametrize("env_id", ["MicroConveyor-v1", "MicroConveyor2D-v0"])
def test_evaluates_human_output_shows_the_placement_time_in_ms(capsys, env_id):
    capsys.readouterr()
    assert main(["evaluate", "--env", env_id, "--targets", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for key in ("median_placement_time", "p90_placement_time"):
        shown = [line.split() for line in lines if line.split()[:1] == [key]]
        assert len(shown) == 1 and shown[0][-1] == "ms", lines


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


@pytest.mark.parametrize("env_id", ["MicroConveyor-v1", "MicroPositioner-v0"])
def test_evaluate_at_distances_gives_a_row_per_distance(capsys, env_id):
    """``--at``: per-distance targets over d ± 0.1 mm on the line and the positioner; each row's
    figures are its own targets', the overall figures every target's."""
    capsys.readouterr()
    assert main(["evaluate", "--env", env_id, "--at", "1e-3,9e-3", "--per-distance", "3",
                 "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert [r["distance_m"] for r in res["per_distance"]] == [1e-3, 9e-3]
    assert res["n_targets"] == 6 and res["targets_per_distance"] == 3
    for r in res["per_distance"]:
        assert r["n_targets"] == 3
        assert r["targets_m"] == pytest.approx(
            [r["distance_m"] - 1e-4, r["distance_m"], r["distance_m"] + 1e-4], abs=1e-12)
        assert 0 <= r["success_rate"] <= 1 and r["median_abs_error_m"] <= r["p90_abs_error_m"]
        assert r["median_placement_time_s"] <= r["p90_placement_time_s"]   # its own episodes'
    assert res["success_rate"] == pytest.approx(
        sum(r["success_rate"] for r in res["per_distance"]) / 2)
    assert main(["evaluate", "--env", env_id, "--at", "1e-3,9e-3", "--per-distance", "3"]) == 0
    text = capsys.readouterr().out
    assert "1 mm" in text and "9 mm" in text and "µm" in text and "all" in text
    assert "median time" in text and "p90 time" in text and " ms " in text


def test_distance_targets_stay_in_the_range():
    from agents.rl.evaluation.evaluate import distance_targets
    from microconveyor_env.envs import env_config

    cfg = env_config("MicroConveyor-v1")
    lo, hi = cfg.target_range
    grid = distance_targets(cfg, [lo, hi], 3)
    assert grid.shape == (2, 3) and grid.min() == lo and grid.max() == hi
    assert distance_targets(cfg, [5e-3], 1).tolist() == [[5e-3]]


@pytest.mark.parametrize("argv, words", [
    (["--at", "20e-3"], "target range"),
    (["--at", "1e-3", "--targets", "5"], "give one of them"),
    (["--per-distance", "3"], "goes with --at"),
    (["--env", "MicroConveyor2D-v1", "--at", "1e-3"], "points of its grid box"),
])
def test_evaluate_at_refuses_in_one_line(capsys, argv, words):
    capsys.readouterr()
    assert main(["evaluate", *argv]) != 0
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1
