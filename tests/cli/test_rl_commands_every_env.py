"""The RL commands that take ``--env`` (``train``, ``evaluate``, ``tune``, ``train-seeds``) on every
registered id, on tiny budgets: each either runs (exit 0) or refuses with exit 2 and exactly one
line on stderr saying why. Which of the two is pinned per command and id, so a command that
starts refusing an env it ran on (or the reverse) fails here."""
from __future__ import annotations

import pytest
import yaml

from microconveyor_env.cli import main
from microconveyor_env.env_ids import REGISTRY

pytest.importorskip("stable_baselines3")

PLANE = "MicroConveyor2D-v0"
GOAL = "MicroConveyorGoal-v1"
# a tiny PPO entry for every registered id (observations normalised, as the shipped recipes)
ENTRY = {"env_kwargs": {"num_threads": 1}, "n_envs": 8, "n_timesteps": 512, "n_steps": 32,
         "batch_size": 64, "n_epochs": 1, "normalize": True, "policy": "MlpPolicy",
         "policy_kwargs": "dict(net_arch=dict(pi=[16], vf=[16]))"}
# command -> ids it refuses, with what its one line says
REFUSED = {
    "train": {GOAL: "normalize: MicroConveyorGoal-v1 has Dict observations"},
    "evaluate": {},   # the goal env: its scene version's default policy, on that scene
    "tune": {GOAL: "normalize: MicroConveyorGoal-v1 has Dict observations"},
    "train-seeds": {GOAL: "normalize: MicroConveyorGoal-v1 has Dict observations"},
}


def _argv(command: str, env_id: str, tmp, conf: str) -> list[str]:
    out = str(tmp / "out")
    budget = ["--conf-file", conf, "--steps", "256", "--eval-freq", "0"]
    return {
        "train": ["train", "--out", out, *budget, "--eval-targets", "2", "--no-progress"],
        "evaluate": ["evaluate", "--targets", "2"],
        "tune": ["tune", "--out", out, "--trials", "1", "--quiet", *budget, "--eval-targets", "2",
                 "--fix", "n_envs:8", "n_steps:32", "batch_size:64", "n_epochs:1",
                 "net_width:64"],
        "train-seeds": ["train-seeds", "--seeds", "0", "--out", out, "--quiet", *budget,
                        "--eval-targets", "2"],
    }[command] + ["--env", env_id]


@pytest.mark.parametrize("env_id", list(REGISTRY))
@pytest.mark.parametrize("command", list(REFUSED))
def test_rl_command_runs_or_refuses_in_one_line(command, env_id, tmp_path, capsys):
    conf = tmp_path / "tiny.yml"
    conf.write_text(yaml.safe_dump({i: ENTRY for i in REGISTRY}))
    capsys.readouterr()
    code = main(_argv(command, env_id, tmp_path, str(conf)))
    err = capsys.readouterr().err
    why = REFUSED[command].get(env_id)
    if why is None:
        assert code == 0, err
    else:
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, err
        assert why in lines[0]


def test_refine_refuses_a_plane_policy_in_one_line(tmp_path, capsys):
    from agents.rl.artefacts.shipped import shipped_path

    code = main(["refine", str(shipped_path("ppo", PLANE)), "--out", str(tmp_path / "r"),
                 "--targets", "4", "--rounds", "1"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "refine needs a policy of the 1-D conveyor" in lines[0]
