"""numba's on-disk cache: damaged entries are discarded and recompiled (once, with a note on
stderr); a read-only install without a writable HOME still imports and runs.

Every test works on a temporary *copy* of the package in a subprocess, so the caches of the
installed package are never touched.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import microconveyor_env

PKG = Path(microconveyor_env.__file__).resolve().parent
CONFIGS = PKG.parent / "configs"
# surface_eval calls shape_eval and stroke_eval: a small, quick compile that still has callees
PROBE = ("from microconveyor_env.physics import kinematics as k\n"
         "print(repr(k.surface_eval(1e-5, 2e-4, 0.0, 1000.0, 1e-4, 0, 6e-4)))\n")


def _copy_package(dest: Path) -> Path:
    root = dest / "site"
    shutil.copytree(PKG, root / "microconveyor_env",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    if not (root / "microconveyor_env" / "configs").exists():
        shutil.copytree(CONFIGS, root / "microconveyor_env" / "configs",
                        ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _run(root: Path, code: str, **env_changes) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHON"))}
    env.update(PYTHONPATH=str(root), MICROCONVEYOR_CACHE_DIR=str(root.parent / "tables"))
    env.update(env_changes)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       cwd=root.parent, timeout=300)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def warm_copy(tmp_path_factory):
    """A copy of the package whose probe functions are compiled and cached in its __pycache__."""
    root = _copy_package(tmp_path_factory.mktemp("pkg"))
    first = _run(root, PROBE)
    cache = root / "microconveyor_env" / "physics" / "__pycache__"
    assert list(cache.glob("kinematics.surface_eval-*.nbi"))
    return root, first.stdout


def _damage_and_rerun(root: Path, expected: str, damage, check_healed: bool) -> str:
    cache = root / "microconveyor_env" / "physics" / "__pycache__"
    damage(cache)
    again = _run(root, PROBE)
    assert again.stdout == expected
    if check_healed:  # recovered for good: a good copy with checksums, no further complaint
        clean = _run(root, PROBE)
        assert clean.stdout == expected and "damaged" not in clean.stderr, clean.stderr
    return again.stderr


def _one(cache: Path, pattern: str) -> Path:
    (p,) = cache.glob(pattern)
    return p


def _truncate_index(cache):
    p = _one(cache, "kinematics.surface_eval-*.nbi")
    p.write_bytes(p.read_bytes()[:10])


def _flip_data_byte(cache):
    p = _one(cache, "kinematics.surface_eval-*.1.nbc")
    b = bytearray(p.read_bytes())
    b[len(b) // 2] ^= 0xFF
    p.write_bytes(bytes(b))


def _swap_data(cache):
    shutil.copyfile(_one(cache, "kinematics.shape_eval-*.1.nbc"),
                    _one(cache, "kinematics.surface_eval-*.1.nbc"))


@pytest.mark.parametrize("damage", [_truncate_index, _flip_data_byte, _swap_data],
                         ids=["truncated-nbi", "flipped-nbc-byte", "swapped-nbc"])
def test_damaged_numba_cache_recovers_and_says_so(warm_copy, damage):
    root, expected = warm_copy
    err = _damage_and_rerun(root, expected, damage, check_healed=damage is _truncate_index)
    assert "damaged numba cache" in err and "surface_eval" in err and "recompiling" in err
    assert "Traceback" not in err


def test_cache_without_checksums_is_discarded_quietly(warm_copy):
    """Entries written by an older version (no checksum file) are recompiled without noise."""
    root, expected = warm_copy
    err = _damage_and_rerun(root, expected, lambda c: [p.unlink() for p in c.glob("*.nbi.sha256")],
                            check_healed=True)
    assert "damaged" not in err


def _unwritable_everywhere(tmp_path):
    """As root, permissions do not stop writes: block every cache location with plain files."""
    root = _copy_package(tmp_path)
    for sub in ("", "physics", "envs", "studies"):
        (root / "microconveyor_env" / sub / "__pycache__").write_text("")
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    env = {"HOME": str(blocker / "home"), "XDG_CACHE_HOME": str(blocker / "xdg"),
           "MICROCONVEYOR_CACHE_DIR": str(blocker / "tables")}
    return root, blocker, env


def test_read_only_install_falls_back_to_a_private_temp_cache(tmp_path):
    root, _, env = _unwritable_everywhere(tmp_path)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    code = PROBE + "print(k.surface_eval._cache.cache_path)\n"
    r = _run(root, code, TMPDIR=str(tmp), **env)
    assert str(tmp / "microconveyor-env-numba-") in r.stdout
    user_dir = next(tmp.glob("microconveyor-env-numba-*"))
    assert oct(user_dir.stat().st_mode & 0o777) == oct(0o700)
    assert list(user_dir.rglob("kinematics.surface_eval-*.nbc"))
    r2 = _run(root, code, TMPDIR=str(tmp), **env)  # and the cache is used again
    assert r2.stdout == r.stdout


def test_nothing_writable_runs_uncached(tmp_path):
    root, blocker, env = _unwritable_everywhere(tmp_path)
    code = f"import tempfile; tempfile.tempdir = {str(blocker / 'tmp')!r}\n" + PROBE + \
        "print(type(k.surface_eval._cache).__name__)\n"
    r = _run(root, code, **env)
    assert r.stdout.strip().endswith("NullCache")


@pytest.mark.slow
def test_cli_recovers_from_damaged_kernel_index(tmp_path):
    """The issue's example: every .nbi of the kernel truncated, then ``simulate --json``."""
    import json

    root = _copy_package(tmp_path)
    code = "import sys; from microconveyor_env.cli import main; sys.exit(main(sys.argv[1:]))"
    args = ["simulate", "--json"]
    first = _run(root, f"import sys; sys.argv[1:] = {args!r}\n" + code)
    for p in (root / "microconveyor_env").rglob("*.nbi"):
        p.write_bytes(p.read_bytes()[:7])
    again = _run(root, f"import sys; sys.argv[1:] = {args!r}\n" + code)
    assert json.loads(again.stdout)["final_position_m"] == json.loads(first.stdout)["final_position_m"]
    assert "damaged numba cache" in again.stderr
