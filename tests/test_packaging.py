"""A real (non-editable) install: the wheel built offline from the source holds every module,
config file and shipped policy, and every command runs from it.

An editable install reads the source tree and hides a package left out of the distribution
(``microconveyor compare`` once failed from a wheel with "No module named 'agents.mpc'")."""
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SKIP = shutil.ignore_patterns(".git", "build", "dist", "*.egg-info", "__pycache__", "site",
                              "runs", "out", ".pytest_cache", ".mypy_cache", ".ruff_cache",
                              "tests")


# session: the test workers share out a module's tests, and a worker would build it again
# each time it comes back to the module
@pytest.fixture(scope="session")
def wheel(tmp_path_factory):
    pytest.importorskip("setuptools")
    pytest.importorskip("wheel")
    src = tmp_path_factory.mktemp("src") / "microconveyor-env"
    shutil.copytree(ROOT, src, ignore=SKIP)
    dist = tmp_path_factory.mktemp("dist")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-index",
                        "--no-build-isolation", "-q", "-w", str(dist), str(src)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = dist.glob("microconveyor_env-*.whl")
    return whl


def _source_files():
    """Paths the wheel must hold (as installed), from the source tree."""
    want = set()
    for pkg in ("microconveyor_env", "agents"):
        for p in (ROOT / pkg).rglob("*"):
            if p.is_file() and "__pycache__" not in p.parts and p.suffix in (".py", ".typed"):
                want.add(p.relative_to(ROOT).as_posix())
    for p in (ROOT / "configs").rglob("*"):
        if p.is_file() and p.suffix in (".py", ".yaml", ".yml"):
            want.add("microconveyor_env/" + p.relative_to(ROOT).as_posix())
    for p in (ROOT / "agents" / "policies").rglob("*"):
        if p.is_file():
            want.add(p.relative_to(ROOT).as_posix())
    return want


def test_the_wheel_holds_every_module_config_and_policy(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = sorted(_source_files() - names)
    assert not missing, f"left out of the wheel: {missing}"
    assert "microconveyor_env/configs/envs/MicroConveyor-v1.yaml" in names
    assert not any(n.startswith(("tests/", "configs/")) for n in names)   # nothing top-level


@pytest.mark.slow   # ~60 s; the wheel's contents are checked in the default suite (above)
def test_every_command_runs_from_the_installed_wheel(wheel, tmp_path):
    """Installed into a fresh venv (dependencies from this environment's site packages), away
    from the source tree: every module imports and ``microconveyor <cmd> --help`` works."""
    import sysconfig

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    py = venv / "bin" / "python"
    # the dependencies: this environment's site packages (a virtual environment's own, which
    # --system-site-packages would miss), after the venv's; a path named in a .pth file is
    # searched but its own .pth files are not run, so this tree's editable install stays out
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], capture_output=True, text=True, check=True).stdout
    deps = dict.fromkeys(sysconfig.get_paths()[k] for k in ("purelib", "platlib"))
    (Path(site.strip()) / "_test_dependencies.pth").write_text("\n".join(deps) + "\n")
    r = subprocess.run([str(py), "-m", "pip", "install", "--no-deps", "--no-index", "-q",
                        str(wheel)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    modules = sorted(n[:-3].replace("/", ".").removesuffix(".__init__")
                     for n in zipfile.ZipFile(wheel).namelist()
                     if n.endswith(".py") and n.startswith(("microconveyor_env/", "agents/"))
                     and not n.endswith("__main__.py"))   # importing it runs the command
    check = ("import importlib, sys, microconveyor_env\n"
             f"assert microconveyor_env.__file__.startswith({str(venv)!r}), "
             "microconveyor_env.__file__\n"
             "bad = []\n"
             "for m in sys.argv[1:]:\n"
             "    try:\n"
             "        importlib.import_module(m)\n"
             "    except Exception as exc:\n"
             "        bad.append(f'{m}: {type(exc).__name__}: {exc}')\n"
             "from microconveyor_env.cli import COMMANDS\n"
             "print(' '.join(sorted(COMMANDS)))\n"
             "assert not bad, bad\n")
    r = subprocess.run([str(py), "-c", check, *modules], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    commands = r.stdout.split()
    assert {"compare", "evaluate", "train", "demo", "refine", "tune"} <= set(commands)
    exe = venv / "bin" / "microconveyor"
    for cmd in commands:
        r = subprocess.run([str(exe), cmd, "--help"], capture_output=True, text=True,
                           timeout=120, cwd=tmp_path, env=env)
        assert r.returncode == 0 and "usage: microconveyor" in r.stdout, (cmd, r.stderr)
