"""The studies' execution engine: one core, a local Dask cluster, or an existing one.

A study is a list of *tasks* (plain dicts of parameters) and a module-level function
``task -> list of rows`` (each row a flat dict: the parameters as columns, then the results).
:func:`run_tasks` runs the tasks

* serially in this process (the default),
* on a local Dask cluster of ``workers`` single-threaded worker processes, or
* on an existing Dask cluster whose scheduler listens at ``scheduler`` (``tcp://host:8786``),

cutting the task list into chunks, scattering the chunks to the workers and gathering the rows
back **in task order**. Every simulation is deterministic, so the rows are identical to the serial
run's whatever the number of workers (timing columns, listed in :data:`TIMING_COLUMNS`, are
measurements and naturally differ). Workers must have this package installed (the same version);
contact tables are cached on each worker's disk (``$MICROCONVEYOR_CACHE_DIR``).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import functools
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from ..physics.materials import ParameterError

if TYPE_CHECKING:
    import pandas as pd

    from ..physics.simulator import Simulator

Row = dict[str, Any]    # one table row: parameters and results, SI units in the key names
Task = dict[str, Any]   # the parameters of one task

TIMING_COLUMNS = ("wall_time_s",)  # measured, not computed: excluded when comparing runs


# ----------------------------------------------------------------------------- simulators
@functools.lru_cache(maxsize=128)
def _simulator(preset: str, mass: float | None, sigma: float | None, dgamma: float | None,
               profile: str, wavelength: float,
               sim_items: tuple[tuple[str, Any], ...]) -> Simulator:
    from .sweep import Scene

    return Scene(preset=preset, mass=mass, sigma=sigma, dgamma=dgamma, profile=profile,
                 wavelength=wavelength, sim_kw=dict(sim_items)).simulator()


def simulator(preset: str = "dissertation", mass: float | None = None, sigma: float | None = None,
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
def dask_client(workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: to the cluster at ``scheduler``, or to a new local cluster of
    ``workers`` processes (1 thread each), closed on exit."""
    from distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    cluster = LocalCluster(n_workers=int(workers or 1), threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def run_tasks(func: Callable[[Task], list[Row]], tasks: Iterable[Task], *,
              workers: int | None = None, scheduler: str | None = None,
              client: Any = None, chunk_size: int | None = None, progress: bool = True,
              desc: str = "study") -> list[Row]:
    """Rows of ``func`` over ``tasks``, in task order (see the module docstring).

    ``workers`` [-]: number of local worker processes (None or 0: serial, unless ``scheduler`` or
    ``client`` is given); ``scheduler``: address of an existing Dask scheduler; ``client``: an open
    ``distributed.Client`` to use (tests); ``chunk_size``: tasks per chunk (default: about four
    chunks per worker).
    """
    tasks = list(tasks)
    if workers is not None and int(workers) < 0:
        raise ParameterError(f"workers = {workers!r} is invalid: must be >= 0")
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc=desc, file=sys.stderr, disable=not progress, leave=False)
    try:
        if client is None and not scheduler and not workers:
            rows: list[Row] = []
            for task in tasks:
                rows.extend(func(task))
                bar.update()
            return rows
        if client is not None:
            return _run_dask(client, func, tasks, chunk_size, bar)
        with dask_client(workers, scheduler) as c:
            return _run_dask(c, func, tasks, chunk_size, bar)
    finally:
        bar.close()


def _run_dask(client: Any, func: Callable[[Task], list[Row]], tasks: list[Task],
              chunk_size: int | None, bar: Any) -> list[Row]:
    from distributed import as_completed

    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    if chunk_size is None:
        chunk_size = max(1, -(-len(tasks) // (4 * n_workers)))
    chunks = chunked(tasks, chunk_size)
    if not chunks:
        return []
    data = client.scatter(chunks)
    futures = client.map(functools.partial(_run_chunk, func), data, pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    results: list[Any] = [None] * len(chunks)
    for fut in as_completed(futures):
        i = index[fut.key]
        results[i] = fut.result()
        bar.update(len(chunks[i]))
    return [row for rows in results for row in rows]


def timed(func: Callable[..., Any], *args: Any, **kw: Any) -> tuple[Any, float]:
    """(result, wall time [s]) of one call."""
    t0 = time.perf_counter()
    out = func(*args, **kw)
    return out, time.perf_counter() - t0


# ----------------------------------------------------------------------------- tables
def write_table(rows: list[Row], path: str | Path) -> Path:
    """Write rows as a tidy table: ``.csv`` or ``.parquet`` (one row per simulation)."""
    import pandas as pd

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    df = pd.DataFrame(rows)
    if path.suffix == ".parquet":
        df.to_parquet(path, index=False)
    elif path.suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        raise ParameterError(f"table file {str(path)!r}: use a .csv or .parquet name")
    return path


def read_table(path: str | Path) -> pd.DataFrame:
    """A table written by :func:`write_table` (``.parquet``, else CSV)."""
    import pandas as pd

    path = Path(path)
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def same_rows(a: Sequence[Row], b: Sequence[Row]) -> bool:
    """Whether two row lists are identical, row for row, ignoring :data:`TIMING_COLUMNS`."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b):
        ka = {k: v for k, v in ra.items() if k not in TIMING_COLUMNS}
        kb = {k: v for k, v in rb.items() if k not in TIMING_COLUMNS}
        if ka.keys() != kb.keys():
            return False
        for k in ka:
            x, y = ka[k], kb[k]
            if x != y and not (_isnan(x) and _isnan(y)):
                return False
    return True


def _isnan(v: object) -> bool:
    return isinstance(v, float) and v != v
