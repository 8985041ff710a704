"""The documentation site (mkdocs.yml) builds with warnings as errors, its CLI reference covers
every command, and the Python examples of docs/examples.md, docs/getting-started.md and
docs/env.md run as written (each block in a fresh interpreter, as tests/test_readme.py runs the
README's)."""
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from support.scripts import load_script
from support.snippets import assert_snippet_runs

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_PAGES = ("examples.md", "getting-started.md", "env.md")
BLOCKS = [(page, code) for page in EXAMPLE_PAGES
          for code in re.findall(r"```python\n(.*?)```", (ROOT / "docs" / page).read_text(),
                                 flags=re.S)]


# session: the test workers share out a module's tests, and a worker would build it again
# each time it comes back to the module
@pytest.fixture(scope="session")
def site(tmp_path_factory):
    """The site, built by ``mkdocs build --strict`` into a temporary folder."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip("mkdocs is not installed (it comes with the dev extra: pip install -e '.[dev]')")
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                        str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    return out


def test_site_builds_strict_with_every_page(site):
    pages = {p.with_suffix("").name for p in (ROOT / "docs").glob("*.md")} - {"index"}
    for page in sorted(pages) + ["cli-reference", "api/simulator", "api/envs", "api/policies"]:
        assert (site / page / "index.html").is_file(), page
    assert (site / "index.html").is_file()
    api = (site / "api" / "envs" / "index.html").read_text()
    for name in ("MicroConveyorEnv", "MicroConveyorVectorEnv", "MicroConveyorGoalEnv",
                 "EnvConfig", "env_config"):
        assert name in api, name
    assert "shipped_path" in (site / "api" / "policies" / "index.html").read_text()


def test_docstring_roles_are_not_shown_raw(site):
    for page in (site / "api").rglob("*.html"):
        assert not re.search(r":(func|class|mod|meth|attr):<code>", page.read_text()), page


def test_cli_reference_has_every_command(site):
    from microconveyor_env.cli import COMMANDS  # the agents' too (entry point)

    html = (site / "cli-reference" / "index.html").read_text()
    for name in COMMANDS:
        assert f'id="{name}"' in html, name
        assert f"usage: microconveyor {name}" in html, name


def test_cli_reference_does_not_depend_on_the_terminal(monkeypatch):
    from microconveyor_env.cli import COMMANDS

    gen = load_script("gen_cli_reference")
    monkeypatch.setenv("COLUMNS", "40")
    narrow = gen.reference()
    monkeypatch.setenv("COLUMNS", "200")
    assert gen.reference() == narrow
    assert narrow.startswith("# CLI reference")
    assert all(f"\n## {name}\n" in narrow for name in COMMANDS)


def test_role_hook_shortens_as_sphinx_does():
    strip = load_script("docs_sphinx_roles").strip_roles
    assert strip(":class:<code>~.physics.simulator.Simulator</code>") == "<code>Simulator</code>"
    assert strip(":mod:<code>.threads</code> and :func:<code>a.b</code>") == (
        "<code>threads</code> and <code>a.b</code>")


def test_examples_are_there():
    assert sum(page == "examples.md" for page, _ in BLOCKS) >= 4
    assert sum(page == "env.md" for page, _ in BLOCKS) >= 7


# env.md's SAC + HER block trains for ~10 s: it runs with the slow tests;
# tests/envs/test_goal_env.py::test_her_trains_a_few_hundred_steps trains the same model (SAC with
# a HerReplayBuffer on MicroConveyorGoal-v1) in the default suite. env.md's two video blocks
# (rendering a whole episode frame by frame and encoding it, 10-50 s in a loaded session) run
# with the slow tests too; tests/envs/test_render.py (RecordStrokeVideo) and tests/cli/
# test_video.py (write_video through the video command) cover both in the default suite
SLOW_BLOCKS = ("HerReplayBuffer", "write_video(frames", "RecordStrokeVideo(")


@pytest.mark.parametrize("page, code", [
    pytest.param(p, c, id=f"{p}-{i}",
                 marks=[pytest.mark.slow] if any(w in c for w in SLOW_BLOCKS) else [])
    for i, (p, c) in enumerate(BLOCKS)])
def test_example_runs(page, code, tmp_path):
    assert_snippet_runs(code, tmp_path, timeout=300)
