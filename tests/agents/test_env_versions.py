"""Agents on a chosen env version: --env / --env-kwargs through train -> evaluate, and a policy
evaluated on another scene is refused."""
import argparse
import json

import pytest

pytest.importorskip("stable_baselines3")

from agents.cli.args import env_kwarg  # noqa: E402
from agents.rl.artefacts.policy_files import PolicyError, load_policy  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from microconveyor_env.envs import env_config  # noqa: E402
from support.cli import run_cli  # noqa: E402

TINY = """MicroConveyor-v1:
  env_kwargs: {num_threads: 1}
  n_envs: 4
  n_timesteps: 64
  policy: 'MlpPolicy'
  normalize: "dict(norm_obs=True, norm_reward=True, gamma=0.99)"
  n_steps: 16
  batch_size: 32
  n_epochs: 1
  policy_kwargs: "dict(net_arch=[16])"
"""


def _cli(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def test_env_kwargs_are_parsed_as_data():
    assert env_kwarg("n_actuators:7") == ("n_actuators", 7)
    assert env_kwarg("target_range:(0.5e-3, 6e-3)") == ("target_range", [0.5e-3, 6e-3])
    assert env_kwarg("preset:conveyor") == ("preset", "conveyor")
    assert env_kwarg("stop_at_target:false") == ("stop_at_target", False)
    assert env_kwarg("progress_scale:null") == ("progress_scale", None)
    assert env_kwarg("preset:__import__('os').system('true')")[1] == \
        "__import__('os').system('true')"   # a string, never evaluated
    for bad in ("n_actuators", ":3", "a b:1", "x:"):
        with pytest.raises(argparse.ArgumentTypeError, match="KEY:VALUE"):
            env_kwarg(bad)


def test_train_evaluate_round_trip_and_scene_refusals(tmp_path):
    conf = tmp_path / "ppo.yml"
    conf.write_text(TINY)
    run = tmp_path / "run"
    r = _cli("train", "--env", "MicroConveyor-v1", "--env-kwargs", "n_actuators:3",
             "target_range:(1e-3, 4e-3)", "--conf-file", str(conf), "--out", str(run),
             "--eval-freq", "0", "--eval-targets", "4", "--no-progress", "--json")
    assert r.returncode == 0, r.stderr
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["env_id"] == "MicroConveyor-v1"
    assert meta["env_kwargs"] == {"num_threads": 1, "n_actuators": 3,
                                  "target_range": [1e-3, 4e-3]}
    # the policy brings its scene: evaluated on it without being told
    pol = load_policy(run)
    assert pol.env_id == "MicroConveyor-v1"
    assert pol.config == env_config("MicroConveyor-v1", n_actuators=3, target_range=(1e-3, 4e-3),
                                    num_threads=1)
    r = _cli("evaluate", "--policy", str(run), "--targets", "4", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["env_id"] == "MicroConveyor-v1" and out["target_range_m"] == [1e-3, 4e-3]
    # the same scene spelled out, and a runtime knob, are accepted
    r = _cli("evaluate", "--policy", str(run), "--targets", "4", "--env", "MicroConveyor-v1",
             "--env-kwargs", "n_actuators:3", "num_threads:2", "--json")
    assert r.returncode == 0, r.stderr
    # another scene is refused, naming what differs; nothing is evaluated
    for extra, what in ((["--env-kwargs", "n_actuators:5"], "n_actuators: trained 3, asked 5"),
                        (["--env", "MicroConveyor-v0"], "preset: trained 'conveyor', asked "
                                                        "'feasibility'")):
        r = _cli("evaluate", "--policy", str(run), "--targets", "4", *extra, "--json")
        assert r.returncode == 2, r.stderr
        err = json.loads(r.stdout)["error"]
        assert "refused" in err and what in err, err


def test_shipped_v0_policy_refuses_v1_and_keeps_its_scene():
    pol = load_policy(shipped_path("ppo", "MicroConveyor-v0"))
    assert pol.env_id == "MicroConveyor-v0" and pol.config.preset == "feasibility"
    with pytest.raises(PolicyError, match="preset: trained 'feasibility', asked 'conveyor'"):
        load_policy(shipped_path("ppo", "MicroConveyor-v0"), env_config("MicroConveyor-v1"))
    # randomisation is a test condition, not the scene: the randomised policy loads nominal
    rand = load_policy(shipped_path("ppo_randomised", "MicroConveyor-v0"))
    assert rand.config.action_noise == 0.0 and rand.config.friction_factor_range == (1.0, 1.0)
    load_policy(shipped_path("ppo", "MicroConveyor-v0"), env_config("MicroConveyor-v0", action_noise=0.01))


def test_commands_take_env_and_refuse_what_does_not_fit(tmp_path):
    r = _cli("optimize", "--problem", "target", "--env", "MicroConveyor-v1", "--env-kwargs",
             "n_actuators:3", "--target", "3e-3", "--budget", "30", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["env_id"] == "MicroConveyor-v1" and len(out["plan"]) == 3
    r = _cli("optimize", "--problem", "dissertation", "--env", "MicroConveyor-v1", "--json")
    assert r.returncode == 2 and "belong to --problem target" in json.loads(r.stdout)["error"]
    r = _cli("evaluate", "--env", "MicroConveyor-v1", "--targets", "5", "--json")
    assert r.returncode == 0, r.stderr  # the shipped v1 policy, in its own scene
    assert json.loads(r.stdout)["env_id"] == "MicroConveyor-v1"
    r = _cli("evaluate", "--env", "MicroConveyor-v1", "--env-kwargs", "n_actuators:3", "--json")
    assert r.returncode == 2 and "n_actuators" in r.stdout
    r = _cli("reach", "--env", "MicroConveyor-v1", "--targets", "1e-3", "--budget", "30",
             "--robust-budget", "0", "--noisy", "4", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["env_id"] == "MicroConveyor-v1" and len(out["rows"]) == 1
    r = _cli("evaluate", "--env", "MicroConveyor-v9", "--json")
    assert r.returncode == 2 and "MicroConveyor-v9" in r.stdout


def test_demo_on_v1_shows_v1s_surface_and_its_shipped_policy(tmp_path):
    r = _cli("demo", "--env", "MicroConveyor-v1", "--out", str(tmp_path), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["preset"] == "conveyor"
    assert "MicroConveyor-v1" in out["policy_demo"]["policy"] and out["policy_demo"]["rows"]
    assert out["episode"]["env_id"] == "MicroConveyor-v1"
    assert (tmp_path / "episode.png").stat().st_size > 1000
    # chapter 4's surface conveys over a narrower window than chapter 3's (225-1250 Hz)
    assert out["window_hz"] == [200.0, 800.0]


@pytest.mark.parametrize("algo", ["SAC", "TD3"])
def test_off_policy_zips_load_as_data_and_act_as_trained(tmp_path, algo):
    import numpy as np
    import stable_baselines3 as sb3

    from microconveyor_env.envs import MicroConveyorEnv

    env = MicroConveyorEnv(config=env_config("MicroConveyor-v1"))
    model = getattr(sb3, algo)("MlpPolicy", env, learning_starts=10, seed=0, device="cpu",
                               policy_kwargs={"net_arch": [16]})
    model.learn(40)
    model.save(tmp_path / "model.zip")
    from agents.rl.artefacts.checkpoint import sha256

    (tmp_path / "metadata.json").write_text(json.dumps({
        "env_id": "MicroConveyor-v1", "algo": algo.lower(), "env_kwargs": {},
        "hyperparams": {"normalize": None}, "files": {"model.zip": sha256(tmp_path / "model.zip")}}))
    pol = load_policy(tmp_path)
    obs = np.stack([env.reset(seed=s)[0] for s in range(4)])
    # act computes each row alone (Policy.act): the model's own prediction, row by row
    rows = np.concatenate([model.predict(o[None], deterministic=True)[0] for o in obs])
    np.testing.assert_array_equal(pol.act(obs), rows)
    r = _cli("evaluate", "--policy", str(tmp_path), "--targets", "3", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["env_id"] == "MicroConveyor-v1"
