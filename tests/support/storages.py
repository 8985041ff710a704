"""Opening one Optuna storage from several processes at the same instant, as commands on
several machines would (tests of ``tune``'s storages: SQLite and PostgreSQL)."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from .processes import DEADLINE_S


def open_at_once(url: str, n: int, tmp_path: Path, imports: str = "") -> list[str]:
    """``n`` processes open the storage at ``url`` at the same instant (each waits, imported
    and ready, for a file to appear; ``imports``: modules each imports first, e.g. the database
    driver); what each printed: ``ok`` or its error."""
    go = tmp_path / f"go-{time.monotonic_ns()}"
    code = (f"import os, sys, time\nimport optuna{', ' + imports if imports else ''}\n"
            "from agents.rl.tuning.storage import open_storage\n"
            "optuna.storages.RDBStorage('sqlite://')\n"  # every import done: they start together
            "print('ready', flush=True)\n"
            f"while not os.path.exists({str(go)!r}): time.sleep(0.001)\n"
            "try:\n"
            f"    open_storage({url!r})\n    print('ok')\n"
            "except Exception as e:\n    print(type(e).__name__, str(e).splitlines()[0])\n")
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
             for _ in range(n)]
    try:
        for p in procs:
            assert p.stdout is not None and p.stdout.readline().strip() == "ready"
        go.write_text("")
        return [p.communicate(timeout=DEADLINE_S)[0].strip() for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
