"""`microconveyor compare` on a tiny budget: every method reported, the charts written, and the
bookkeeping (budgets, crossover) consistent."""
import json
import subprocess
import sys

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("cma")

from agents.experiments.compare import crossover  # noqa: E402


def test_crossover():
    assert crossover(100.0, 0.01, 1.01) == pytest.approx(100.0)   # 1 s saved per target
    assert crossover(100.0, 0.5, 0.4) is None                      # the search is cheaper


def test_compare_tiny_budget_writes_its_charts(tmp_path):
    out = tmp_path / "cmp"
    r = subprocess.run([sys.executable, "-m", "microconveyor_env.cli", "compare", "--targets", "2",
                        "--budgets", "20,40", "--noise", "0,0.01", "--spread", "0,0.02",
                        "--repeats", "1", "--randomised-policy", "", "--plot",
                        str(out / "compare.png"), "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    methods = [(row["method"], row.get("budget")) for row in res["rows"]]
    assert methods == [("ppo", None), ("random", None), ("fixed_schedule", None), ("de", 20),
                       ("de", 40), ("cmaes", 20), ("cmaes", 40)]
    for row in res["rows"]:
        assert row["n_targets"] == 2 and 0 <= row["success_rate"] <= 1
        assert row["wall_s_per_target"] > 0
        if "budget" in row:
            assert row["episodes_per_target"] <= row["budget"]
    assert res["rows"][0]["train_wall_s"] > 0 and res["rows"][0]["train_steps"] > 0
    pert = res["perturbation"]
    assert set(pert) == {"ppo", "de_40_plan", "cmaes_40_plan"}
    assert [lvl["action_noise"] for lvl in pert["ppo"]["action_noise"]] == [0.0, 0.01]
    assert [lvl["spread"] for lvl in pert["ppo"]["spread"]] == [0.0, 0.02]
    # the unperturbed level replays what the table reports for the same policy and targets
    assert pert["ppo"]["action_noise"][0]["success_rate"] == res["rows"][0]["success_rate"]
    for name in ("compare_compute.png", "compare.png", "compare_perturbation.png"):
        assert (out / name).stat().st_size > 20_000
    assert json.loads((out / "compare.json").read_text())["targets_m"] == res["targets_m"]


def test_compare_rejects_bad_arguments():
    r = subprocess.run([sys.executable, "-m", "microconveyor_env.cli", "compare", "--methods",
                        "pso", "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "de, cmaes" in json.loads(r.stdout)["error"]
