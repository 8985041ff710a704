"""The lock: every dependency of the package and of every extra pinned in ``requirements-lock.txt``
(written by ``scripts/refresh_lock.sh``), inside the package's own ranges, and the one thing the
README's commands, the docs' install lines and ``.ci/run`` install from.

A dependency added to ``pyproject.toml`` without refreshing the lock fails here, before a new
release of it can break a fresh machine that CI's older packages hide."""
import re
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

try:
    import tomllib
except ImportError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "requirements-lock.txt"
INSTALL = re.compile(r"^python3 -m pip install (?P<opts>.*?)-e \"?\.", re.M)  # command lines


def _locked() -> dict[str, Version]:
    pins = {}
    for line in LOCK.read_text().splitlines():
        line = line.split("#")[0].strip()
        if not line:
            continue
        req = Requirement(line)
        (spec,) = req.specifier  # exactly one pin, ==
        assert spec.operator == "==" and not req.extras and req.marker is None, line
        pins[canonicalize_name(req.name)] = Version(spec.version)
    return pins


def _requirements() -> list[tuple[str, Requirement]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [("install", Requirement(r)) for r in project["dependencies"]]
    for extra, items in project["optional-dependencies"].items():
        reqs += [(extra, Requirement(r)) for r in items]
    return reqs


def test_every_requirement_of_every_extra_is_pinned_inside_its_range():
    pins = _locked()
    assert len(pins) > 50   # the whole tree, not only the direct requirements
    for where, req in _requirements():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req} ({where}) is not in {LOCK.name}: bash scripts/refresh_lock.sh"
        assert req.specifier.contains(pins[name], prereleases=True), \
            f"{LOCK.name} pins {name} {pins[name]}, outside {req} ({where})"


def test_torch_is_the_cpu_build_of_the_project_machines():
    assert _locked()["torch"].public == "2.13.0"


@pytest.mark.parametrize("page", ["README.md", "docs/index.md", "docs/getting-started.md",
                                  ".ci/run"])
def test_every_install_line_installs_from_the_lock(page):
    lines = [m.group("opts") for m in INSTALL.finditer((ROOT / page).read_text())]
    assert lines, f"{page} has no install line"
    for opts in lines:
        assert f"-c {LOCK.name}" in opts, f"{page}: `pip install {opts}-e .` ignores the lock"


def test_ci_builds_a_new_virtual_environment_and_runs_the_readme_test_command():
    ci = (ROOT / ".ci/run").read_text()
    readme = (ROOT / "README.md").read_text()
    command = next(line for line in readme.splitlines()
                   if "pip install" in line and "pytest" in line)
    assert "python3 -m venv" in ci and command.strip() in ci
