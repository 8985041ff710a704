"""How the batched env uses threads: a serial loop or numba's parallel loop, chosen by measurement.

numba's parallel region pays off on an idle machine, but when other processes keep the cores busy
(PPO's learner, an evaluation, a browser) its worker threads wait for each other and one batched
step can be many times slower than the plain loop. No fixed rule is right on every machine, so the
automatic mode (``num_threads=None``) *measures*: it keeps a running mean of the wall time per
firing of each choice, uses the faster one, and re-tries the other one every ``PROBE_EVERY``
steps, so it follows a load that comes and goes. Both choices run the same compiled per-part code,
so results are bit-identical whichever runs.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numba

SERIAL_BELOW = 4     # parts: smaller batches always run serially (a parallel region costs more)
PROBE_EVERY = 32     # steps between re-tries of the slower choice
SMOOTHING = 0.25     # weight of the newest measurement in the running mean


@contextmanager
def threads(n: int) -> Iterator[None]:
    """Run numba parallel regions with ``n`` threads inside the block."""
    prev = numba.get_num_threads()
    numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]
    try:
        yield
    finally:
        numba.set_num_threads(prev)


class ThreadChooser:
    """Serial or parallel for each batched step.

    ``num_threads``: 1 (always serial), k > 1 (always parallel with k threads) or ``None``
    (automatic: measured, see the module docstring). ``choose()`` gives the threads for the next
    step; ``record(threads, seconds, firings)`` reports how long it took.
    """

    def __init__(self, num_threads: int | None, num_envs: int):
        self.fixed = num_threads
        self.parallel: int = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
        if num_threads is None and (num_envs < SERIAL_BELOW or self.parallel < 2):
            self.fixed = 1
        self.cost: dict[int, float | None] = {1: None, self.parallel: None}  # s/firing, mean
        self.steps = 0

    def choose(self) -> int:
        if self.fixed is not None:
            return self.fixed
        self.steps += 1
        untried = [k for k, c in self.cost.items() if c is None]
        if untried:
            return untried[0]
        best = min(self.cost, key=lambda k: self.cost[k] or 0.0)
        if self.steps % PROBE_EVERY == 0:
            return next(k for k in self.cost if k != best)
        return best

    def record(self, threads: int, seconds: float, firings: int) -> None:
        if self.fixed is not None or firings <= 0 or threads not in self.cost:
            return
        c = seconds / firings
        old = self.cost[threads]
        self.cost[threads] = c if old is None else (1 - SMOOTHING) * old + SMOOTHING * c

    @property
    def current(self) -> int:
        """The choice in use now (threads)."""
        if self.fixed is not None:
            return self.fixed
        known = {k: c for k, c in self.cost.items() if c is not None}
        return min(known, key=lambda k: known[k]) if known else 1
