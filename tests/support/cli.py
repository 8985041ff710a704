"""The ``microconveyor`` command run inside the test's process: what a subprocess would give
(exit status, stdout, stderr) without starting an interpreter and importing numba, scipy and
torch again. For tests of what a command does or refuses; a test of the process itself (the
console script's exit status, signals, kill -9, a closed pipe, imports from the working
folder) starts one."""
from __future__ import annotations

import contextlib
import io
import subprocess
import warnings

# Python's own filters outside ``__main__`` (a fresh interpreter's): these are ignored, every
# other warning is printed on stderr once per place
_IGNORED = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def run_cli(*args: object) -> subprocess.CompletedProcess:
    """``microconveyor *args`` through :func:`microconveyor_env.cli.main`, stdout and stderr
    captured as text (neither is a terminal, as with a subprocess's pipes) and warnings printed
    on that stderr under a fresh interpreter's filters (not pytest's), as a subprocess shows
    them."""
    from microconveyor_env.cli import main

    argv = [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings():
        warnings.resetwarnings()
        warnings.simplefilter("default")
        for category in _IGNORED:
            warnings.simplefilter("ignore", category)
        try:
            status = main(argv)
        except SystemExit as done:   # --help and --version end the command as a process would
            code = done.code
            status = 0 if code is None else code if isinstance(code, int) else 1
    return subprocess.CompletedProcess(argv, status, out.getvalue(), err.getvalue())
