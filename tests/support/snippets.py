"""Running a documentation page's Python block as a reader would: in a fresh interpreter."""
import subprocess
import sys

import pytest


def assert_snippet_runs(code: str, cwd, timeout: float = 600) -> None:
    """``code`` runs in a fresh interpreter in ``cwd``, exits 0 and prints what it shows (a
    block using the agents package is skipped without stable-baselines3)."""
    if "agents." in code:
        pytest.importorskip("stable_baselines3")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=timeout, cwd=cwd)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip(), "each block prints what it shows"
