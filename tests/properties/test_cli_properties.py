"""CLI argument fuzzing through ``main(argv)``: with ``--json`` every run prints exactly one JSON
object on stdout (strict JSON: no NaN) and every failure is ``{"error": ...}`` with exit status 2;
without it a failure is one readable line on stderr. Never a traceback, never an internal error."""
import json

import pytest
from hypothesis import assume, event, example, given, strategies as st

from microconveyor_env.cli import build_parser, main

NUM = ["950", "700", "1e-4", "-5", "0", "nan", "inf", "-inf", "1e999", "abc", "", ",", "1_000",
       "0x10", " 3 "]
SPEC = ["200:1500:100", "300,700", "200:300:0", "1500:200:25", "0:1e308:1e-300",
        "-1e308:1e308:1", "200:1500:0.0001", ",", "a:b:c", "1:2:3:4", "nan:1:1", "700,abc"]
VALUES = {
    "--freq": NUM + SPEC, "--stroke": ["200e-6", "150e-6,200e-6", "1e-2", "-1", "abc", ","],
    "--x0": ["0.125e-3", "0", "1e308", "nan", "abc"],
    "--wavelength": ["0.6e-3", "1e-300", "5e-324", "2", "abc", "6e-4,7e-4"],
    "--profile": ["gaussian", "sinusoidal", "clamped_beam", "square", "gaussian,sinusoidal", ","],
    "--mass": ["2e-9", "2e-9,3e-9", "-1", "abc", ","], "--sigma": ["abc", "-1", ","],
    "--dgamma": ["nan", "0", ","],
    "--mode": ["event", "karnopp", "euler"], "--kinematics": ["reduced", "exact", "seed", "x"],
    "--dt": ["5e-5", "1e-6", "1e-12", "5e-324", "0", "2", "nan", "abc"],
    "--max-steps": ["1", "1000", "0", "-3", "2.5", "abc", "1e7"],
    "--max-points": ["1", "5", "0", "abc"], "--repeats": ["0", "-1", "abc", "1e3"],
    "--out": ["{tmp}/demo"],
    "--plot": ["", "{tmp}/noext", "{tmp}/x.xyz", "{tmp}/", "{tmp}/c.png", "{tmp}/c.svg"],
    "--preset": ["dissertation", "seed", "nope", "../seed", "{tmp}/bad.yaml", "{tmp}/alias.yaml",
                 "{tmp}/types.yaml", "{tmp}/text.yaml", "{tmp}/list.yaml", "{tmp}/missing.yaml"],
}
FLAGS = ["--json", "--no-progress", "--check-table", "--skip-reference", "--bogus", "-h"]
COMMANDS = ["simulate", "sweep", "contact", "bench", "accuracy", "demo", "nope"]
HEAVY = {"bench", "accuracy", "demo", "contact"}  # run only when the arguments are refused
EXPECTED_ERRORS = {"UsageError", "ParameterError", "PresetError", "TableRangeError",
                   "DetachmentError", "ValueError", "FileNotFoundError", "IsADirectoryError",
                   "NotADirectoryError", "PermissionError"}

PRESETS = {"bad.yaml": "name: [a\n", "alias.yaml": "surface: &s {sigma: 2.0e-8}\npart: *s\n",
           "types.yaml": "materials: [1, 2]\n", "text.yaml": "surface: {sigma: '2e-8'}\n",
           "list.yaml": "- 1\n- 2\n"}


@pytest.fixture(scope="module")
def tmpdir_(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    for name, text in PRESETS.items():
        (d / name).write_text(text)
    return d


def _opts(pool, **kw):
    return st.lists(st.sampled_from(sorted(pool)).flatmap(
        lambda k: st.tuples(st.just(k), st.sampled_from(pool[k]))), unique_by=lambda o: o[0], **kw)


SIM_OK = {"--freq": ["950", "700", "300"], "--stroke": ["200e-6", "150e-6"],
          "--x0": ["0.125e-3", "0.1e-3"], "--mode": ["event", "karnopp"],
          "--kinematics": ["reduced", "exact"], "--dt": ["5e-5", "2e-5"],
          "--profile": ["gaussian", "sinusoidal", "clamped_beam"], "--max-steps": ["100000"]}
SWEEP_OK = {"--stroke": ["200e-6"], "--x0": ["0.125e-3"], "--mode": ["event", "karnopp"],
            "--dt": ["5e-5"], "--max-points": ["50"]}
hostile_options = st.lists(st.one_of(
    st.sampled_from(sorted(VALUES)).flatmap(lambda k: st.tuples(st.just(k),
                                                                st.sampled_from(VALUES[k]))),
    st.sampled_from(FLAGS).map(lambda f: (f,))), max_size=5)
# (command, options): mostly valid lines with one hostile option at most, or anything at all
lines = st.one_of(
    st.tuples(st.just("simulate"), _opts(SIM_OK, max_size=4)),
    st.tuples(st.just("sweep"), st.tuples(
        st.sampled_from(["--freq", "--stroke", "--x0", "--mass", "--profile"]).map(
            lambda k: (k, {"--freq": "200:1500:325", "--stroke": "100e-6,200e-6",
                           "--x0": "0.1e-3:0.15e-3:0.025e-3", "--mass": "2e-9,3e-9",
                           "--profile": "gaussian,sinusoidal"}[k])),
        _opts(SWEEP_OK, max_size=3)).map(lambda t: [t[0]] + [o for o in t[1] if o[0] != t[0][0]])),
    st.tuples(st.sampled_from(COMMANDS + [""]), hostile_options),
).flatmap(lambda line: st.tuples(st.just(line[0]), st.one_of(
    st.just(line[1]), hostile_options.map(lambda h: line[1] + h[:1]))))


def _argv(command, opts, json_flag, tmp):
    argv = [command] if command else []
    for o in opts:
        argv += [o[0]] + ([o[1].format(tmp=tmp)] if len(o) > 1 else [])
    if json_flag and "--json" not in argv:
        argv.append("--json")
    return argv


def _refused_by_parser(argv) -> bool:
    try:
        build_parser().parse_args(argv)
        return False
    except (ValueError, SystemExit):
        return True


@given(line=lines, json_flag=st.booleans())
@example(line=("simulate", [("--freq", "abc")]), json_flag=True)          # argparse error
@example(line=("sweep", [("--freq", "0:1e308:1e-300")]), json_flag=True)  # overflow
@example(line=("contact", [("--preset", "{tmp}/bad.yaml")]), json_flag=True)
@example(line=("contact", [("--preset", "{tmp}/alias.yaml")]), json_flag=True)
@example(line=("contact", [("--preset", "{tmp}/types.yaml")]), json_flag=False)
@example(line=("sweep", [("--freq", ",")]), json_flag=True)               # empty list
@example(line=("simulate", [("--plot", "")]), json_flag=True)
@example(line=("simulate", [("--dt", "1e-12")]), json_flag=True)          # 1e9 steps
# the old preset names it draws on purpose are still accepted, with their deprecation warning
@pytest.mark.filterwarnings("ignore:preset '.*' is now called:DeprecationWarning")
def test_cli_errors_follow_the_contract(tmpdir_, capsys, line, json_flag):
    command, opts = line
    argv = _argv(command, opts, json_flag, tmpdir_)
    if "-h" in argv and not _refused_by_parser([a for a in argv if a != "-h"]):
        assume(False)  # help on a valid line: prints usage and exits 0, not an error
    if command in HEAVY and not _refused_by_parser(argv):
        assume(False)  # a valid long study: not for a fuzz loop
    capsys.readouterr()
    try:
        rc = main(argv)
    except SystemExit as exc:  # only --help may exit
        assert "-h" in argv and exc.code == 0, argv
        return
    out, err = capsys.readouterr()
    json_flag = "--json" in argv
    assert rc in (0, 2), (argv, rc)
    event(f"exit {rc}")
    assert "Traceback" not in err and "internal error" not in err, (argv, err)
    if json_flag:
        lines = out.strip().splitlines()
        assert len(lines) == 1, (argv, out)
        obj = json.loads(lines[0], parse_constant=lambda c: pytest.fail(f"{c} in JSON: {argv}"))
        assert isinstance(obj, dict)
        if rc == 2:
            assert set(obj) == {"error", "error_type"}, obj
            assert obj["error_type"] in EXPECTED_ERRORS, (argv, obj)
        else:
            assert "error" not in obj
    if rc == 2:
        last = err.strip().splitlines()[-1]
        assert last.startswith("microconveyor") and "Error:" in last, (argv, err)
        if not json_flag:
            assert out == "", (argv, out)
