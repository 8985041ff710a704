"""``--preset``: the surface a physics command simulates, or the env's surface on an env command
(as ``--env-kwargs preset:NAME``, so a policy's scene check sees it); refused at parse time when
unknown, and not offered by the commands that have no surface."""
import argparse
import json

import pytest

from microconveyor_env.cli import build_parser, main
from microconveyor_env.presets import available_presets

# a policy's own scene, or files only: (command, its required arguments)
NO_SURFACE = {"refine": ("x", "--out", "y"), "seeds": ("x",), "convert-stats": ("x",),
              # a shipped policy is recorded on the surface it was trained on
              "record": ("MicroConveyor-v1/ppo",), "ship": ("x", "MicroConveyor-v1/x"),
              # a firing map is of its scene's own surface
              "firing-map": ("--env", "MicroPositioner-v0")}


def _commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _run(capsys, *argv):
    capsys.readouterr()
    rc = main(list(argv))
    return rc, capsys.readouterr().out


def test_every_command_with_a_surface_takes_preset_and_refuses_an_unknown_one(capsys):
    with_preset = [n for n, p in _commands().items()
                   if any("--preset" in a.option_strings for a in p._actions)]
    assert sorted(with_preset) == sorted(set(_commands()) - set(NO_SURFACE))
    known = ", ".join(available_presets())
    assert known.startswith("conveyor, feasibility")
    for name in with_preset:
        rc, out = _run(capsys, name, "--preset", "nosuch", "--json")
        err = json.loads(out)
        assert rc == 2 and err["error_type"] == "UsageError", (name, out)   # at parse time
        assert f"unknown preset 'nosuch'; available: {known}" in err["error"], (name, out)


@pytest.mark.parametrize("name", sorted(NO_SURFACE))
def test_commands_without_a_surface_do_not_offer_preset(capsys, name):
    rc, out = _run(capsys, name, *NO_SURFACE[name], "--preset", "silicon", "--json")
    assert rc == 2 and "unrecognized arguments: --preset silicon" in json.loads(out)["error"]


def test_preset_sets_the_env_of_an_env_command(capsys):
    """``optimize --preset silicon`` plans on silicon (as ``--env-kwargs preset:silicon``), not
    on the env's own conveyor surface."""
    base = ("optimize", "--env", "MicroConveyor-v1", "--target", "2e-3", "--budget", "30",
            "--json")
    results = []
    for extra in ((), ("--preset", "silicon"), ("--env-kwargs", "preset:silicon")):
        rc, out = _run(capsys, *base, *extra)
        assert rc == 0, out
        results.append(json.loads(out))
    own, preset, kwargs = results
    assert preset["env_kwargs"] == kwargs["env_kwargs"] == {"preset": "silicon"}
    assert preset["final_position_m"] == kwargs["final_position_m"]
    assert preset["plan"] == kwargs["plan"]
    assert preset["final_position_m"] != own["final_position_m"]
    rc, out = _run(capsys, *base, "--preset", "silicon", "--env-kwargs", "preset:conveyor")
    assert rc == 2 and "preset given twice" in json.loads(out)["error"]
    rc, out = _run(capsys, "optimize", "--problem", "dissertation", "--preset", "silicon",
                   "--json")
    assert rc == 2 and "--preset belong to --problem target" in json.loads(out)["error"]


def test_evaluate_refuses_a_policy_on_another_preset(capsys):
    rc, out = _run(capsys, "evaluate", "--targets", "2", "--preset", "silicon", "--json")
    err = json.loads(out)["error"]
    assert rc == 2 and "differs in preset" in err and "another scene is refused" in err
    rc, out = _run(capsys, "evaluate", "--targets", "2", "--preset", "conveyor", "--json")
    res = json.loads(out)   # what ran (its own preset, named), and what the policy trained on
    assert rc == 0 and res["env_kwargs"] == {"num_threads": 1, "preset": "conveyor"}
    assert res["trained_env_kwargs"] == {"num_threads": 1}
