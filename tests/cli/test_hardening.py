"""Regression tests for issue #8's examples (the property suite in tests/properties generalises)."""
import json

import numpy as np
import pytest

import microconveyor_env  # noqa: F401 - registers the env
from microconveyor_env.cli import main
from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, MicroConveyorVectorEnv
from microconveyor_env.physics.materials import ParameterError, Surface
from microconveyor_env.physics.schedule import Schedule
from microconveyor_env.presets import simulator
from microconveyor_env.studies.sweep import parse_values


def _run(capsys, *argv):
    capsys.readouterr()
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_argparse_error_under_json_is_one_json_object_and_exit_2(capsys):
    rc, out, err = _run(capsys, "simulate", "--json", "--freq", "abc")
    assert rc == 2 and json.loads(out)["error_type"] == "UsageError"
    assert "--freq" in json.loads(out)["error"] and len(err.strip().splitlines()) == 1
    rc, out, err = _run(capsys, "simulate", "--freq", "abc")
    assert rc == 2 and out == "" and "invalid float value" in err


def test_plot_without_extension_reports_the_file_written(capsys, tmp_path):
    rc, out, _ = _run(capsys, "simulate", "--json", "--plot", str(tmp_path / "noext"))
    assert rc == 0
    path = json.loads(out)["plot"]
    assert path == str(tmp_path / "noext.png") and (tmp_path / "noext.png").is_file()


@pytest.mark.parametrize("value", ["", "   "])
def test_empty_plot_path_is_refused(capsys, value):
    rc, out, _ = _run(capsys, "simulate", "--json", "--plot", value)
    assert rc == 2 and "empty file name" in json.loads(out)["error"]


@pytest.mark.parametrize("spec", [",", " , ,"])
def test_empty_value_lists_are_refused(capsys, spec):
    with pytest.raises(ParameterError, match="no values"):
        parse_values(spec, "freq")
    rc, out, _ = _run(capsys, "sweep", "--json", "--no-progress", "--freq", spec)
    assert rc == 2 and "no values" in json.loads(out)["error"]


def test_sweep_size_is_capped_with_an_override():
    with pytest.raises(ParameterError, match="1e\\+07 points.*--max-points"):
        parse_values("0:1e7:1", "freq")
    with pytest.raises(ParameterError, match="inf points"):
        parse_values("0:1e308:1e-300", "freq")  # the count overflows
    assert len(parse_values("1:20000:1", "freq", max_points=20000)) == 20000


def test_tiny_dt_is_refused_not_run_and_absurd_dt_does_not_wrap():
    sim = simulator("feasibility", dt=1e-12)
    with pytest.raises(ParameterError, match=r"dt = 1e-12 s.*1\.05e\+09 RK4 steps.*max_steps"):
        sim.simulate(Schedule.single(950.0, 200e-6), 0.125e-3)
    slow = simulator("feasibility", dt=1.0, min_steps=2)
    with pytest.raises(ParameterError, match="inf RK4 steps"):  # 1/(f dt) beyond float range
        slow.simulate(Schedule.single(1e-310, 200e-6), 0.125e-3)
    big = simulator("feasibility", dt=1e-9, max_steps=10 ** 9)  # the override
    big.check_firings(np.array([950.0]), np.array([200e-6]))
    with pytest.raises(ParameterError, match="max_steps"):
        simulator("feasibility", max_steps=0)


def test_env_step_budget_and_its_override():
    with pytest.raises(ParameterError, match="dt, freq_range, n_actuators"):
        EnvConfig(dt=1e-9)
    assert EnvConfig(dt=1e-9, max_steps=10 ** 8).max_steps == 10 ** 8


@pytest.mark.parametrize("kw,field", [
    ({"tolerance": 5e-324}, "tolerance"), ({"progress_scale": 1e-320}, "progress_scale"),
    ({"target_range": [1e-3, 0.5]}, "target_range"), ({"tolerance": "1e-3"}, "tolerance"),
    ({"time_cost": True}, "time_cost"), ({"n_actuators": float("nan")}, "n_actuators"),
])
def test_configs_that_gave_nan_or_passed_wrong_types_are_refused_by_name(kw, field):
    with pytest.raises(ValueError, match=field):
        EnvConfig(**kw)


def test_yaml_text_number_hint():
    with pytest.raises(ParameterError, match="write 1.0e-3"):
        Surface(sigma="2e-8")


def test_batched_env_refuses_human_render_mode_and_the_single_env_unknown_ones():
    with pytest.raises(ValueError, match="render_mode 'ansi'"):
        MicroConveyorEnv(render_mode="ansi")  # (human: a pygame window, tests/envs/test_render.py)
    with pytest.raises(ValueError, match="render_mode 'human'"):
        MicroConveyorVectorEnv(2, render_mode="human")
    for bad in (0, 2.5, True, "3"):
        with pytest.raises(ValueError, match="num_envs"):
            MicroConveyorVectorEnv(bad)


@pytest.mark.parametrize("argv, shown", [
    (("stretch", "--repeats", "0"), "--repeats: must be an integer in [1, 10000], got 0"),
    (("fidelity", "--repeats", "0"), "--repeats: must be an integer in [1, 10000], got 0"),
    (("fidelity", "--repeats", "-2"), "--repeats: must be an integer in [1, 10000], got -2"),
    (("stretch", "--n-sigma", "1"), "--n-sigma: must be an integer in [2, 1000], got 1"),
    (("sensitivity", "--n-freq", "0"), "--n-freq: must be an integer in [1, 10000], got 0"),
    (("sensitivity", "--sobol-n", "-1"), "--sobol-n: must be an integer in [0, ...], got -1"),
])
def test_counts_outside_their_range_are_refused_before_any_work(capsys, argv, shown):
    rc, out, err = _run(capsys, *argv, "--json")
    assert rc == 2
    e = json.loads(out)
    assert e["error_type"] == "UsageError" and shown in e["error"]
    assert len(err.strip().splitlines()) == 1


def test_every_repeats_option_needs_at_least_one():
    """Every command's ``--repeats`` (the agents' too) refuses 0: no run times nothing."""
    import argparse

    from microconveyor_env.cli import UsageError, build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    with_repeats = [name for name, p in sub.choices.items()
                    if any("--repeats" in a.option_strings for a in p._actions)]
    assert {"stretch", "fidelity", "accuracy", "bench"} <= set(with_repeats)
    for name in with_repeats:
        with pytest.raises(UsageError, match="--repeats: must be an integer in \\[1, "):
            parser.parse_args([name, "--repeats", "0"])


def test_an_integer_bound_is_printed_whole(capsys):
    """A count's bound reads as the integer it is (not 2.14748e+09, which the refused value
    seems to lie within)."""
    capsys.readouterr()
    assert main(["evaluate", "--seed", "2147483648"]) == 2
    err = capsys.readouterr().err
    assert "[0, 2147483647], got 2147483648" in err and "e+09" not in err
