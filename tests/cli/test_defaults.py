"""One default env id for every command (microconveyor_env.env_ids.DEFAULT_ENV_ID) and one
default shipped policy per env id (agents.rl.artefacts.shipped.DEFAULT_POLICIES): the most
accurate one shipped for it, the one ``evaluate``, ``video --policy shipped``, ``demo`` and
``place`` use unless told."""
import argparse
import json

import pytest

from microconveyor_env.cli import build_parser, main
from microconveyor_env.env_ids import DEFAULT_ENV_ID, REGISTRY


def _env_options():
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if action.dest == "env":
                yield name, action


def test_every_env_option_defaults_to_the_one_default_id():
    """An --env either defaults to DEFAULT_ENV_ID or to None (the policy's own env, else the
    default: the help says which); its choices are registered ids."""
    seen = set()
    for name, action in _env_options():
        seen.add(name)
        assert action.default in (None, DEFAULT_ENV_ID), (name, action.default)
        assert set(action.choices) <= set(REGISTRY), name
        if action.default is None and name not in ("evaluate",):
            assert DEFAULT_ENV_ID in action.help, (name, action.help)
    assert {"demo", "reach", "optimize", "evaluate", "video", "place", "train", "compare",
            "tune"} <= seen


def _nominal_success(meta):
    return meta.get("evaluation_nominal", meta["evaluation"])["success_rate_50um"]


def test_the_default_policy_of_each_env_is_its_most_accurate_shipped_one():
    from agents.rl.artefacts.shipped import DEFAULT_POLICIES, require_shipped, shipped_policies

    shipped = shipped_policies()
    assert set(DEFAULT_POLICIES) <= set(shipped)
    for env_id, names in shipped.items():
        default = require_shipped(env_id)
        assert default.parent.name == env_id and default.name in names
        success = {n: _nominal_success(json.loads((default.parent / n / "metadata.json")
                                                  .read_text())) for n in names}
        assert success[default.name] == max(success.values()), (env_id, success)
    assert require_shipped("MicroConveyor-v1").name == "ppo_refined"
    # an interface variant without policies of its own uses its scene version's default
    assert require_shipped("MicroConveyorGoal-v1") == require_shipped("MicroConveyor-v1")


def test_evaluate_without_policy_uses_the_default_envs_default_policy(capsys):
    pytest.importorskip("stable_baselines3")
    assert main(["evaluate", "--targets", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["env_id"] == DEFAULT_ENV_ID and out["policy"].endswith("MicroConveyor-v1/ppo_refined")
