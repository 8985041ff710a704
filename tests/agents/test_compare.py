"""`microconveyor compare` on a tiny budget: every method reported, the charts written, and the
bookkeeping (budgets, crossover) consistent."""
import json
import subprocess
import sys

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("cma")

from agents.experiments.compare import crossover  # noqa: E402
from support.cli import run_cli  # noqa: E402


def test_crossover():
    assert crossover(100.0, 0.01, 1.01) == pytest.approx(100.0)   # 1 s saved per target
    assert crossover(100.0, 0.5, 0.4) is None                      # the search is cheaper


def test_compare_tiny_budget_writes_its_charts(tmp_path):
    out = tmp_path / "cmp"
    # in this process, the MPC's episodes too (they do not depend on the number of workers:
    # tests/agents/test_mpc.py::test_one_worker_or_two_give_the_same_episodes)
    r = run_cli("compare", "--targets", "2", "--env", "MicroConveyor-v0", "--budgets", "20,40",
                "--noise", "0,0.01", "--spread", "0,0.02", "--diagonal", "0.01:0.02",
                "--mpc-budgets", "20,10", "--mpc-prior", "shipped", "--repeats", "1",
                "--randomised-policy", "", "--workers", "1", "--plot", out / "compare.png",
                "--json")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    methods = [(row["method"], row.get("budget")) for row in res["rows"]]
    assert methods == [("ppo", None), ("mpc", None), ("mpc_ppo", None), ("random", None),
                       ("fixed_schedule", None), ("de", 20), ("de", 40), ("cmaes", 20),
                       ("cmaes", 40)]
    for row in res["rows"]:
        assert row["n_targets"] == 2 and 0 <= row["success_rate"] <= 1
        assert row["wall_s_per_target"] > 0
        assert {"median_placement_time_s", "p90_placement_time_s"} <= set(row)
        if "budget" in row:
            assert row["episodes_per_target"] <= row["budget"]
            reached = [e for e in row["episodes_to_tolerance"] if e is not None]
            assert all(0 < e <= row["budget"] for e in reached)
    mpc = res["rows"][1]
    # one first plan of 20 and at most 4 re-plans of 10 per target
    assert 10 <= mpc["episodes_per_target"] <= 20 + 4 * 10
    assert res["rows"][0]["train_wall_s"] > 0 and res["rows"][0]["train_steps"] > 0
    pert = res["perturbation"]
    assert set(pert) == {"ppo", "mpc", "mpc_ppo", "random", "fixed_schedule", "de_40_plan",
                         "cmaes_40_plan"}
    # seeded by the shipped PPO's plan on the (exact) model, MPC never ends farther than PPO
    seeded = res["rows"][2]
    assert seeded["prior"].endswith("ppo")
    for a, b in zip(seeded["abs_error_m"], res["rows"][0]["abs_error_m"], strict=True):
        assert a <= b + 1e-12
    assert [lvl["action_noise"] for lvl in pert["ppo"]["action_noise"]] == [0.0, 0.01]
    assert [lvl["spread"] for lvl in pert["ppo"]["spread"]] == [0.0, 0.02]
    assert [(lvl["action_noise"], lvl["spread"]) for lvl in pert["ppo"]["combined"]] == [
        (0.0, 0.0), (0.01, 0.02)]
    # the unperturbed level replays what the table reports for the same method and targets
    for name, row in (("ppo", res["rows"][0]), ("mpc", mpc)):
        assert pert[name]["action_noise"][0]["success_rate"] == row["success_rate"]
        assert pert[name]["spread"][0] == pert[name]["action_noise"][0]
    for name in ("compare_compute.png", "compare.png", "compare_perturbation.png",
                 "compare_ecdf.png"):
        assert (out / name).stat().st_size > 20_000
    assert not (out / "compare_grid.png").exists()  # only with --full
    assert json.loads((out / "compare.json").read_text())["targets_m"] == res["targets_m"]


def test_compare_full_grid_and_seed_iqm(tmp_path):
    """v1 (the default env), --quick shrunk further, the full grid and two 'seeds' (the shipped
    policy twice: their IQM is its own success, with a zero-width interval)."""
    from agents.rl.artefacts.shipped import require_shipped

    shipped = str(require_shipped("MicroConveyor-v1"))
    out = tmp_path / "cmp"
    r = run_cli("compare", "--quick", "--targets", "2", "--budgets", "20", "--mpc-budgets", "0",
                "--robust-mpc", "80,40", "--noise", "0.01", "--spread", "0.02", "--diagonal",
                "0.01:0.02", "--full", "--policy-seeds", shipped, shipped, "--workers", "1",
                "--plot", out / "c.png", "--json")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert res["env_id"] == "MicroConveyor-v1"
    assert [row["method"] for row in res["rows"]][:3] == ["ppo_refined", "ppo_randomised",
                                                          "mpc_robust"]
    grid = res["perturbation"]["ppo_refined"]["grid"]
    assert sorted((g["action_noise"], g["spread"]) for g in grid) == [
        (0.0, 0.0), (0.0, 0.02), (0.01, 0.0), (0.01, 0.02)]
    nominal = res["seeds"]["nominal"]
    assert nominal["iqm"] == res["rows"][0]["success_rate"]
    assert nominal["ci95"] == [nominal["iqm"]] * 2
    robust = res["rows"][2]
    assert robust["settings"]["identify"] and robust["settings"]["noise_copies"] == 8
    assert "friction and mass identified online" in r.stderr
    assert (out / "c_grid.png").stat().st_size > 20_000
    assert "full grid" in r.stderr


def test_seed_summary_and_episodes_to_tolerance():
    from agents.experiments.compare import episodes_to, seed_summary
    from agents.rl.evaluation.seeds import iqm

    values = [0.1, 0.5, 0.6, 0.7, 1.0]
    res = seed_summary(values)
    assert res["iqm"] == pytest.approx((0.5 + 0.6 + 0.7) / 3)  # trims 1 of 5 at each end
    assert res["iqm"] == iqm(values) and res["per_seed"] == values
    assert res["ci95"][0] < res["iqm"] < res["ci95"][1]
    assert seed_summary(values, seed=0) == res               # seeded
    assert seed_summary([0.4, 0.4])["ci95"] == [0.4, 0.4]    # no spread: a zero-width interval
    assert episodes_to([10, 20, 30], [None, 60e-6, 40e-6], 50e-6) == 30
    assert episodes_to([10, 20], [None, 1e-3], 50e-6) is None


@pytest.mark.parametrize("argv, message", [
    (["--methods", "pso"], "de, cmaes"), (["--diagonal", "0.01"], "SIGMA:R"),
    (["--diagonal=-1:0.1"], "SIGMA:R"), (["--mpc-budgets", "100"], "FIRST,REPLAN"),
    (["--mpc-budgets", "5,5"], ">= 10"), (["--robust-mpc", "x"], "FIRST,REPLAN"),
    (["--mpc-prior", "/nonexistent"], "no policy folder"), (["--workers", "0"], "workers")])
def test_compare_rejects_bad_arguments(argv, message):
    r = run_cli("compare", *argv, "--json")
    assert r.returncode == 2 and message in json.loads(r.stdout)["error"]


def test_the_console_script_refuses_a_bad_argument_with_status_2():
    """The refusals above in this process; one through the installed command's process."""
    r = subprocess.run([sys.executable, "-m", "microconveyor_env.cli", "compare", "--workers",
                        "0", "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "workers" in json.loads(r.stdout)["error"]
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_the_shipped_policy_is_the_ids_default_one():
    """On MicroConveyor-v1 the policy row and ``--mpc-prior shipped`` are its default shipped
    policy (ppo_refined), as in every other command, and are named after it (the stored
    figures' ``ppo`` and ``mpc_ppo`` are the shipped ``ppo``): in the rows, the text, the
    charts' labels and the docs' table."""
    import importlib.util
    from pathlib import Path

    from agents.cli.compare import _prior
    from agents.experiments.compare import compare
    from agents.experiments.compare_settings import CompareSettings
    from agents.experiments.compare_text import summary_table
    from agents.mpc import MPCSettings
    from agents.plots.compare import _label

    prior = _prior("shipped", "MicroConveyor-v1")
    assert prior.endswith("MicroConveyor-v1/ppo_refined")
    res = compare(CompareSettings(env_id="MicroConveyor-v1", n_targets=1, methods=("de",),
                                  budgets=(10,), randomised_policy="", mpc_prior=prior,
                                  mpc=MPCSettings(first_budget=10, replan_budget=10),
                                  mpc_workers=1, noise_ladder=(0.0,), spread_ladder=(0.0,),
                                  diagonal=(), progress=False))
    assert res["policy"].endswith("MicroConveyor-v1/ppo_refined")
    names = [row["method"] for row in res["rows"] if "budget" not in row]
    assert names == ["ppo_refined", "mpc", "mpc_ppo_refined", "random", "fixed_schedule"]
    assert res["rows"][0]["policy"] == res["policy"]
    assert res["rows"][2]["prior"] == prior
    assert set(res["perturbation"]) >= {"ppo_refined", "mpc_ppo_refined"}
    text = summary_table(res)
    assert "\nppo_refined " in text and "\nmpc_ppo_refined " in text
    assert "\nppo " not in text and "\nmpc_ppo " not in text
    assert _label("mpc_ppo_refined") == "MPC seeded by ppo_refined's plan"
    path = Path(__file__).resolve().parents[2] / "scripts" / "results_tables.py"
    spec = importlib.util.spec_from_file_location("_results_tables", path)
    assert spec is not None and spec.loader is not None
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    table = tables.compare_table(res)
    assert "| the shipped `ppo_refined` |" in table
    assert "| MPC seeded by `ppo_refined` |" in table


def test_a_rows_placement_time_is_of_the_parts_that_rested():
    """Each method's row carries the median and 90th percentile of its parts' time to rest [s]
    (a detached part never arrives), and the text tables show them in ms."""
    import numpy as np

    from agents.experiments.compare_rows import result_row
    from agents.experiments.compare_text import positioner_table

    res = {"error_m": [1e-6, -2e-6, 3e-3, 4e-6], "outcome": ["rest", "rest", "detached", "rest"],
           "time_s": [0.04, 0.05, 0.01, 0.06]}
    row = result_row("de", res, np.zeros(4), 50e-6, wall_s_per_target=0.1)
    assert row["median_placement_time_s"] == pytest.approx(0.05)
    assert row["p90_placement_time_s"] == pytest.approx(0.058)
    text = positioner_table({"rows": [row], "perturbation": {}, "plan_firings": 5})
    assert "p90 time" in text.splitlines()[0] and "50.0 ms" in text and "58.0 ms" in text


def test_a_policy_row_is_named_after_its_folder():
    from agents.experiments.compare_rows import policy_row_name, seeded_mpc_name

    assert policy_row_name({}, "agents/policies/MicroConveyor-v1/ppo_refined") == "ppo_refined"
    assert policy_row_name({"trained_by": "dagger"}, "/x/dagger") == "dagger"
    assert policy_row_name({}, "runs/my_run/") == "my_run"
    for taken in ("random", "fixed_schedule", "ppo_randomised", "mpc", "mpc_robust", "de",
                  "de_40", "cmaes_1000_plan"):   # another row's name: kept apart
        assert policy_row_name({}, f"runs/{taken}") == f"policy_{taken}"
    assert policy_row_name({}) == "ppo" and policy_row_name({"trained_by": "dagger"}) == "dagger"
    assert seeded_mpc_name("agents/policies/MicroConveyor-v1/ppo") == "mpc_ppo"
    assert seeded_mpc_name("runs/robust", ("mpc", "mpc_robust")) == "mpc_seeded_robust"
