"""Every command that README.md and docs/*.md give to reproduce a stored result or a figure with a
script (``python scripts/...``, ``python benchmarks/...``), and every usage line of a script's
docstring, runs: each as quoted (``nice``, ``taskset`` and variables before ``python`` dropped,
``...`` filled in), on a tiny budget, writing under a temporary folder.

The budget: options appended to the quoted line (argparse keeps an option's last value), listed
per command in :data:`RUNS`; an option a command needs only to run in seconds (``--quick``,
``--imitate-args``, ``--budgets``, ``--page``, ``--root``) is the script's own. The outputs: the
appended options point every file the command writes into the temporary folder (the runs start
there), and the test fails when a stored result (``docs/figures``, ``agents/policies``) or a
page a script writes changed. A quoted command
without an entry here fails ``test_every_quoted_command_has_a_run``.

The commands that record and ship policies are package commands (``microconveyor record``,
``microconveyor ship``): tests/test_ship_commands.py runs them; the README's ``microconveyor``
lines: tests/test_readme_commands.py.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SCRIPT_FILES = sorted([*(ROOT / "scripts").glob("*.py"), *(ROOT / "benchmarks").glob("*.py")])
# a quoted command: optional prefixes (nice, taskset, VAR=value), python, a script, its options
QUOTED = re.compile(r"`((?:nice |taskset -c \d+ |[A-Z_]+=\S+ )*python3? "
                    r"(?:scripts|benchmarks)/[\w./-]+\.py[^`]*)`")
PREFIX = re.compile(r"^(?:nice |taskset -c \d+ |[A-Z_]+=\S+ )*python3? ")
POLICY = str(ROOT / "agents/policies/MicroPositioner-v0/dagger")
SHIPPED_V1 = str(ROOT / "agents/policies/MicroConveyor-v1/ppo")
IMITATE_TINY = "--rounds 1 --episodes 2"


def normalise(cmd: str) -> str:
    """``python SCRIPT ARGS`` of a quoted command (prefixes dropped, whitespace collapsed)."""
    return "python " + PREFIX.sub("", " ".join(cmd.split()))


def quoted_in_pages() -> dict[str, list[str]]:
    """Every script command quoted in README.md and docs/*.md -> where (page:line)."""
    out: dict[str, list[str]] = {}
    for page in PAGES:
        text = page.read_text()
        for m in QUOTED.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            out.setdefault(normalise(m.group(1)), []).append(f"{page.name}:{line}")
    return out


def docstring_usage() -> dict[str, list[str]]:
    """Every usage line of a script's module docstring (``python scripts/X.py ...``, optional
    options in brackets dropped, continuation lines joined) -> the script."""
    import ast

    out: dict[str, list[str]] = {}
    for path in SCRIPT_FILES:
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        doc = re.sub(r"\\\n\s*", " ", doc)
        for line in doc.splitlines():
            m = re.match(r"\s*((?:nice |taskset -c \d+ |[A-Z_]+=\S+ )*python3? "
                         r"(?:scripts|benchmarks)/[\w.]+\.py.*?)(?:\s+#.*)?$", line)
            found = [m.group(1)] if m else []
            found += re.findall(r"``((?:nice |[A-Z_]+=\S+ )*python3? (?:scripts|benchmarks)/"
                                r"[\w.]+\.py[^`]*)``", line)
            for cmd in found:
                cmd = re.sub(r"\s*\[[^\]]*\]", "", cmd)   # optional options
                out.setdefault(normalise(cmd), []).append(f"{path.parent.name}/{path.name}")
    return out


# quoted command -> what is appended to it (None: the command needs no budget); {out}: the
# temporary folder. Commands sharing a script share its tiny options.
ANSWER = ["--per-distance", "1", "--noise-seeds", "1", "--de-budget", "30", "--out",
          "{out}/answer.json"]
IMITATE = ["--seeds", "0", "--cpu", "-1", "--targets", "2", "--imitate-args", IMITATE_TINY]
KERNEL = ["--firings", "16", "--repeats", "1", "--rounds", "1", "--json", "{out}/kernel.json"]
SAC = ["--steps", "200", "--repeats", "1", "--out", "{out}/sac.json"]
SIZING = ["--spacings", "0.5", "--targets", "2", "--out", "{out}/sizing.json"]
BREAKDOWN = ["--steps", "4096", "--refine-rounds", "1", "--no-progress", "--json",
             "{out}/breakdown.json"]
DISSERTATION = ["--seeds", "1", "--long-seeds", "1", "--budgets", "100,200", "--explain-seeds",
                "1", "--figures", "{out}", "--out", "{out}/diss.json"]
RUNS: dict[str, list[str] | None] = {
    "python scripts/answer_table.py --per-distance 5 --noise-seeds 10 --sigma 0.003": ANSWER,
    "python scripts/answer_table.py": ANSWER,
    "python scripts/answer_table.py --out docs/figures/answer_table.json": ANSWER,
    "python scripts/materials_table.py --write": ["--page", "{out}/physics.md"],
    "python scripts/materials_table.py": None,
    "python scripts/materials_table.py --json": None,
    "python scripts/results_tables.py": ["--root", "{out}"],
    "python scripts/results_tables.py --check": None,
    "python scripts/results_tables.py --root DIR": ["--root", "{out}"],
    "python scripts/launch_noise_bound.py": ["--targets", "2", "--quick", "--out",
                                             "{out}/bound.json"],
    "python scripts/launch_noise_bound.py --sigma 3e-3 --targets 2,4,6,8,10 --out "
    "docs/figures/launch_noise_bound_v1.json": ["--targets", "2", "--quick", "--out",
                                                "{out}/bound.json"],
    "python scripts/plane_figures.py": ["--out", "{out}/plane"],
    "python scripts/plane_figures.py --firings": ["--targets", "2", "--out", "{out}/firings.json"],
    "python scripts/planner_speed.py --noise-seeds 3 --positioner-targets 100 --compare-with "
    "/tmp/old --out docs/figures/planner_speed.json": [
        "--noise-seeds", "1", "--per-distance", "1", "--positioner-targets", "2",
        "--compare-with", str(ROOT), "--out", "{out}/ps.json"],
    "python scripts/planner_speed.py": ["--noise-seeds", "1", "--per-distance", "1",
                                        "--positioner-targets", "2", "--out", "{out}/ps.json"],
    "python benchmarks/kernel_speed.py": KERNEL,
    # the other checkout: this one (the test runs both sides of the A/B on one tree)
    "python benchmarks/kernel_speed.py --compare-with /tmp/base": [*KERNEL, "--compare-with",
                                                                    str(ROOT)],
    "python benchmarks/positioner_expert.py": ["--states", "8", "--grids", "9x3"],
    "python scripts/sac_threads.py --steps 3000 --repeats 2": SAC,
    "python scripts/sac_threads.py": SAC,
    "python scripts/dissertation_study.py": DISSERTATION,
    "python scripts/positioner_sizing.py --out docs/figures/positioner_sizing.json": SIZING,
    "python scripts/positioner_sizing.py": SIZING,
    # the runs of `microconveyor imitate --env MicroPositioner-v0 --seed S` replaced by the
    # shipped policy's folder
    "python scripts/positioner_policies.py runs/dagger-s0 runs/dagger-s1 runs/dagger-s2 runs/da"
    "gger-s3 runs/dagger-s4 runs/dagger-s5 runs/dagger-s6 runs/dagger-s7 runs/dagger-s8 runs/dagger-s9 --targets 1000 --seed 1 --out docs/figures/positioner_seeds.json": [
        "--targets", "2", "--out", "{out}/seeds.json"],
    "python scripts/positioner_policies.py": [POLICY, "--targets", "2", "--out",
                                              "{out}/seeds.json"],
    "python scripts/positioner_policies.py runs/dagger-s0 runs/dagger-s1 runs/dagger-s2": [
        "--targets", "2", "--out", "{out}/seeds.json"],
    "python scripts/plane_scene_scan.py": ["--samples", "2"],
    "python benchmarks/dagger_breakdown.py": ["--rounds", "1", "--episodes", "4", "--json",
                                              "{out}/breakdown.json"],
    "python benchmarks/dagger_breakdown.py --env MicroConveyor2D-v1 --json "
    "docs/figures/dagger_breakdown_plane.json": ["--rounds", "1", "--episodes", "4", "--json",
                                                 "{out}/breakdown.json"],
    "python benchmarks/dagger_breakdown.py --env MicroPositioner-v0 --json "
    "docs/figures/dagger_breakdown_positioner.json": ["--rounds", "1", "--episodes", "4",
                                                      "--json", "{out}/breakdown.json"],
    "python scripts/optimize_budget.py": ["--targets", "1", "--budgets", "20", "--out",
                                          "{out}/budget.json", "--plot", "{out}/budget.png"],
    "python scripts/frontier.py --env MicroConveyor-v1 --out docs/figures/frontier_line.json "
    "--plot docs/figures/frontier_line.png": [
        "--targets", "2", "--methods", "ppo_refined", "staged_expert", "--levels", "nominal",
        "--requests-um", "50", "10", "--out", "{out}/frontier.json", "--plot",
        "{out}/frontier.png"],
    "python scripts/frontier.py --env MicroPositioner-v0 --out "
    "docs/figures/frontier_positioner.json --plot docs/figures/frontier_positioner.png": [
        "--targets", "2", "--methods", "dagger_request", "--levels", "nominal",
        "--requests-um", "50", "10", "--out", "{out}/frontier.json", "--plot",
        "{out}/frontier.png"],
    "python scripts/frontier.py --env MicroConveyor2D-v1 --out docs/figures/frontier_plane.json "
    "--plot docs/figures/frontier_plane.png": [
        "--targets", "2", "--methods", "plane_controller", "--levels", "nominal",
        "--requests-um", "50", "--out", "{out}/frontier.json", "--plot", "{out}/frontier.png"],
    "python scripts/frontier.py --plot-only --out docs/figures/frontier_line.json --plot "
    "docs/figures/frontier_line.png": [
        "--out", str(ROOT / "docs/figures/frontier_line.json"), "--plot", "{out}/frontier.png"],
    "python scripts/fork_outcomes.py --out docs/figures/ppo_v1_forks \"the "
    "recipe=runs/rec_s0_f21,runs/rec_s1_f21\" \"target KL 0.03=runs/kl_s0_f21\"": [
        "--out", "{out}/forks"],
    "python scripts/gen_cli_reference.py": ["{out}/cli.md"],
    "python benchmarks/scene_step_cost.py --rounds 3 --seconds 2": [
        "--rounds", "1", "--seconds", "0.05", "--num-envs", "2"],
    "python benchmarks/scene_step_cost.py": ["--rounds", "1", "--seconds", "0.05",
                                             "--num-envs", "2"],
    "python benchmarks/env_speed.py": ["--seconds", "0.05", "--num-envs", "2", "--no-load"],
    "python benchmarks/optimize_speed.py": ["--repeats", "1"],
    "python benchmarks/train_speed.py": ["--steps", "512", "--threads", "1", "--loads", "idle"],
    "python benchmarks/train_time_breakdown.py --json /tmp/mv/train_time_breakdown.json":
        BREAKDOWN,
    "python benchmarks/train_time_breakdown.py": BREAKDOWN,
    "python benchmarks/time_to_bar.py --minutes 5 --seeds 0 1 2 --jobs 1 --out runs/ttb": [
        "--minutes", "0.05", "--seeds", "0", "--methods", "ppo", "--targets", "2"],
    "python benchmarks/time_to_bar.py --aggregate-only --out runs/ttb": None,
    "python benchmarks/imitate_wall_time.py --seeds 0-9 --out runs/imitate-bench --json "
    "docs/figures/imitate_v1_seeds.json": [*IMITATE, "--json", "{out}/seeds.json"],
    "python benchmarks/imitate_wall_time.py --seeds 0-9": IMITATE,
    "python benchmarks/imitate_wall_time.py --seeds 0-9 --parallel-cpus 0,1 --out "
    "runs/imitate-nothing --json docs/figures/imitate_v1_nothing_seeds.json": [
        "--seeds", "0-1", "--targets", "2", "--imitate-args", IMITATE_TINY, "--out",
        "{out}/bench", "--json", "{out}/seeds.json"],
}
# the positional folders a quoted command names, replaced by ones that exist here
# longest first: the ten-seed list is replaced whole, the three-seed list inside shorter commands
SUBSTITUTE = {" ".join(f"runs/dagger-s{s}" for s in range(10)): POLICY,
              "runs/dagger-s0 runs/dagger-s1 runs/dagger-s2": POLICY,
              "runs/rec_s0_f21,runs/rec_s1_f21": SHIPPED_V1,
              "runs/kl_s0_f21": str(ROOT / "agents/policies/MicroConveyor-v1/ppo_refined")}
# commands that need an earlier command's output (in order); run together
CHAINS = [
    ("python benchmarks/imitate_wall_time.py --seeds 0-9 --out runs/imitate-bench --json "
     "docs/figures/imitate_v1_seeds.json",
     "python benchmarks/imitate_wall_time.py --seeds 0-4 --cpu 1 --out /tmp/mv/scalar "
     "--compare-with /tmp/mv/bench10 --json /tmp/mv/imitate_v1_code_paths.json",
     "python benchmarks/imitate_wall_time.py --compare-with ..."),
    ("python benchmarks/time_to_bar.py --minutes 5 --seeds 0 1 2 --jobs 1 --out runs/ttb",
     "python benchmarks/time_to_bar.py --aggregate-only --out runs/ttb"),
]
RUNS.update({
    CHAINS[0][1]: ["--seeds", "0", "--cpu", "-1", "--targets", "2", "--imitate-args",
                   IMITATE_TINY, "--out", "runs/scalar", "--compare-with", "runs/imitate-bench",
                   "--json", "{out}/paths.json"],
    CHAINS[0][2]: ["--seeds", "0", "--cpu", "-1", "--targets", "2", "--imitate-args",
                   IMITATE_TINY, "--out", "runs/scalar2", "--json", "{out}/paths2.json"],
})
# "..." in a quoted command: what it stands for here
ELLIPSIS = {CHAINS[0][2]: "runs/imitate-bench"}
CHAINED = {c for chain in CHAINS for c in chain}
# the runs of the default suite (each under 20 s on the 2-core machine, loaded; one run per
# script where several quote it); the others run with the slow tests
FAST = {"python scripts/results_tables.py --root DIR",
        "python scripts/plane_figures.py", "python scripts/plane_scene_scan.py",
        "python scripts/gen_cli_reference.py",
        "python scripts/fork_outcomes.py --out docs/figures/ppo_v1_forks \"the "
        "recipe=runs/rec_s0_f21,runs/rec_s1_f21\" \"target KL 0.03=runs/kl_s0_f21\"",
        "python scripts/positioner_policies.py", "python benchmarks/env_speed.py",
        "python benchmarks/scene_step_cost.py --rounds 3 --seconds 2",
        "python scripts/positioner_sizing.py --out docs/figures/positioner_sizing.json"}


def _argv(cmd: str, out: Path) -> list[str]:
    import shlex

    text = cmd
    for quoted, here in SUBSTITUTE.items():
        text = text.replace(quoted, here)
    text = text.replace("...", ELLIPSIS.get(cmd, ""))
    words = shlex.split(text)[1:]
    words[0] = str(ROOT / words[0])
    return [sys.executable, *words, *(a.format(out=out) for a in RUNS[cmd] or [])]


def _guarded() -> dict[str, float]:
    """The stored results and the pages a command may write, by their modification time."""
    files = [*(ROOT / "docs" / "figures").rglob("*"), *(ROOT / "agents" / "policies").rglob("*"),
             ROOT / "README.md", ROOT / "docs" / "physics.md", ROOT / "docs" / "results.md"]
    return {str(p.relative_to(ROOT)): p.stat().st_mtime for p in files if p.is_file()}


def _run(cmd: str, tmp: Path) -> None:
    out = tmp / "out"
    out.mkdir(exist_ok=True)
    if "results_tables" in cmd and "--check" not in cmd:   # a copy of the pages to rewrite
        shutil.copy(ROOT / "README.md", out / "README.md")
        (out / "docs").mkdir(exist_ok=True)
        for page in (ROOT / "docs").glob("*.md"):
            shutil.copy(page, out / "docs" / page.name)
    if "materials_table.py --write" in cmd:
        shutil.copy(ROOT / "docs" / "physics.md", out / "physics.md")
    before = _guarded()
    argv = _argv(cmd, out)
    r = subprocess.run(argv, cwd=tmp, capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, f"{cmd}\n{' '.join(argv)}\n{r.stderr[-3000:]}"
    after = _guarded()
    changed = sorted(k for k in {*before, *after} if before.get(k) != after.get(k))
    assert not changed, f"{cmd} wrote into the repository: {changed}"


def test_every_quoted_command_has_a_run():
    quoted = {**quoted_in_pages(), **docstring_usage()}
    assert quoted, "no script command quoted"
    missing = {c: where for c, where in quoted.items() if c not in RUNS}
    assert not missing, f"quoted commands without a run here: {missing}"
    stale = set(RUNS) - set(quoted)
    assert not stale, f"runs of commands no page or docstring quotes: {sorted(stale)}"


def test_every_script_has_a_quoted_command():
    named = {c.split()[1] for c in RUNS}
    files = {f"{p.parent.name}/{p.name}" for p in SCRIPT_FILES}
    # the MkDocs hooks run inside `mkdocs build` (tests/test_docs.py), not from a shell
    hooks = {"scripts/docs_sphinx_roles.py"}
    assert files - hooks <= named, sorted(files - hooks - named)


def _param(cmd: str):
    return cmd if cmd in FAST else pytest.param(cmd, marks=pytest.mark.slow)


@pytest.mark.parametrize("cmd", [_param(c) for c in RUNS if c not in CHAINED])
def test_quoted_command_runs(cmd, tmp_path):
    pytest.importorskip("stable_baselines3")
    _run(cmd, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("chain", CHAINS, ids=lambda c: c[0].split()[1])
def test_quoted_commands_in_order(chain, tmp_path):
    pytest.importorskip("stable_baselines3")
    for cmd in chain:
        _run(cmd, tmp_path)
