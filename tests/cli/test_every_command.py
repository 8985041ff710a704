"""Every command of the ``microconveyor`` command line, run in process as a user types it (tiny
budgets), against two contracts:

* every option a command accepts acts: the handler reads the value of each of the command's
  options in at least one of its runs (``args`` records what is read). An option whose value
  is never read changes nothing, whatever the user gives: a defect.
* the output without ``--json`` is text for people (microconveyor_env/cli/human.py, docs/cli.md):
  no Python repr (``{'``, ``['``, ``None``), no raw SI float (``6.94e-08``,
  ``0.00015000000000000001``), micrometres as µm, and the units people read wherever the
  result holds quantities.

A command added to the CLI without runs here fails ``test_every_command_has_runs``.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

import pytest

from microconveyor_env.cli import COMMANDS, build_parser
from microconveyor_env.cli.base import attach_negative_values

V0_POLICY = "agents/policies/MicroConveyor-v0/ppo"
V1_POLICY = "agents/policies/MicroConveyor-v1/ppo"
TINY_CONF = """MicroConveyor-v0:
  env_kwargs: {num_threads: 1}
  n_envs: 8
  n_timesteps: 512
  policy: MlpPolicy
  normalize: true
  n_steps: 32
  batch_size: 64
  n_epochs: 1
"""
TRAIN_TINY = ["--env", "MicroConveyor-v0", "--conf-file", "{conf}", "--steps", "256",
              "--eval-freq", "0", "--eval-targets", "2"]

# command -> its runs (argv after the command name; {tmp}, {conf}, {pkl}, {run}, {root} are filled in)
RUNS: dict[str, list[list[str]]] = {
    "contact": [["--preset", "feasibility", "--check-table", "--plot", "{tmp}/c.png"]],
    "simulate": [["--preset", "feasibility", "--freq", "900", "--stroke", "150e-6", "--x0",
                  "-0.125e-3", "--wavelength", "0.6e-3", "--profile", "gaussian", "--mode",
                  "event", "--kinematics", "reduced", "--roughness", "constant", "--dt", "2.5e-5",
                  "--max-steps", "100000", "--plot", "{tmp}/f.png", "--trajectory",
                  "{tmp}/f.csv"]],
    "sweep": [["--preset", "feasibility", "--freq", "600:800:100", "--stroke", "200e-6", "--x0",
               "0.125e-3", "--wavelength", "0.6e-3", "--profile", "gaussian", "--mode", "event",
               "--kinematics", "reduced", "--roughness", "constant", "--dt", "5e-5",
               "--max-steps", "100000", "--no-progress", "--max-points", "10", "--plot",
               "{tmp}/s.png"]],
    "accuracy": [["--repeats", "1", "--plot", "{tmp}/a.png"],
                 ["--episode", "--per-category", "1", "--repeats", "1", "--seed", "1"]],
    "bench": [["--preset", "feasibility", "--repeats", "2", "--skip-reference", "--plane"]],
    "sensitivity": [["--quick", "--n-freq", "3", "--sobol-n", "0", "--no-progress", "--out",
                     "{tmp}/s.csv", "--plot", "{tmp}/s.png", "--workers", "0", "--chunk-size",
                     "4", "--scheduler-timeout", "5"]],
    "engage": [["--freqs", "500", "--stroke", "150e-6", "--x0", "0:0.1e-3:0.1e-3", "--v0",
                "0:0.1:0.1", "--two-freq", "950", "--two-stroke", "200e-6", "--start-offset",
                "0.125e-3", "--spacing", "0.5e-3", "--delay", "0,1e-3", "--no-progress",
                "--out", "{tmp}/e.csv", "--plot", "{tmp}/e.png"]],
    "fidelity": [["--scenes", "single", "--repeats", "1", "--no-progress", "--out",
                  "{tmp}/f.csv", "--plot", "{tmp}/f.png"]],
    "firing-map": [["--env", "MicroPositioner-v0", "--samples", "50", "--seed", "3"]],
    "stretch": [["--freq", "900,950", "--stroke", "200e-6", "--x0", "0.125e-3", "--profile",
                 "gaussian", "--wavelength", "0.6e-3", "--kinematics", "reduced", "--repeats",
                 "1", "--n-sigma", "21", "--no-progress", "--out", "{tmp}/s.csv", "--plot",
                 "{tmp}/s.png"]],
    "demo": [["--out", "{tmp}/demo", "--env", "MicroConveyor-v0", "--env-kwargs",
              "num_threads:1", "--preset", "feasibility", "--policy", V0_POLICY]],
    "optimize": [["--env", "MicroConveyor-v1", "--preset", "conveyor", "--target", "1e-3",
                  "--budget", "30", "--popsize", "10", "--seed", "1", "--method", "de", "--plot",
                  "{tmp}/o.png"],
                 ["--problem", "dissertation", "--budget", "30", "--method", "cmaes"]],
    "place": [["--target", "2e-3", "--method", "mpc", "--mpc-budgets", "10,10", "--policy",
               V1_POLICY, "--seed", "1", "--noise", "1e-3", "--spread", "0.01", "--env",
               "MicroConveyor-v1", "--preset", "conveyor"],
              ["--target", "1e-3", "--method", "de", "--budget", "20", "--tolerance", "1e-4",
               "--time-weight", "500"]],
    "reach": [["--targets", "1e-3", "--budget", "10", "--robust-budget", "0", "--noisy", "2",
               "--sigma", "1e-3", "--seed", "1", "--plot", "{tmp}/r.png", "--env",
               "MicroConveyor-v0", "--preset", "feasibility"]],
    "evaluate": [["--policy", V0_POLICY, "--targets", "3", "--seed", "1", "--tolerance", "1e-4",
                  "--env", "MicroConveyor-v0", "--preset", "feasibility"],
                 ["--env", "MicroConveyor2D-v0", "--targets", "2"]],
    "video": [["--out", "{tmp}/v.gif", "--frames-per-stroke", "1", "--fps", "2", "--target",
               "2e-3", "--seed", "1", "--freq", "900", "--stroke", "200e-6", "--delay", "0",
               "--env", "MicroConveyor-v1", "--preset", "conveyor"],
              ["--policy", "shipped", "--out", "{tmp}/p.gif", "--frames-per-stroke", "1"]],
    "compare": [["--quick", "--targets", "1", "--budgets", "20", "--methods", "de",
                 "--mpc-budgets", "0", "--noise", "0", "--spread", "0",
                 "--diagonal", "0:0", "--randomised-policy", "", "--repeats", "1",
                 "--amortise-over", "10", "--workers", "1", "--seed", "1", "--policy",
                 V1_POLICY, "--plot", "{tmp}/c.png", "--env", "MicroConveyor-v1"]],
    "train": [[*TRAIN_TINY, "--algo", "ppo", "--out", "{tmp}/run", "--seed", "1",
               "--checkpoint-freq", "128", "--max-minutes", "5", "--no-progress"]],
    "seeds": [["{run}", "--plot", "{tmp}/curves.png"]],
    "imitate": [["--out", "{tmp}/dagger", "--rounds", "1", "--episodes", "2", "--seed", "1",
                 "--env", "MicroPositioner-v0", "--env-kwargs", "action_noise:1e-3"],
                ["--out", "{tmp}/dagger-v1", "--rounds", "1", "--episodes", "2",
                 "--seed-policy", "ppo"]],
    "refine": [[V1_POLICY, "--out", "{tmp}/refined", "--targets", "2", "--rounds", "1",
                "--fit-iterations", "1", "--eval-targets", "2", "--seed", "1"]],
    "convert-stats": [["{pkl}", "--out", "{tmp}/normalization.json"]],
    "tune": [[*TRAIN_TINY, "--out", "{tmp}/tune", "--trials", "1", "--workers", "1",
              "--fix", "n_envs:8", "n_steps:32", "batch_size:64", "n_epochs:1", "net_width:64",
              "--quiet", "--seed", "1", "--sampler-seed", "1", "--study", "s", "--no-prune",
              "--best", "{tmp}/best.yml", "--storage", "sqlite:///{tmp}/optuna.db",
              "--trial-minutes", "5"]],
    "train-seeds": [[*TRAIN_TINY, "--out", "{tmp}/seeds", "--seeds", "0", "--workers", "1",
                     "--algo", "ppo", "--max-minutes", "5", "--checkpoint-freq", "128",
                     "--quiet", "--plot", "{tmp}/curves.png"]],
    "record": [["MicroConveyor2D-v0/ppo", "--root", "{root}"]],
    "ship": [[V0_POLICY, "MicroConveyor-v0/new", "--root", "{root}"]],
}

# numbers that are dimensionless and rightly in scientific notation, by command: a line matching
# is exempt from the raw-SI-float rule only
DIMENSIONLESS = {
    "contact": re.compile(r"^\s*max_(rel|abs)_error_\w+\s"),          # the table's relative error
    "sensitivity": re.compile(r"\de-\d\d\s+n/a\s"),                     # the regression's p-values
    "tune": re.compile(r"^\s*hyperparameters: "),                     # learning rates and such
}
NO_QUANTITIES = {"convert-stats"}   # its result holds a file name and a count only

PY_REPR = re.compile(r"\{'|\['|\('|': |\bNone\b|np\.float|array\(")
LONG_FLOAT = re.compile(r"(?<![\w.])-?\d+\.\d{9,}")
# a number in scientific notation with a negative exponent and no unit people read after it
SCI_NEGATIVE = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?[eE]-\d+(?![\d.]|\s?(?:[pnµm][mN]|[nµm]s|Hz|%|/))")
ASCII_MICRO = re.compile(r"\bum\b")
UNITS = re.compile(r"µm|mm|nm|µN|nN|µs|ms|Hz|%|m/s")


def human_problems(text: str, command: str = "") -> list[str]:
    """What in ``text`` (a command's stdout without --json) breaks the human-output contract."""
    problems = []
    if not text.strip():
        problems.append("no output")
    allowed = DIMENSIONLESS.get(command)
    for line in text.splitlines():
        if PY_REPR.search(line):
            problems.append(f"Python repr: {line!r}")
        if LONG_FLOAT.search(line):
            problems.append(f"raw float: {line!r}")
        if SCI_NEGATIVE.search(line) and not (allowed and allowed.search(line)):
            problems.append(f"raw SI float: {line!r}")
        if ASCII_MICRO.search(line):
            problems.append(f"'um' for µm: {line!r}")
    if command not in NO_QUANTITIES and not UNITS.search(text):
        problems.append("no unit people read")
    return problems


class RecordingNamespace(argparse.Namespace):
    """``args`` that records the attributes read while ``recording`` is on."""

    def __init__(self) -> None:
        object.__setattr__(self, "_read", set())
        object.__setattr__(self, "_recording", False)
        super().__init__()

    def __getattribute__(self, name: str) -> Any:
        if not name.startswith("_") and object.__getattribute__(self, "_recording"):
            object.__getattribute__(self, "_read").add(name)
        return object.__getattribute__(self, name)


def option_dests(name: str) -> set[str]:
    """The dests of command ``name``'s options and arguments."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest for a in sub.choices[name]._actions if a.dest != "help"}


def run_command(argv: list[str], capsys: Any) -> tuple[set[str], str]:
    """Run ``microconveyor ARGV`` in process; (the attributes its handler read, its stdout)."""
    args = RecordingNamespace()
    build_parser().parse_args(attach_negative_values(argv), namespace=args)
    capsys.readouterr()
    object.__setattr__(args, "_recording", True)
    try:
        args.func(args)
    finally:
        object.__setattr__(args, "_recording", False)
    return set(args._read), capsys.readouterr().out


def _fill(argv: list[str], tmp: Path, **files: str) -> list[str]:
    return [a.format(tmp=tmp, **files) for a in argv]


def _setup(name: str, tmp: Path) -> dict[str, str]:
    """Files a command's runs need: a tiny config, a trained run folder, a VecNormalize pickle."""
    conf = tmp / "tiny.yml"
    conf.write_text(TINY_CONF)
    files = {"conf": str(conf), "run": "", "pkl": "", "root": str(tmp / "policies")}
    if name == "record":   # a copy of a shipped policy to record into
        import shutil

        shutil.copytree(Path(__file__).parents[2] / "agents/policies/MicroConveyor2D-v0/ppo",
                        tmp / "policies" / "MicroConveyor2D-v0" / "ppo")
    if name == "seeds":
        from agents.rl.training.settings import TrainSettings
        from agents.rl.training.train import train

        train(tmp / "run", TrainSettings(steps=256, env_id="MicroConveyor-v0", conf_file=str(conf),
                                         progress_bar=False, tensorboard=False, eval_freq=0,
                                         eval_targets=2))
        files["run"] = str(tmp / "run")
    if name == "convert-stats":
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        from microconveyor_env.envs import MicroConveyorEnv

        vn = VecNormalize(DummyVecEnv([MicroConveyorEnv]))
        vn.reset()
        vn.save(str(tmp / "vecnormalize.pkl"))
        files["pkl"] = str(tmp / "vecnormalize.pkl")
    return files


def test_every_command_has_runs():
    assert sorted(RUNS) == sorted(COMMANDS)
    assert len(COMMANDS) == 26


# commands whose modules belong to other work: what they break is reported, not fixed here
OTHERS: dict[str, str] = {}


@pytest.mark.parametrize("name", sorted(RUNS))
def test_every_option_acts_and_the_output_is_for_people(name, tmp_path, capsys, monkeypatch):
    pytest.importorskip("stable_baselines3")
    monkeypatch.chdir(Path(__file__).parents[2])   # the shipped policies' relative paths
    files = _setup(name, tmp_path)
    read: set[str] = set()
    problems = []
    for argv in RUNS[name]:
        got, out = run_command([name, *_fill(argv, tmp_path, **files)], capsys)
        read |= got
        problems += [f"{' '.join(argv[:4])} ...: {p}" for p in human_problems(out, name)]
    unread = option_dests(name) - read
    assert not unread, f"`{name}` accepts options whose value it never reads: {sorted(unread)}"
    if name in OTHERS and problems:
        pytest.xfail(f"{OTHERS[name]}: {problems}")
    assert not problems, problems


def test_the_contract_check_catches_what_it_names():
    """The checks above fail on what they are for (so the contract test can fail)."""
    assert human_problems("default: {'mode': 'event', 'error_m': 6.94e-08}")
    assert human_problems("x0  0.00015000000000000001")
    assert human_problems("median 8.69e-06")
    assert human_problems("dt 5e-05 s")                          # a unit, but not one people read
    assert human_problems("error 1.251e-05 nm") == []            # far below a nanometre
    assert human_problems("error 12.0 um")
    assert human_problems("robust target range: None")
    assert human_problems("wrote a.png")                         # no unit
    assert human_problems("wrote a.png", "convert-stats") == []
    p_value = "np.log(freq_hz)   9.226  0.252  36.66  1.45e-24        n/a         +  yes"
    assert human_problems(p_value, "contact") and human_problems(p_value, "sensitivity") == [
        "no unit people read"]
    assert human_problems("error 6.94 nm, 12 µm, 97.0 %, 2.6e+11 /m²") == []
