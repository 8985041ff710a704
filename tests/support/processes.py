"""Waiting on subprocesses in tests: every wait bounded, nothing timed."""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

DEADLINE_S = 300   # bounds every wait on a subprocess (a hang fails the test, nothing is timed)


def wait_for(cond: Callable[[], Any], what: str, deadline_s: float = DEADLINE_S,
             poll_s: float = 0.05) -> Any:
    """``cond()``'s first truthy value, polled every ``poll_s`` s; AssertionError naming
    ``what`` after ``deadline_s`` s."""
    t_end = time.monotonic() + deadline_s
    while time.monotonic() < t_end:
        got = cond()
        if got:
            return got
        time.sleep(poll_s)
    raise AssertionError(f"gave up waiting ({deadline_s} s) for {what}")
