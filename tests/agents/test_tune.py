"""Tuning on a shared Optuna storage and multi-seed training in worker processes (issue 23,
item 5): two local workers share one SQLite study and both run trials, another command joins
the same study, the best trial comes out as a config entry that trains as the trial did, a
periodic evaluation can stop a run (pruning), seeds train in two workers and aggregate."""
import json

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("optuna")

from agents.rl.artefacts import checkpoint  # noqa: E402
from agents.rl.training import hyperparams  # noqa: E402
from agents.rl.tuning import space as tune_space  # noqa: E402
from agents.rl.training.parallel import train_seeds  # noqa: E402
from agents.rl.training.settings import TrainSettings  # noqa: E402
from agents.rl.tuning.settings import TuneSettings  # noqa: E402
from agents.rl.tuning.study import summary  # noqa: E402
from agents.rl.tuning.tune import tune  # noqa: E402
from agents.rl.tuning.workers import shares  # noqa: E402

ENV = "MicroConveyor-v0"   # v0 for speed: the machinery is the same on v1
TINY = {"n_envs": 8, "n_steps": 32, "batch_size": 64, "n_epochs": 2}
BUDGET = {"eval_freq": 1024, "eval_targets": 5}


@pytest.mark.slow   # ~17 s; one storage opened by several commands at once: test_tune_workers.py
def test_two_workers_share_one_sqlite_study_and_the_best_is_a_config_entry(tmp_path):
    out = tmp_path / "tune"
    res = tune(TuneSettings(out=out, n_trials=4, workers=2, env_id=ENV, trial_steps=2048,
                            fixed={**TINY, "net_width": 64}, **BUDGET))
    assert res["storage"] == f"sqlite:///{out / 'optuna.db'}"
    assert res["states"] == {"complete": 4}
    mine: dict = {}
    for row in res["this_run"]:
        mine[row["worker"]] = mine.get(row["worker"], 0) + 1
    assert sorted(mine.values()) == [2, 2], mine  # two processes, two trials each
    assert res["workers"] == mine

    # another command on the same storage (another machine would do the same) adds its trial
    again = tune(TuneSettings(out=out, n_trials=1, workers=1, env_id=ENV, trial_steps=2048,
                              fixed={**TINY, "net_width": 64}, **BUDGET))
    assert again["trials"] == 5 and len(again["workers"]) == 3
    assert summary(again["storage"])["trials"] == 5

    not_comparable = "with eval_targets=5, trial_steps=2048, this command with eval_targets=6"
    with pytest.raises(ValueError, match=not_comparable):
        tune(TuneSettings(out=out, n_trials=1, env_id=ENV, trial_steps=4096, eval_freq=1024,
                          eval_targets=6))

    best = again["best"]
    assert best["value"] == max(r["value"] for r in res["this_run"] + again["this_run"])
    hp = hyperparams.load(again["best_file"], ENV)          # rl-zoo3 format, loads as data
    trained = json.loads((out / "microconveyor-ppo" / f"trial-{best['number']:04d}" /
                          "metadata.json").read_text())["hyperparams"]
    assert hyperparams.changed_keys(trained, hp) == []      # the entry is what the trial trained
    assert hp["policy_kwargs"]["net_arch"] == {"pi": [64, 64], "vf": [64, 64]}
    assert hp["normalize"]["gamma"] == hp["gamma"] == best["params"]["gamma"]


def test_an_evaluation_hook_stops_the_run_and_frees_the_folder(tmp_path):
    from agents.rl.training.train import train

    class Prune(Exception):
        pass

    seen = []

    def on_eval(res):
        seen.append(res["steps"])
        raise Prune

    with pytest.raises(Prune):
        train(tmp_path / "run", TrainSettings(steps=4096, env_id=ENV, overrides=TINY,
                                              progress_bar=False, tensorboard=False, **BUDGET),
                                              on_eval=on_eval)
    assert seen == [1024]
    assert len((tmp_path / "run" / "evaluations.jsonl").read_text().splitlines()) == 1
    assert not (tmp_path / "run" / "metadata.json").exists()
    with checkpoint.folder_lock(tmp_path / "run"):   # the lock went with the run
        pass


def test_a_trial_below_the_median_is_pruned_at_its_periodic_evaluation(tmp_path):
    import optuna

    from agents.rl.tuning.workers import _objective

    class Trial:  # what the objective uses of optuna.Trial; the pruner says "prune"
        number, attrs, reports = 7, {}, []

        def set_user_attr(self, k, v):
            self.attrs[k] = v

        def report(self, value, step):
            self.reports.append((step, value))

        def should_prune(self):
            return True

    job = {"out": str(tmp_path), "study_name": "s", "env_id": ENV, "env_kwargs": None,
           "conf_file": None, "trial_steps": 4096, "trial_minutes": None, "eval_seed": 1,
           "seed": 0, "fixed": {**TINY, "n_envs": 24, "net_width": 64, "learning_rate": 3e-4,
                                "log_std_init": -1.0, "gamma": 0.99}, **BUDGET}
    trial = Trial()
    with pytest.raises(optuna.TrialPruned):
        _objective(job, "here")(trial)
    # reported at the nominal step, though the run evaluated at 1,032 (43 x 24 envs): trials of
    # other rollout sizes are compared with it at equal steps
    assert [step for step, _ in trial.reports] == [1024] and trial.attrs["pruned_at"] == 1024
    run = tmp_path / "s" / "trial-0007"
    evals = [json.loads(line) for line in (run / "evaluations.jsonl").read_text().splitlines()]
    assert [e["steps"] for e in evals] == [1032]
    assert trial.attrs["worker"] == "here" and trial.attrs["run"] == str(run)


@pytest.mark.slow   # ~10 s of two worker processes training
def test_train_seeds_in_two_workers_aggregate_and_finished_seeds_are_reused(tmp_path):
    kw = {"env_id": ENV, "steps": 2048, "overrides": TINY, "tensorboard": False, **BUDGET}
    res = train_seeds(tmp_path, [0, 1], TrainSettings(**kw), workers=2)
    assert [r["status"] for r in res["runs"]] == ["trained", "trained"]
    assert [r["seed"] for r in res["runs"]] == [0, 1]
    agg = res["aggregate"]
    assert agg["runs"] == [str(tmp_path / "seed-0"), str(tmp_path / "seed-1")]
    assert len(agg["success_rate_50um"]["per_seed"]) == 2
    seeds = [json.loads((tmp_path / f"seed-{s}" / "metadata.json").read_text())["seed"]
             for s in (0, 1)]
    assert seeds == [0, 1]
    # run again (a killed command, or a second machine's share): finished seeds are kept
    res2 = train_seeds(tmp_path, [0, 1], TrainSettings(**kw), workers=2)
    assert [r["status"] for r in res2["runs"]] == ["done earlier", "done earlier"]
    assert res2["aggregate"]["median_abs_error_m"] == agg["median_abs_error_m"]
    with pytest.raises(ValueError, match="distinct"):
        train_seeds(tmp_path, [0, 0], TrainSettings(**kw))


def test_search_space_fixed_keys_and_config_text(tmp_path):
    with pytest.raises(ValueError, match="cannot fix clip_range"):
        tune_space.check_fixed({"clip_range": 0.1})
    for key, bad in (("n_envs", 0), ("n_steps", 8.0), ("gamma", 1.5), ("learning_rate", "lin_x"),
                     ("learning_rate", -1e-3), ("log_std_init", float("nan")), ("n_epochs", True)):
        with pytest.raises(ValueError, match=f"{key} must be"):
            tune_space.check_fixed({key: bad})
    assert tune_space.check_fixed({"learning_rate": "lin_3e-4", "gamma": 1, "n_envs": 8})
    assert shares(5, 2) == [3, 2] and shares(1, 3) == [1]
    import torch.nn as nn

    hp = {"n_envs": 64, "learning_rate": "lin_3e-4", "env_kwargs": {"num_threads": 1},
          "policy_kwargs": {"net_arch": {"pi": [8], "vf": [8]}, "activation_fn": nn.Tanh,
                            "log_std_init": -1.0},
          "normalize": {"norm_obs": True, "gamma": 0.99}}
    text = tune_space.config_yaml(ENV, hp, "a note\nover two lines")
    assert text.startswith("# a note\n# over two lines\n")
    (tmp_path / "c.yml").write_text(text)
    assert hyperparams.load(str(tmp_path / "c.yml"), ENV) == hp


def test_a_storage_that_cannot_be_opened_is_one_error_without_its_password(tmp_path):
    urls = ("postgresql://tuner:s3cret@127.0.0.1:1/optuna", "nodb://x",
            "sqlite:////no/such/dir/x.db")
    for url in urls:
        with pytest.raises(ValueError) as err:
            tune(TuneSettings(out=tmp_path, n_trials=1, env_id=ENV, storage=url))
        msg = str(err.value)
        assert msg.startswith(("the storage ", "cannot open the Optuna storage ")), msg
        assert "s3cret" not in msg
        if url.startswith("postgresql"):
            assert "postgresql://tuner:***@127.0.0.1:1/optuna" in msg
            try:
                import psycopg  # noqa: F401
            except ImportError:
                assert "pip install 'psycopg[binary]'" in msg


def test_a_written_config_keeps_package_keys_out_of_the_rl_zoo3_entry(tmp_path):
    """best.yml on the v1 base: the rl-zoo3 entry holds only keys rl-zoo3 knows (the run
    phases go to the package's section), and loading it gives back every hyperparameter."""
    import yaml

    from agents.rl.training import hyperparams
    from agents.rl.tuning.space import config_yaml

    hp = hyperparams.load(None, "MicroConveyor-v1")
    assert set(hyperparams.PACKAGE_KEYS) & set(hp)          # the v1 recipe has run phases
    path = tmp_path / "best.yml"
    path.write_text(config_yaml("MicroConveyor-v1", hp, "a note"))
    doc = yaml.safe_load(path.read_text())
    assert not set(hyperparams.PACKAGE_KEYS) & set(doc["MicroConveyor-v1"])
    assert set(doc[hyperparams.PACKAGE_SECTION]["MicroConveyor-v1"]) <= set(
        hyperparams.PACKAGE_KEYS)
    assert hyperparams.load(str(path), "MicroConveyor-v1") == hp
