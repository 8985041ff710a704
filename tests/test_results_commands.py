"""Every ``microconveyor`` command that docs/results.md quotes to reproduce a result runs: each as
quoted (``taskset -c N`` and ``nice`` dropped, an optional ``[--option]`` kept), its placeholders
(``S``, ``RUN``, ``ID``, ``NAME``, ``N``, ``...``) filled per command in :data:`RUNS`, on a tiny
budget, in the test's process (:func:`microconveyor_env.cli.main`), writing under a temporary
folder.

The budget: options appended to the quoted line (argparse keeps an option's last value), listed
per command in :data:`RUNS`. The outputs: each run starts in the temporary folder (a relative
``--out`` lands there), an output the quote names in the repository (``--plot docs/figures/...``)
is pointed there by an appended option, ``record`` and ``ship`` write into a copy of
``agents/policies`` there (``--root``), their evaluations cut to two targets; and the test fails
when anything under ``docs/figures`` or ``agents/policies`` changed. A quoted command without an
entry here fails ``test_every_quoted_command_has_a_run``; every quoted command, filled in, is
parsed in the default suite (a renamed or removed option fails there at once); the long runs
(``compare``) run with the slow tests.

The script commands that results.md quotes (``python scripts/...``):
tests/test_reproduce_commands.py; the README's ``microconveyor`` lines:
tests/test_readme_commands.py. ``train --refine`` refines at refine's defaults (minutes): here on
four targets, one round (the ``workdir`` fixture).
"""
from __future__ import annotations

import dataclasses
import re
import shlex
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results.md"
SPAN = re.compile(r"`([^`]+)`")                      # inline code, possibly over two lines
PREFIX = re.compile(r"^(?:nice |taskset -c \d+ )*")
PLACEHOLDER = re.compile(r"(?<![A-Z0-9_])(?:RUN|REFINED|NAME|ID|S|N)(?![A-Za-z0-9_])")
OPTIONAL = re.compile(r"\[([^\]]*)\]")               # `[--explain]`: the option is given


def quoted_commands() -> dict[str, list[int]]:
    """Every ``microconveyor`` command quoted in docs/results.md (whitespace collapsed,
    ``taskset``/``nice`` dropped) -> the lines it is quoted on."""
    text = RESULTS.read_text()
    out: dict[str, list[int]] = {}
    for m in SPAN.finditer(text):
        cmd = PREFIX.sub("", " ".join(m.group(1).split()))
        if cmd == "microconveyor" or cmd.startswith("microconveyor "):
            out.setdefault(cmd, []).append(text.count("\n", 0, m.start()) + 1)
    return out


@dataclass(frozen=True)
class Run:
    """How a quoted command runs here: ``fill`` its placeholders (``...`` included), ``tiny`` the
    options appended (``{tmp}``: the temporary folder), ``slow`` whether it runs with the slow
    tests only."""

    tiny: tuple[str, ...] = ()
    fill: dict[str, str] = field(default_factory=dict)
    slow: bool = False


TRAIN = ("--steps", "512", "--eval-targets", "2", "--no-progress")
POLICIES = "{tmp}/policies"                          # the copy of agents/policies
RECORD = ("--root", POLICIES)
COMPARE_V1 = ("--targets", "2", "--budgets", "40", "--mpc-budgets", "40,40", "--robust-mpc",
              "80,80", "--repeats", "1", "--plot", "{tmp}/compare_v1.png")
COMPARE_POSITIONER = ("--targets", "2", "--budgets", "20", "--repeats", "1", "--plot",
                      "{tmp}/compare_positioner.png")
IMITATE = ("--rounds", "1", "--episodes", "2")
REQUESTS = ("--rounds", "1", "--episodes", "4")   # one episode per request
# the options of the stored v1 comparison that the provenance table's `...` stands for (above it)
COMPARE_REST = ("--budgets 1000 --methods de --mpc-budgets 1000,300 --noise 0 --spread 0 "
                "--diagonal 3e-3:0.05")

RUNS: dict[str, Run] = {
    # the target sets
    "microconveyor evaluate --targets 1000 --seed 1": Run(("--targets", "2")),
    "microconveyor compare": Run(("--targets", "2", "--budgets", "20", "--mpc-budgets", "20,10",
                                  "--repeats", "1"), slow=True),
    # the shipped policies' table
    "microconveyor record": Run(RECORD),
    "microconveyor evaluate --env ID --policy agents/policies/ID/NAME --targets N --seed S": Run(
        fill={"ID": "MicroPositioner-v0", "NAME": "dagger", "N": "2", "S": "1"}),
    # training seeds
    "microconveyor seeds RUN ... --json": Run(fill={"RUN": "runs/s0", "...": "runs/s1"}),
    "microconveyor seeds RUN ...": Run(fill={"RUN": "runs/s0", "...": "runs/s1"}),
    "microconveyor train --quick": Run(TRAIN),
    "microconveyor imitate --env MicroConveyor-v1 --seed S": Run(IMITATE, {"S": "0"}),
    # every method under perturbation
    "microconveyor compare --budgets 1000 --methods de --mpc-budgets 1000,300 --policy "
    "agents/policies/MicroConveyor-v1/ppo --mpc-prior agents/policies/MicroConveyor-v1/ppo "
    "--robust-mpc --noise 0 --spread 0 --diagonal 3e-3:0.05 --plot "
    "docs/figures/compare_v1_mpc_ppo.png": Run(COMPARE_V1, slow=True),
    "microconveyor compare --mpc-prior agents/policies/MicroConveyor-v1/ppo --robust-mpc ...":
        Run(COMPARE_V1, {"...": COMPARE_REST}, slow=True),
    # the plane, v1
    "microconveyor train --env MicroConveyor2D-v1 --seed 1 --out RUN --eval-freq 2000000 "
    "--eval-targets 200": Run(TRAIN, {"RUN": "runs/plane_v1"}),
    "microconveyor ship RUN MicroConveyor2D-v1/ppo": Run(RECORD, {"RUN": "runs/plane_v1"}),
    # the dissertation's problem
    "microconveyor optimize --problem dissertation [--explain]": Run(("--budget", "50")),
    # the positioner
    "microconveyor compare --env MicroPositioner-v0 --targets 100 --seed 0 --budgets 3000 "
    "--plot docs/figures/compare_positioner.png": Run(COMPARE_POSITIONER, slow=True),
    "microconveyor compare --env MicroPositioner-v0 --targets 100 --seed 0 --budgets 3000":
        Run(COMPARE_POSITIONER, slow=True),
    "microconveyor imitate --env MicroPositioner-v0 --seed S": Run(IMITATE, {"S": "0"}),
    "microconveyor imitate --env MicroPositioner-v0 --seed S --out runs/dagger-sS":
        Run(IMITATE, {"S": "0"}),
    # one network for every request (the requested tolerance an input)
    "microconveyor imitate --env ID --requests 5e-6 10e-6 20e-6 50e-6":
        Run(REQUESTS, {"ID": "MicroPositioner-v0"}),
    "microconveyor imitate --env MicroPositioner-v0 --seed 0 --requests 5e-6 10e-6 20e-6 "
    "50e-6": Run(REQUESTS),
    "microconveyor imitate --env MicroConveyor2D-v1 --seed 0 --requests 5e-6 10e-6 20e-6 "
    "50e-6 --episodes 512": Run(REQUESTS),
    # training time (the refinement's settings cut in the test: `--refine` takes refine's
    # defaults)
    "microconveyor train --env MicroConveyor-v1 --refine": Run(TRAIN),
    "microconveyor train --env MicroConveyor-v1 --seed 0 --eval-freq 0": Run(TRAIN),
    # the provenance table
    "microconveyor record MicroConveyor-v0/ppo MicroConveyor-v0/ppo_randomised": Run(RECORD),
    "microconveyor record MicroConveyor-v1/ppo MicroConveyor-v1/ppo_randomised": Run(RECORD),
    "microconveyor record MicroConveyor-v1/ppo_refined": Run(RECORD),
    "microconveyor record MicroConveyor2D-v0/ppo": Run(RECORD),
    "microconveyor record MicroConveyor2D-v1/ppo": Run(RECORD),
    "microconveyor record MicroPositioner-v0/dagger": Run(RECORD),
    "microconveyor train --env MicroConveyor-v0 --seed S --out RUN --max-minutes 14.5":
        Run(TRAIN, {"S": "0", "RUN": "runs/v0_s0"}),
    "microconveyor train --env MicroConveyor-v1 --seed S --out RUN --eval-freq 250000":
        Run(TRAIN, {"S": "0", "RUN": "runs/s0"}),
    "microconveyor train --env MicroConveyor-v1 --seed S --out RUN --eval-freq 500000 "
    "[--steps 10000000]": Run(TRAIN, {"S": "1", "RUN": "runs/s1"}),
    "microconveyor refine RUN --out REFINED": Run(
        ("--targets", "4", "--rounds", "1", "--fit-iterations", "5", "--eval-targets", "2"),
        {"RUN": "runs/s1", "REFINED": "runs/s1_refined"}),
    "microconveyor train --env MicroConveyor2D-v0 --seed 1": Run(TRAIN),
    "microconveyor evaluate --env MicroConveyor2D-v0 --seed 2026": Run(("--targets", "2")),
}
# commands that need an earlier command's output, run in order in one test
CHAINS = [
    ("microconveyor train --env MicroConveyor2D-v1 --seed 1 --out RUN --eval-freq 2000000 "
     "--eval-targets 200",
     "microconveyor ship RUN MicroConveyor2D-v1/ppo"),
    ("microconveyor train --env MicroConveyor-v1 --seed S --out RUN --eval-freq 250000",
     "microconveyor train --env MicroConveyor-v1 --seed S --out RUN --eval-freq 500000 "
     "[--steps 10000000]",
     "microconveyor refine RUN --out REFINED",
     "microconveyor seeds RUN ...",
     "microconveyor seeds RUN ... --json"),
]
CHAINED = {cmd for chain in CHAINS for cmd in chain}


def filled(cmd: str) -> list[str]:
    """The quoted command's arguments (after ``microconveyor``), its placeholders filled and its
    optional options given; a placeholder without a value here fails."""
    run = RUNS[cmd]
    text = OPTIONAL.sub(r"\1", cmd).replace("...", run.fill.get("...", ""))
    missing = sorted({m.group(0) for m in PLACEHOLDER.finditer(text)} - set(run.fill))
    assert not missing, f"{cmd}: no value here for {missing}"
    text = PLACEHOLDER.sub(lambda m: run.fill[m.group(0)], text)
    words = shlex.split(text)[1:]
    # the shipped policies the command reads: the repository's (the run starts elsewhere)
    return [str(ROOT / w) if w.startswith("agents/policies/") else w for w in words]


def argv(cmd: str, tmp: Path) -> list[str]:
    """What runs: the filled command, then its tiny options."""
    return [*filled(cmd), *(a.format(tmp=tmp) for a in RUNS[cmd].tiny)]


def _guarded() -> dict[str, int]:
    """The stored results a command could write, by modification time."""
    files = [*(ROOT / "docs" / "figures").rglob("*"), *(ROOT / "agents" / "policies").rglob("*")]
    return {str(p.relative_to(ROOT)): p.stat().st_mtime_ns for p in files if p.is_file()}


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """The runs' folder: the current directory, with a copy of agents/policies to record and ship
    into; every evaluation of ``record`` and ``ship`` on at most two targets, and ``train
    --refine``'s refinement on a few targets, one round."""
    from agents.cli import rl
    from agents.rl.artefacts import shipping
    from agents.rl.refinement.settings import RefineSettings

    shutil.copytree(ROOT / "agents" / "policies", tmp_path / "policies",
                    ignore=shutil.ignore_patterns("__pycache__"))
    real_targets, real_refine = shipping.fixed_targets, rl._refine_folder
    monkeypatch.setattr(shipping, "fixed_targets",
                        lambda cfg, n, seed: real_targets(cfg, min(n, 2), seed))

    def refine_tiny(policy, out, settings, eval_targets):   # refine's defaults: train --refine
        if settings == RefineSettings():
            settings = dataclasses.replace(settings, targets=4, rounds=1, fit_iterations=5)
        return real_refine(policy, out, settings, eval_targets)

    monkeypatch.setattr(rl, "_refine_folder", refine_tiny)
    monkeypatch.chdir(tmp_path)
    before = _guarded()
    yield tmp_path
    after = _guarded()
    changed = sorted(k for k in {*before, *after} if before.get(k) != after.get(k))
    assert not changed, f"a command wrote into the repository: {changed}"


def _run(cmd: str, tmp: Path, capsys) -> None:
    from microconveyor_env.cli import main

    args = argv(cmd, tmp)
    status = main(args)
    err = capsys.readouterr().err
    assert status == 0, f"{cmd}\nmicroconveyor {shlex.join(args)}\n{err[-3000:]}"


def test_every_quoted_command_has_a_run():
    quoted = quoted_commands()
    assert quoted, "docs/results.md quotes no microconveyor command"
    missing = {c: lines for c, lines in quoted.items() if c not in RUNS}
    assert not missing, f"quoted commands (results.md lines) without a run here: {missing}"
    stale = sorted(set(RUNS) - set(quoted))
    assert not stale, f"runs of commands results.md does not quote: {stale}"


def _id(cmd: str) -> str:
    """``results.md:LINE:COMMAND`` (the first line that quotes it)."""
    lines = QUOTED.get(cmd)
    return f"results.md:{lines[0] if lines else '?'}:{cmd.split()[1]}"


QUOTED = quoted_commands()


@pytest.mark.parametrize("cmd", sorted(RUNS), ids=_id)
def test_quoted_command_parses(cmd, tmp_path):
    """The quote as it stands (placeholders filled) and with its tiny options: both parse."""
    from microconveyor_env.cli import build_parser
    from microconveyor_env.cli.base import attach_negative_values

    parser = build_parser()
    for args in (filled(cmd), argv(cmd, tmp_path)):
        parsed = parser.parse_args(attach_negative_values(args))
        assert parsed.command == args[0]


def _param(cmd: str):
    return pytest.param(cmd, marks=[pytest.mark.slow] if RUNS[cmd].slow else [], id=_id(cmd))


@pytest.mark.parametrize("cmd", [_param(c) for c in RUNS if c not in CHAINED])
def test_quoted_command_runs(cmd, workdir, capsys):
    _run(cmd, workdir, capsys)


@pytest.mark.parametrize("chain", CHAINS, ids=lambda c: f"{_id(c[0])}-{_id(c[-1])}")
def test_quoted_commands_in_order(chain, workdir, capsys):
    for cmd in chain:
        _run(cmd, workdir, capsys)
