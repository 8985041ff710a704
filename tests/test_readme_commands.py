"""The README's shell examples run as written, with a shorter budget where one is needed (options
appended to the README's own line; argparse keeps the last value of an option). Every
``microconveyor`` line of the README's ``bash`` blocks must have an entry here, so an example
added to the README without a test fails."""
import contextlib
import re
from pathlib import Path

import pytest
from support.cli import run_cli

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```bash\n(.*?)```", README.read_text(), flags=re.S)
LINES = [line.split("  #")[0].strip() for block in BLOCKS for line in block.splitlines()
         if line.startswith("microconveyor ")]

TINY = ["--steps", "256", "--eval-freq", "0", "--eval-targets", "2", "--no-progress"]
# what each README line gets appended so that it runs in seconds; None: it runs as it is
SHORTER = {
    "microconveyor demo": ["--out", "out", "--targets", "2e-3", "--gif-target", "0"],
    "microconveyor place --target 9e-3 --method mpc": ["--mpc-budgets", "200,50"],
    "microconveyor train --out runs/v1": TINY,
    "microconveyor refine runs/v1 --out runs/v1_refined": ["--targets", "4", "--rounds", "1",
                                                           "--eval-targets", "2"],
    "microconveyor train --env MicroConveyor2D-v0 --out runs/plane": TINY,
    "microconveyor train --algo sac --env MicroConveyorGoal-v1 --out runs/sac": TINY,
    "microconveyor imitate --out runs/v1_dagger": ["--rounds", "1", "--episodes", "2"],
    "microconveyor imitate --env MicroPositioner-v0 --out runs/dagger": ["--rounds", "1",
                                                                         "--episodes", "2"],
    "microconveyor imitate --env MicroConveyor2D-v1 --out runs/plane_dagger": ["--rounds", "1",
                                                                               "--episodes", "2"],
    "microconveyor evaluate --targets 1000 --seed 1 --json": ["--targets", "10"],
    "microconveyor compare --mpc-prior shipped --plot out/c.png": [
        "--targets", "2", "--budgets", "20", "--mpc-budgets", "20,10", "--noise", "0.003",
        "--spread", "0.05", "--randomised-policy", ""],
}
# lines that need an earlier line's output, in README order
CHAINS = [("microconveyor train --out runs/v1",
           "microconveyor refine runs/v1 --out runs/v1_refined")]
CHAINED = {line for chain in CHAINS for line in chain}


def _run(line: str, cwd: Path) -> None:
    """The line in ``cwd``, in this process (the console script's process: tests/cli)."""
    argv = [*line.split()[1:], *SHORTER[line]]
    with contextlib.chdir(cwd):
        r = run_cli(*argv)
    assert r.returncode == 0, f"{line} {' '.join(SHORTER[line])}\n{r.stderr[-3000:]}"


def test_every_readme_command_has_a_test():
    assert LINES, "the README shows no microconveyor command"
    assert sorted(set(LINES)) == sorted(SHORTER), "README commands and this test disagree"


# compare (~30 s even with tiny budgets) runs with the slow tests; tests/agents/test_compare.py
# covers its code in the default suite
SLOW = {"microconveyor compare --mpc-prior shipped --plot out/c.png"}


@pytest.mark.parametrize("line", [pytest.param(line, marks=pytest.mark.slow) if line in SLOW
                                  else line for line in LINES if line not in CHAINED])
def test_readme_command_runs(line, tmp_path):
    _run(line, tmp_path)


@pytest.mark.parametrize("chain", CHAINS, ids=lambda c: c[0].split()[1])
def test_readme_commands_in_order(chain, tmp_path):
    for line in chain:
        _run(line, tmp_path)
