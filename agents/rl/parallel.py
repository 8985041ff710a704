"""Independent training processes on one machine: a pool of spawned worker processes
(:func:`run_local`), used by ``microconveyor tune`` (one Optuna worker per process) and
``microconveyor train-seeds`` (one :func:`.train.train` per seed, :func:`train_seeds`).

Not the studies' Dask engine (``microconveyor_env.studies.engine``): the agents may not import
the studies room (docs/architecture.md), Dask is not in the ``agents`` extra, and a task here is
one long training with nothing to chunk or gather but a small dict. Many machines: ``tune``
shares an Optuna storage (docs/studies.md); ``train-seeds`` runs a share of the seeds on each
machine into one shared (or copied) folder, then ``microconveyor seeds`` aggregates.
"""
from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")


_interrupted = False  # in a worker process: a Ctrl-C reached it


def _guarded(func: Callable[[T], R], task: T) -> R:
    """``func(task)`` in a worker, unless a Ctrl-C already reached this worker: the pool hands
    out tasks queued before the interrupt, which must not start."""
    global _interrupted
    if _interrupted:
        raise KeyboardInterrupt
    try:
        return func(task)
    except KeyboardInterrupt:
        _interrupted = True
        raise


def run_local(func: Callable[[T], R], tasks: Sequence[T], workers: int = 1) -> list[R]:
    """``func`` over ``tasks`` in ``workers`` spawned processes (<= 1: in this process), results
    in task order. ``func`` must be a module-level function and the tasks picklable. An error
    cancels the tasks still waiting and propagates once the running ones end; a Ctrl-C reaches
    the workers too, and none of them starts another task."""
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers!r}")
    if workers == 1 or len(tasks) <= 1:
        return [func(t) for t in tasks]
    # spawn, not fork: the parent may hold numba and torch threads
    pool = ProcessPoolExecutor(max_workers=min(workers, len(tasks)),
                               mp_context=multiprocessing.get_context("spawn"))
    try:
        futures: list[Future[R]] = [pool.submit(_guarded, func, t) for t in tasks]
        return [f.result() for f in futures]
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _finished(out: Path, seed: int) -> dict | None:
    """The row of a seed whose folder already holds a finished run (reused as it is)."""
    import json

    from .checkpoint import META

    if not (out / META).is_file():
        return None
    meta = json.loads((out / META).read_text())
    return {"seed": seed, "out": str(out), "status": "done earlier", "steps": meta.get("steps"),
            "wall_time_s": meta.get("wall_time_s"), "evaluation": meta.get("evaluation")}


def _train_seed(task: dict) -> dict:
    """One seed's training (runs in a worker): its metadata's summary, or the error."""
    import traceback

    from . import checkpoint
    from .train import train

    out, seed = Path(task["out"]), int(task["seed"])
    row: dict[str, Any] = {"seed": seed, "out": str(out)}

    def log(line: str) -> None:
        print(f"seed {seed}: {line}", file=sys.stderr, flush=True)

    kw = dict(task["train"])
    kw["resume"] = bool(kw.get("resume")) and bool(checkpoint.generations(out))
    try:
        meta = train(out, seed=seed, progress_bar=False, log=log if task.get("verbose") else None,
                     **kw)
    except Exception as exc:  # noqa: BLE001 - one seed's failure is reported, the others go on
        if task.get("verbose"):
            traceback.print_exc()
        return {**row, "status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    return {**row, "status": "trained", "steps": meta["steps"], "wall_time_s": meta["wall_time_s"],
            "evaluation": meta["evaluation"]}


def train_seeds(out: str | Path, seeds: Sequence[int], workers: int = 1, verbose: bool = False,
                **train_kwargs: Any) -> dict:
    """Train one run per seed into ``out/seed-<seed>`` (``workers`` processes at a time), then
    aggregate the finished runs (:func:`.seeds.aggregate`: IQM and bootstrap CI).
    ``train_kwargs`` go to :func:`.train.train` (steps, conf_file, env_id, max_minutes, ...;
    ``resume=True`` continues a seed's checkpoints, if it has some). Returns ``runs`` (one row
    per seed: status, steps, wall time, final evaluation or error) and ``aggregate`` (None if no
    run finished)."""
    from .seeds import aggregate

    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"give distinct seeds, got {seeds!r}")
    for bad in ("seed", "out", "log", "progress_bar", "on_eval"):
        if bad in train_kwargs:
            raise ValueError(f"{bad} is set per seed by train_seeds")
    earlier = {s: _finished(Path(out) / f"seed-{s}", s) for s in seeds}
    tasks = [{"out": str(Path(out) / f"seed-{s}"), "seed": s, "train": train_kwargs,
              "verbose": verbose} for s in seeds if earlier[s] is None]
    trained = iter(run_local(_train_seed, tasks, workers))
    rows = [earlier[s] or next(trained) for s in seeds]
    done = [r["out"] for r in rows if r["status"] != "failed"]
    return {"out": str(out), "workers": workers, "runs": rows,
            "aggregate": aggregate(done) if done else None}
