"""The agents package: PPO end to end (train, save, load, resume), the shipped policy, the
evaluate command's errors, the reach study and the demo."""
import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.training import hyperparams  # noqa: E402
from agents.rl.evaluation.evaluate import PolicyError, evaluate, load_policy  # noqa: E402
from agents.experiments.reach import reach_study, widest_robust_range  # noqa: E402
from agents.rl.training.settings import TrainSettings  # noqa: E402
from agents.rl.training.train import train  # noqa: E402
from support.cli import run_cli  # noqa: E402

SMALL = {"n_envs": 16, "n_steps": 32, "batch_size": 256, "n_epochs": 1}


def run(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def test_ppo_config_is_rl_zoo_format():
    hp = hyperparams.load()
    assert hp["n_steps"] * hp["n_envs"] <= 4096  # a short rollout
    assert hp["normalize"]["norm_obs"] and hp["policy_kwargs"]["net_arch"]
    kw = hyperparams.algo_kwargs(hp)
    assert "n_steps" in kw and "n_envs" not in kw
    if isinstance(hp["learning_rate"], str):  # rl-zoo3's lin_<value>
        assert kw["learning_rate"](1.0) == float(hp["learning_rate"][4:]) and kw["learning_rate"](0.0) == 0


@pytest.mark.slow   # ~17 s; PPO trained, saved, resumed and loaded in the default tier:
# test_recipe_options.py::test_raw_observations_train_save_resume_and_load, test_checkpoints.py
def test_ppo_trains_saves_loads_and_resumes(tmp_path):
    from agents.rl.artefacts.checkpoint import generations

    lines = []
    meta = train(tmp_path, TrainSettings(steps=1024, seed=1, overrides=SMALL, checkpoint_freq=512,
                                         eval_freq=512, eval_targets=8, progress_bar=False),
                                         log=lines.append)
    assert meta["steps"] >= 1024 and meta["wall_time_s"] > 0
    gens = generations(tmp_path)
    assert 1 <= len(gens) <= 2 and gens[0].name == f"gen-{meta['steps']:012d}"
    for name in ("model.zip", "normalization.json", "metadata.json"):
        assert (tmp_path / name).is_file() and (gens[0] / name).is_file()
    assert not list(tmp_path.glob("*.pkl")) and not list(tmp_path.rglob("*.pkl"))
    assert meta["files"]["model.zip"] and meta["format"] == 2
    assert list((tmp_path / "tb").iterdir())  # tensorboard logs
    evals = [json.loads(line) for line in (tmp_path / "evaluations.jsonl").read_text().splitlines()]
    assert len(evals) >= 2 and {"success_rate_50um", "success_rate_250um"} <= set(evals[0])
    assert any(x.startswith("eval: step") for x in lines)           # one line per evaluation
    assert any(x.startswith("checkpoint: step") for x in lines)     # and per checkpoint
    ckpt = json.loads((gens[0] / "metadata.json").read_text())["steps"]
    resumed = train(tmp_path, TrainSettings(steps=2048, seed=1, overrides=SMALL, resume=True,
                                            checkpoint_freq=512, eval_freq=0, eval_targets=8,
                                            progress_bar=False), log=lines.append)
    assert any(x.startswith(f"resume: from step {ckpt}") for x in lines)
    assert resumed["steps"] >= 2048 and resumed["steps"] - ckpt <= 2048 - ckpt + 512
    assert resumed["wall_time_s"] > meta["wall_time_s"]  # wall time carried over
    pol = load_policy(tmp_path)
    res = evaluate(pol, 8, seed=3)
    assert res["n_targets"] == 8 and 0 <= res["success_rate"] <= 1
    assert np.isfinite(res["median_abs_error_m"])


def test_schedules_run_out_with_the_wall_time_budget(tmp_path):
    """With --max-minutes the lin_ learning rate decays over whichever budget ends first."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from agents.rl.training.algos import algo_class
    BudgetPPO = algo_class("ppo")
    from microconveyor_env.envs import MicroConveyorEnv

    model = BudgetPPO("MlpPolicy", DummyVecEnv([MicroConveyorEnv]), n_steps=16, batch_size=16,
                      learning_rate=hyperparams.linear_schedule(1e-3), device="cpu")
    model._update_current_progress_remaining(10, 100)
    assert model._current_progress_remaining == pytest.approx(0.9)  # steps only
    model.budget_clock = lambda: 0.5                                  # half the wall time gone
    model._update_current_progress_remaining(10, 100)
    assert model._current_progress_remaining == pytest.approx(0.5)
    model.budget_clock = lambda: 1.2                                  # past the budget
    model._update_current_progress_remaining(10, 100)
    assert model._current_progress_remaining == 0.0
    model.save(tmp_path / "m.zip")                                    # the clock is not saved
    from agents.rl.artefacts.sb3_files import read_data

    assert "budget_clock" not in read_data(tmp_path / "m.zip")
    assert BudgetPPO.load(tmp_path / "m.zip", device="cpu").budget_clock is None


def test_evaluate_cli_on_the_shipped_policy():
    r = run("evaluate", "--targets", "20", "--seed", "5", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["n_targets"] == 20 and 0 <= out["success_rate"] <= 1
    assert out["median_abs_error_m"] >= 0


def test_evaluate_cli_missing_or_incompatible_policy(tmp_path):
    r = run("evaluate", "--policy", str(tmp_path / "nope"), "--json")
    assert r.returncode == 2 and "no policy at" in json.loads(r.stdout)["error"]
    assert len(r.stderr.strip().splitlines()) == 1
    (tmp_path / "junk.zip").write_bytes(b"not a zip")
    r = run("evaluate", "--policy", str(tmp_path / "junk.zip"), "--json")
    assert r.returncode == 2 and "not a stable-baselines3 model" in r.stdout
    import gymnasium as gym
    from stable_baselines3 import PPO

    PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64, batch_size=64).save(tmp_path / "pend")
    r = run("evaluate", "--policy", str(tmp_path / "pend.zip"), "--env", "MicroConveyor-v1",
            "--json")
    assert r.returncode == 2 and "trained for observations (3,)" in r.stdout, r.stdout
    assert len(r.stderr.strip().splitlines()) == 1
    with pytest.raises(PolicyError):
        load_policy(tmp_path / "pend.zip")


def test_reach_study_small():
    study = reach_study([0.5e-3, 4.5e-3], budget=300, robust_budget=0, n_noisy=20, seed=0)
    near, far = study["rows"]
    assert near["reachable"] and near["best_abs_error_m"] <= 50e-6
    assert not far["reachable"] and not far["robust"]
    assert len(near["schedule"]) == 5 and study["tolerance_m"] == 50e-6


def test_widest_robust_range():
    rows = [{"target_m": t, "robust": r} for t, r in
            [(1, True), (2, False), (3, True), (4, True), (5, True), (6, False)]]
    assert widest_robust_range(rows) == [3, 5]
    assert widest_robust_range([{"target_m": 1, "robust": False}]) is None


def fake_runs(tmp_path, curves=False):
    """Three run folders with final evaluations at 20/50/80 % (and, with ``curves``, two
    evaluations each in evaluations.jsonl)."""
    runs = []
    for i, rate in enumerate((0.2, 0.5, 0.8)):
        d = tmp_path / str(i)
        d.mkdir()
        ev = {"success_rate_50um": rate, "success_rate_100um": rate, "success_rate_250um": rate,
              "median_abs_error_m": 1e-5 * (i + 1)}
        (d / "metadata.json").write_text(json.dumps({"evaluation": ev}))
        if curves:
            rows = [{**ev, "steps": s, "wall_time_s": s / 1e3} for s in (1000, 2000)]
            (d / "evaluations.jsonl").write_text("\n".join(json.dumps(r) for r in rows) + "\n")
        runs.append(d)
    return runs


def test_seed_aggregation(tmp_path):
    from agents.rl.evaluation.seeds import aggregate, iqm

    assert iqm([0.0, 1.0, 2.0, 3.0]) == 1.5 and iqm([1.0, 2.0, 4.0]) == pytest.approx(7 / 3)
    out = aggregate(fake_runs(tmp_path), reps=200)
    lo, hi = out["success_rate_50um"]["ci95"]
    assert 0.2 - 1e-12 <= lo <= out["success_rate_50um"]["iqm"] <= hi <= 0.8 + 1e-12


def test_seeds_command_reports_curves_and_plots(tmp_path):
    fake_runs(tmp_path, curves=True)
    r = run("seeds", *(str(tmp_path / str(i)) for i in range(3)), "--plot",
            str(tmp_path / "curves.png"), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["success_rate_50um"]["per_seed"] == [0.2, 0.5, 0.8]
    assert out["curves"][str(tmp_path / "1")]["steps"] == [1000, 2000]
    assert (tmp_path / "curves.png").stat().st_size > 10_000
    r = run("seeds", *(str(tmp_path / str(i)) for i in range(3)))   # human: %, µm
    assert r.returncode == 0, r.stderr
    assert "success_rate_50um: IQM 50.0 %" in r.stdout and "per seed 20.0 %, 50.0 %, 80.0 %" \
        in r.stdout, r.stdout
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("median_abs_error:"))
    assert line.count("µm") == 6 and "e-0" not in line, line
    r = run("seeds", str(tmp_path / "nope"), "--json")
    assert r.returncode == 2 and "error" in json.loads(r.stdout)


def test_seeds_refuses_runs_of_different_configs(tmp_path):
    from agents.rl.evaluation.seeds import aggregate

    runs = fake_runs(tmp_path)
    base = {"env_id": "MicroConveyor-v1", "env_kwargs": {"num_threads": 1}, "algo": "ppo",
            "hyperparams": {"gamma": 0.99, "n_envs": 64}}
    for i, r in enumerate(runs):
        meta = json.loads((r / "metadata.json").read_text())
        (r / "metadata.json").write_text(json.dumps({**meta, **base, "seed": i}))
    assert aggregate(runs)["success_rate_50um"]["per_seed"] == [0.2, 0.5, 0.8]  # seeds differ: fine
    meta = json.loads((runs[2] / "metadata.json").read_text())
    meta["env_kwargs"] = {"num_threads": 1, "n_actuators": 10}
    meta["hyperparams"] = {"gamma": 0.9, "n_envs": 64}
    (runs[2] / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="differs from .* in env_kwargs, hyperparams.gamma"):
        aggregate(runs)


def test_iqm_interval_over_seeds():
    import math

    from agents.rl.evaluation.seeds import iqm, iqm_interval

    vals = [0.6, 0.7, 0.8, 0.9, 0.95]
    out = iqm_interval(vals, seed=3)
    assert out["per_seed"] == vals and out["iqm"] == iqm(vals)
    lo, hi = out["ci95"]
    assert 0.6 <= lo < out["iqm"] < hi <= 0.95
    assert iqm_interval(vals, seed=3) == out                        # seeded: the same interval
    assert iqm_interval([0.5, 0.5, 0.5])["ci95"] == [0.5, 0.5]      # equal scores: no spread
    assert iqm_interval([0.7])["ci95"] == [0.7, 0.7]
    assert all(math.isnan(x) for x in iqm_interval([])["ci95"])
