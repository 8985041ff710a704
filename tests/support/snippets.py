"""Running a documentation page's Python block as a reader would: in a fresh interpreter."""
import os
import subprocess
import sys

import pytest


def assert_snippet_runs(code: str, cwd, timeout: float = 600) -> None:
    """``code`` runs in a fresh interpreter in ``cwd``, exits 0 and prints what it shows (a
    block using the agents package is skipped without stable-baselines3)."""
    if "agents." in code:
        pytest.importorskip("stable_baselines3")
    # one OpenMP thread (torch's and BLAS's pools; numba's is its own): the suite's workers share
    # the cores, and torch's default of a thread per core spent 3.5 times the CPU of one thread
    # on env.md's SAC block on the loaded 2-core machine; what a block prints does not depend
    # on it
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=timeout, cwd=cwd, env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip(), "each block prints what it shows"
