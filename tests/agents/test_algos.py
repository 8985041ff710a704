"""`train --algo`: SAC and TQC (with HER on the goal-conditioned env, and on the Box env) train,
save, resume with the whole run's budget, and evaluate through the data-only loader."""
import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.training import hyperparams  # noqa: E402

TINY = {"n_envs": 2, "learning_starts": 50, "batch_size": 32, "buffer_size": 5000,
        "policy_kwargs": {"net_arch": [16, 16]}}


def _train(out, algo, env_id, steps, **kw):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    log = kw.pop("log", None)
    return train(out, TrainSettings(steps=steps, seed=0, algo=algo, env_id=env_id, overrides=TINY,
                                    checkpoint_freq=100, eval_freq=0, eval_targets=5,
                                    progress_bar=False, tensorboard=False, **kw), log=log)


@pytest.mark.parametrize("algo,env_id", [("sac", "MicroConveyorGoal-v1"),
                                         ("tqc", "MicroConveyorGoal-v1"),
                                         ("sac", "MicroConveyor-v1")])
def test_off_policy_trains_resumes_and_evaluates(tmp_path, algo, env_id):
    if algo == "tqc":
        pytest.importorskip("sb3_contrib")
    from agents.rl.evaluation.evaluate import evaluate, load_policy

    logs = []
    meta = _train(tmp_path, algo, env_id, 200)
    assert meta["algo"] == algo and meta["env_id"] == env_id and meta["steps"] == 200
    meta = _train(tmp_path, algo, env_id, 300, resume=True, log=logs.append)
    assert meta["steps"] == 300  # the budget counts the whole run: 100 more, not 300
    assert any("continuing at step 200 of 300" in line for line in logs)
    assert any("replay buffer is not checkpointed" in line for line in logs)
    with pytest.raises(ValueError, match="nothing to resume"):
        _train(tmp_path, algo, env_id, 300, resume=True)

    pol = load_policy(tmp_path)  # data only: the HER buffer class is replaced, not unpickled
    assert pol.env_id == env_id and pol.config.progress_scale == 1e-3
    res = evaluate(pol, 8, seed=1)
    assert res["n_targets"] == 8 and 0 <= res["success_rate"] <= 1
    # a policy trained with another reward scale is evaluated in v1's default scene
    from microconveyor_env.envs import env_config

    load_policy(tmp_path, env_config("MicroConveyor-v1"))
    # the live model and the loaded one act alike on the Box env's observations
    from microconveyor_env.envs import MicroConveyorVectorEnv

    obs, _ = MicroConveyorVectorEnv(4, config=pol.config).reset(seed=3)
    assert np.all(np.abs(pol.act(obs)) <= 1)


def test_goal_observations_of_the_box_env_match_the_goal_env():
    from microconveyor_env.envs import MicroConveyorEnv
    from microconveyor_env.envs.line.goal import MicroConveyorGoalEnv, goal_observations

    box, goal = MicroConveyorEnv(), MicroConveyorGoalEnv()
    cfg = {"seed": 5, "options": {"target": 7.3e-3}}
    ob, og = box.reset(**cfg)[0], goal.reset(**cfg)[0]
    for a in ([0.3, 0.2, -0.9], [0.5, 0.9, -0.95], [0.1, 0.0, -1.0]):
        conv = goal_observations(ob)
        for key in og:
            np.testing.assert_allclose(conv[key][0], og[key], rtol=0, atol=2e-7)
        ob, _, term, trunc, _ = box.step(np.array(a, np.float32))
        og, *_ = goal.step(np.array(a, np.float32))
        if term or trunc:
            break


def test_configs_name_each_algorithms_env_ids():
    for algo in ("sac", "tqc"):
        for env_id in ("MicroConveyorGoal-v1", "MicroConveyor-v1"):
            hp = hyperparams.load(None, env_id, algo)
            kw = hyperparams.algo_kwargs(hp)
            if env_id.startswith("MicroConveyorGoal"):
                from stable_baselines3 import HerReplayBuffer

                assert kw["replay_buffer_class"] is HerReplayBuffer
                assert kw["replay_buffer_kwargs"]["copy_info_dict"] is True
    with pytest.raises(ValueError, match="no shipped config for 'a2c'"):
        hyperparams.load(None, "MicroConveyor-v1", "a2c")
    with pytest.raises(ValueError, match="replay_buffer_class 'Evil'"):
        hyperparams.algo_kwargs({"replay_buffer_class": "Evil"})


def test_cli_train_algo_and_evaluate(tmp_path):
    from microconveyor_env.cli import main

    conf = tmp_path / "sac.yml"
    conf.write_text("MicroConveyorGoal-v1:\n  env_kwargs: {progress_scale: 1.0e-3}\n"
                    "  n_envs: 2\n  policy: MultiInputPolicy\n  replay_buffer_class: HerReplayBuffer\n"
                    "  replay_buffer_kwargs: \"dict(copy_info_dict=True)\"\n  learning_starts: 50\n"
                    "  batch_size: 32\n  buffer_size: 5000\n"
                    "  policy_kwargs: \"dict(net_arch=[16])\"\n")
    out = tmp_path / "run"
    assert main(["train", "--algo", "sac", "--env", "MicroConveyorGoal-v1", "--conf-file",
                 str(conf), "--steps", "120", "--out", str(out), "--eval-freq", "100",
                 "--eval-targets", "4", "--no-progress", "--json"]) in (0, None)
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["algo"] == "sac"
    assert len((out / "evaluations.jsonl").read_text().splitlines()) >= 2


def test_goal_env_with_normalised_observations_is_refused_before_training(tmp_path):
    """It used to train to the end and fail at the first save (Dict observations have no
    statistics file); now it is refused before a step is taken."""
    import time

    from agents.rl.training.settings import TrainSettings

    from agents.rl.training.train import train

    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="normalize: MicroConveyorGoal-v1 has Dict observations"):
        train(tmp_path / "run", TrainSettings(steps=2048, env_id="MicroConveyorGoal-v1", algo="sac",
                                              overrides={"normalize": True, "learning_starts": 100},
                                              eval_freq=0, eval_targets=0, checkpoint_freq=1024,
                                              progress_bar=False, tensorboard=False))
    assert time.perf_counter() - t0 < 30
    assert not (tmp_path / "run" / "checkpoints").exists()
