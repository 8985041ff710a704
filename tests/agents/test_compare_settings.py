"""The comparison's settings object (validated once, built by the command line) and `microconveyor
compare` on every registered env id: it runs on the line's versions and refuses the others with
exit status 2 and one stderr line saying why."""
from pathlib import Path

import pytest

from agents.experiments.compare_settings import MPC_SETTINGS, CompareSettings, check_env_id
from agents.mpc import MPCSettings
from microconveyor_env.env_ids import DEFAULT_ENV_ID, REGISTRY
from support.cli import run_cli


def test_defaults_and_normalisation():
    s = CompareSettings()
    assert s.env_id == DEFAULT_ENV_ID and s.mpc == MPC_SETTINGS and s.robust_mpc is None
    t = CompareSettings(methods=["cmaes"], budgets=[20, 40], noise_ladder=[0, 1e-3],
                        diagonal=[(1e-3, 0.01)], policy_seeds=[Path("a")])
    assert t.methods == ("cmaes",) and t.budgets == (20, 40)
    assert t.noise_ladder == (0.0, 1e-3) and t.diagonal == ((1e-3, 0.01),)
    assert t.policy_seeds == ("a",)
    with pytest.raises(AttributeError):
        t.seed = 3  # frozen


@pytest.mark.parametrize("kwargs, message", [
    ({"n_targets": 0}, "n_targets"), ({"n_targets": 2.0}, "n_targets"), ({"seed": -1}, "seed"),
    ({"methods": ["pso"]}, "de, cmaes"), ({"methods": []}, "de, cmaes"),
    ({"methods": ["de", "de"]}, "each once"), ({"budgets": []}, "budgets is empty"),
    ({"budgets": [5]}, "budget"), ({"budgets": [True]}, "budget"),
    ({"amortise_over": 0}, "amortise_over"), ({"mpc_workers": 0}, "mpc_workers"),
    ({"perturb_repeats": 0}, "perturb_repeats"), ({"mpc": "fast"}, "mpc must be"),
    ({"noise_ladder": [-1e-3]}, "noise_ladder"), ({"noise_ladder": [float("nan")]}, "noise"),
    ({"spread_ladder": [0.95]}, "spread_ladder"), ({"diagonal": [(1e-3, 0.95)]}, "diagonal"),
    ({"full_grid": 1}, "full_grid"), ({"config": {"n_actuators": 5}}, "EnvConfig"),
    ({"env_id": "MicroConveyor-v9"}, "not registered")])
def test_every_field_is_checked_when_made(kwargs, message):
    with pytest.raises(ValueError, match=message):
        CompareSettings(**kwargs)


def test_the_command_line_builds_the_settings_python_would():
    from agents.cli.compare import settings_of
    from microconveyor_env.cli import base
    from microconveyor_env.envs import env_config

    args = base.build_parser().parse_args(
        ["compare", "--env", "MicroConveyor-v0", "--quick", "--targets", "3", "--methods", "de",
         "--mpc-budgets", "30,15", "--robust-mpc", "80,40", "--noise", "0,0.01", "--spread",
         "0.02", "--diagonal", "0.01:0.02", "--seed", "4", "--workers", "1", "--repeats", "2",
         "--env-kwargs", "n_actuators:4"])
    robust = MPCSettings(first_budget=80, replan_budget=40, noise_copies=8, assumed_noise=3e-3,
                         identify=True, factor_range=0.1, seed=4)
    assert settings_of(args) == CompareSettings(
        env_id="MicroConveyor-v0", config=env_config("MicroConveyor-v0", n_actuators=4),
        n_targets=3, seed=4, methods=("de",), budgets=(300,),
        mpc=MPCSettings(first_budget=30, replan_budget=15, seed=4), robust_mpc=robust,
        mpc_workers=1, noise_ladder=(0.0, 0.01), spread_ladder=(0.02,),
        diagonal=((0.01, 0.02),), perturb_repeats=2)


def _expected_refusal(env_id: str) -> str | None:
    """What the refusal of ``env_id`` must say (None: compare runs there), from its registration
    alone, so that a new id is covered as it is added."""
    reg = REGISTRY[env_id]
    if reg.geometry not in ("line", "positioner"):
        return f"(the {reg.geometry})"
    if reg.base != env_id:
        return f"--env {reg.base}"
    return None


@pytest.mark.parametrize("env_id", list(REGISTRY))
def test_compare_runs_or_refuses_on_every_registered_id(env_id):
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("cma")
    refusal = _expected_refusal(env_id)
    assert (refusal is None) == _runs(env_id)
    r = run_cli("compare", "--env", env_id, "--targets", "1", "--budgets", "10", "--methods",
                "de", "--mpc-budgets", "0", "--noise", "0", "--spread", "0", "--diagonal", "",
                "--randomised-policy", "", "--workers", "1")
    if refusal is None:
        assert r.returncode == 0, r.stderr
        # the positioner has a PPO row once a policy is shipped for it
        assert "de" in r.stdout and ("ppo" in r.stdout or REGISTRY[env_id].geometry ==
                                     "positioner")
    else:
        assert r.returncode == 2 and r.stdout == ""
        assert len(r.stderr.splitlines()) == 1, r.stderr
        assert env_id in r.stderr and refusal in r.stderr


def _runs(env_id: str) -> bool:
    try:
        check_env_id(env_id)
    except ValueError:
        return False
    return True


def test_python_callers_are_refused_the_same_way():
    for env_id in REGISTRY:
        if _expected_refusal(env_id) is not None:
            with pytest.raises(ValueError, match=env_id):
                CompareSettings(env_id=env_id)
