"""The studies' execution engine: one core, a local Dask cluster, or an existing one.

A study is a list of *tasks* (plain dicts of parameters) and a module-level function
``task -> list of rows`` (each row a flat dict: the parameters as columns, then the results).
:func:`run_tasks` runs the tasks

* serially in this process (the default),
* on a local Dask cluster of ``workers`` single-threaded worker processes, or
* on an existing Dask cluster whose scheduler listens at ``scheduler`` (``tcp://host:8786``),

cutting the task list into chunks, submitting one Dask task per chunk and gathering the rows
back **in task order**. Every simulation is deterministic, so the rows are identical to the serial
run's whatever the number of workers (timing columns, listed in :data:`TIMING_COLUMNS`, are
measurements and naturally differ). Workers must have this package installed (the same version);
contact tables are cached on each worker's disk (``$MICROCONVEYOR_CACHE_DIR``).

A study survives the loss of workers: each Dask task carries its chunk of task dicts (small
parameters, held by the scheduler, nothing is scattered to one worker), and a worker builds its
simulators itself (:func:`simulator`, cached per process; contact tables from the disk cache), so
the scheduler re-runs a lost worker's tasks on another one and the rows stay the serial run's.
Connecting to ``scheduler`` is bounded by a timeout (:data:`SCHEDULER_TIMEOUT_S`) and checks that
a Dask scheduler answers (:func:`check_scheduler`).
"""
from __future__ import annotations

import asyncio
import functools
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import ExitStack, contextmanager, suppress
from typing import TYPE_CHECKING, Any

from ..physics.materials import ParameterError
from . import dask_connect
from .dask_connect import SchedulerConnectionError, check_scheduler  # noqa: F401 - re-exported
from .tables import (TABLE_SUFFIXES, TIMING_COLUMNS, Row, atomic_path,  # noqa: F401
                     partial_path, read_table, same_rows, write_table)

if TYPE_CHECKING:
    from ..physics.simulator import Simulator

Task = dict[str, Any]   # the parameters of one task

SCHEDULER_TIMEOUT_S = dask_connect.SCHEDULER_TIMEOUT_S  # default bound on connecting [s]


# ----------------------------------------------------------------------------- simulators
@functools.lru_cache(maxsize=128)
def _simulator(preset: str, mass: float | None, sigma: float | None, dgamma: float | None,
               profile: str, wavelength: float,
               sim_items: tuple[tuple[str, Any], ...]) -> Simulator:
    from .sweep import Scene

    return Scene(preset=preset, mass=mass, sigma=sigma, dgamma=dgamma, profile=profile,
                 wavelength=wavelength, sim_kw=dict(sim_items)).simulator()


def simulator(preset: str = "feasibility", mass: float | None = None, sigma: float | None = None,
              dgamma: float | None = None, profile: str = "gaussian", wavelength: float = 0.6e-3,
              **sim_kw: Any) -> Simulator:
    """A :class:`Simulator` for these contact/scene values, cached per process.

    ``mass`` [kg], ``sigma`` [m], ``dgamma`` [J/m^2] replace the preset's values (None: keep them;
    the preset's fitted beta and friction scale are kept); ``wavelength`` [m]; ``sim_kw`` go to
    :class:`Simulator` (mode, kinematics, dt, ...).
    """
    f = (lambda v: None if v is None else float(v))
    return _simulator(preset, f(mass), f(sigma), f(dgamma), profile, float(wavelength),
                      tuple(sorted(sim_kw.items())))


# ----------------------------------------------------------------------------- running
def chunked(seq: Sequence[Any], size: int) -> list[list[Any]]:
    """``seq`` cut into lists of ``size`` [-] items (the last may be shorter)."""
    size = max(1, int(size))
    return [list(seq[i:i + size]) for i in range(0, len(seq), size)]


def _run_chunk(func: Callable[[Task], list[Row]], chunk: Iterable[Task]) -> list[Row]:
    """Rows of a chunk of tasks (runs on a worker)."""
    rows: list[Row] = []
    for task in chunk:
        rows.extend(func(task))
    return rows


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None,
                timeout: float = SCHEDULER_TIMEOUT_S) -> Iterator[Any]:
    """A ``distributed.Client``: to the cluster at ``scheduler`` (checked with
    :func:`check_scheduler`, connection bounded by ``timeout`` [s]), or to a new local cluster of
    ``workers`` processes (1 thread each), closed on exit."""
    from distributed import Client, LocalCluster

    if scheduler:
        check_scheduler(scheduler, timeout)
        try:
            client = Client(scheduler, timeout=timeout)
        except (TimeoutError, OSError) as exc:
            raise SchedulerConnectionError(dask_connect.no_answer(scheduler, timeout, exc)) from exc
        try:
            yield client
        finally:
            client.close()
        return
    with ExitStack() as quiet, ExitStack() as stack:  # stack closes first, then quiet restores
        with _sigint_deferred():
            cluster = stack.enter_context(LocalCluster(
                n_workers=int(workers or 1), threads_per_worker=1, processes=True,
                dashboard_address=":0", preload=[__name__]))  # preload: see dask_setup
            client = stack.enter_context(Client(cluster))
        try:
            yield client
        except BaseException:  # an error or Ctrl-C: close without waiting and without log noise
            quiet.enter_context(_logger_level("distributed", logging.CRITICAL))
            _stop_workers_now(cluster)
            raise


@contextmanager
def _logger_level(name: str, level: int) -> Iterator[None]:
    """Logger ``name`` at ``level`` meanwhile."""
    logger = logging.getLogger(name)
    old = logger.level
    logger.setLevel(level)
    try:
        yield
    finally:
        logger.setLevel(old)


def _stop_workers_now(cluster: Any, grace: float = 0.5) -> None:
    """Close the local cluster's nannies at once, each giving its worker process ``grace`` [s] to
    stop before killing it: a running task is not waited for (a plain close gives each worker 4 s,
    then kills it with a warning)."""
    nannies = list(getattr(cluster, "workers", {}).values())

    async def close_all() -> None:
        await asyncio.gather(*(n.close(timeout=grace) for n in nannies), return_exceptions=True)

    with suppress(Exception):
        cluster.sync(close_all)


@contextmanager
def _sigint_deferred() -> Iterator[None]:
    """A Ctrl-C meanwhile is deferred to the end of the block (raised there as
    ``KeyboardInterrupt``), and the threads and processes started meanwhile (the local cluster's
    event loop and, through it, the worker processes) keep SIGINT blocked: a Ctrl-C in a terminal,
    sent to the whole process group, is for this process alone, which stops the study and closes
    the cluster. POSIX, main thread only; elsewhere a no-op."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(
            signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()  # starting it later would unblock SIGINT in that thread
    caught: list[int] = []
    old_handler = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)  # a pending Ctrl-C lands in caught
        signal.signal(signal.SIGINT, old_handler)
    if caught:
        raise KeyboardInterrupt


def dask_setup(worker: object) -> None:
    """Dask's preload hook, run in each worker process of the local cluster (:func:`dask_client`)
    as it starts, restarted ones included: the worker ignores SIGINT (see :func:`_sigint_deferred`)
    and logs only critical messages (``$MICROCONVEYOR_DEBUG`` set: all), so that the command line
    keeps its one line on stderr for an error or a Ctrl-C (a task's exception reaches the client
    anyway; the cluster's own warnings, such as a worker restart, still show)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if not os.environ.get("MICROCONVEYOR_DEBUG"):
        logging.getLogger("distributed").setLevel(logging.CRITICAL)


def run_tasks(func: Callable[[Task], list[Row]], tasks: Iterable[Task], *,
              workers: int | None = None, scheduler: str | None = None,
              client: Any = None, chunk_size: int | None = None, progress: bool = True,
              desc: str = "study", scheduler_timeout: float = SCHEDULER_TIMEOUT_S) -> list[Row]:
    """Rows of ``func`` over ``tasks``, in task order (see the module docstring).

    ``workers`` [-]: number of local worker processes (None or 0: serial, unless ``scheduler`` or
    ``client`` is given); ``scheduler``: address of an existing Dask scheduler, reached within
    ``scheduler_timeout`` [s]; ``client``: an open ``distributed.Client`` to use (tests);
    ``chunk_size``: tasks per chunk (default: about four chunks per worker).
    """
    tasks = list(tasks)
    if workers is not None and int(workers) < 0:
        raise ParameterError(f"workers = {workers!r} is invalid: must be >= 0")
    if client is None and not scheduler and not workers:
        with _progress(len(tasks), desc, progress) as bar:
            rows: list[Row] = []
            for task in tasks:
                rows.extend(func(task))
                bar.update()
            return rows
    if client is not None:
        with _progress(len(tasks), desc, progress) as bar:
            return _run_dask(client, func, tasks, chunk_size, bar)
    with dask_client(workers, scheduler, scheduler_timeout) as c, \
            _progress(len(tasks), desc, progress) as bar:  # no bar before the cluster is up
        return _run_dask(c, func, tasks, chunk_size, bar)


@contextmanager
def _progress(total: int, desc: str, show: bool) -> Iterator[Any]:
    """A progress bar of ``total`` [-] tasks on stderr (``show`` False: a silent one), cleared on
    exit."""
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, file=sys.stderr, disable=not show, leave=False)
    try:
        yield bar
    finally:
        bar.close()


def _run_dask(client: Any, func: Callable[[Task], list[Row]], tasks: list[Task],
              chunk_size: int | None, bar: Any) -> list[Row]:
    """Rows of ``func`` over ``tasks`` on ``client``'s cluster, one Dask task per chunk.

    Each Dask task carries its chunk as an argument (kept by the scheduler), never data scattered
    to one worker, so a chunk whose worker dies is re-run on another worker. Results are fetched
    as they finish and released on the cluster at once."""
    from distributed import as_completed

    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    if chunk_size is None:
        chunk_size = max(1, -(-len(tasks) // (4 * n_workers)))
    chunks = chunked(tasks, chunk_size)
    if not chunks:
        return []
    run = functools.partial(_run_chunk, func)
    futures = [client.submit(run, chunk, pure=False) for chunk in chunks]
    index = {f.key: i for i, f in enumerate(futures)}
    results: list[list[Row]] = [[] for _ in chunks]
    try:
        for fut in as_completed(futures):
            i = index[fut.key]
            results[i] = fut.result()
            fut.release()
            bar.update(len(chunks[i]))
    except BaseException:  # an error or Ctrl-C: stop the rest (the client may outlive us)
        with suppress(Exception):
            client.cancel(futures)
        raise
    return [row for rows in results for row in rows]


def timed(func: Callable[..., Any], *args: Any, **kw: Any) -> tuple[Any, float]:
    """(result, wall time [s]) of one call."""
    t0 = time.perf_counter()
    out = func(*args, **kw)
    return out, time.perf_counter() - t0


