"""Independent training processes on one machine, supervised (:func:`run_local`), used by
``microconveyor tune`` (one Optuna worker per process) and ``microconveyor train-seeds`` (one
:func:`.train.train` per seed, :func:`train_seeds`).

Every task runs in its own spawned process, at most ``workers`` at a time. The parent watches
each one: a worker that dies without its result (killed, out of memory, crashed) costs only its
own task (the caller's ``died`` hook says what that task's result is, and may give a task to run
in its place) while the others go on. A worker whose parent dies (the command killed) stops too
(:func:`exit_with_parent`: a thread waits on the pipe that only the parent holds open, so it
also works where the parent is not the one to signal it).

Not the studies' Dask engine (``microconveyor_env.studies.engine``): the agents may not import
the studies room (docs/architecture.md), Dask is not in the ``agents`` extra, and a task here is
one long training with nothing to chunk or gather but a small dict. Many machines: ``tune``
shares an Optuna storage (docs/studies.md); ``train-seeds`` runs a share of the seeds on each
machine into one shared (or copied) folder, then ``microconveyor seeds`` aggregates.
"""
from __future__ import annotations

import dataclasses
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

if TYPE_CHECKING:
    from .settings import TrainSettings

T = TypeVar("T")
R = TypeVar("R")

EXIT_ORPHANED = 3   # a worker's exit status when it stopped because its parent had died
HOOK_S = 20.0       # at most this long for a worker's last words (exit_with_parent's hooks)
WIND_DOWN_S = 5.0   # a stopped command: workers get this long to end on the Ctrl-C they saw,
STOP_S = 60.0       # then a SIGINT of their own and this long, then SIGKILL


def exit_status(code: int | None) -> str:
    """A process's exit code as words: ``killed by SIGKILL``, ``exit status 1``."""
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


class WorkerDied(RuntimeError):
    """A worker process ended without its task's result: ``pid`` and ``exitcode`` (negative: the
    signal that killed it, as :class:`multiprocessing.Process` reports it)."""

    def __init__(self, pid: int | None, exitcode: int | None) -> None:
        self.pid, self.exitcode = pid, exitcode
        super().__init__(f"worker process {pid} died ({exit_status(exitcode)})")

    def __reduce__(self) -> tuple[Any, ...]:
        return type(self), (self.pid, self.exitcode)


class Died(Generic[R, T]):
    """What a ``died`` hook of :func:`run_local` returns: the dead task's ``result`` and
    optionally a task to run ``instead`` (of what the dead worker had left to do)."""

    def __init__(self, result: R, instead: T | None = None) -> None:
        self.result, self.instead = result, instead


_hooks: list[Callable[[], None]] = []
_watcher: threading.Thread | None = None


def exit_with_parent(hook: Callable[[], None] | None = None) -> bool:
    """In a process started by :mod:`multiprocessing`: end it (exit status
    :data:`EXIT_ORPHANED`) as soon as its parent process ends, whatever ended it (kill -9
    included), after running the hooks registered so far (at most :data:`HOOK_S` s in
    all; a hook's error is ignored). A thread waits on the parent's sentinel: a pipe whose only
    writer is the parent, so it reads end-of-file exactly when the parent is gone. Returns
    False (and does nothing) in a process that multiprocessing did not start."""
    global _watcher
    parent = multiprocessing.parent_process()
    if parent is None:
        return False
    if hook is not None:
        _hooks.append(hook)
    if _watcher is None:
        _watcher = threading.Thread(target=_watch, args=(parent.sentinel,),
                                    name="exit-with-parent", daemon=True)
        _watcher.start()
    return True


def _watch(sentinel: Any) -> None:
    wait([sentinel])

    def last_words() -> None:
        for hook in list(_hooks):
            try:
                hook()
            except Exception:  # noqa: BLE001 - the process ends regardless
                pass

    words = threading.Thread(target=last_words, daemon=True)
    words.start()
    words.join(HOOK_S)
    os._exit(EXIT_ORPHANED)


def _child(func: Callable[[T], R], task: T, conn: Connection) -> None:
    """A worker process's body: ``func(task)``; sends ``("ok", result)``, ``("error", exc)`` or
    ``("interrupted", None)`` to the parent."""
    exit_with_parent()
    msg: tuple[str, Any]
    try:
        msg = ("ok", func(task))
    except KeyboardInterrupt:
        msg = ("interrupted", None)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        msg = ("error", exc)
    try:
        pickle.loads(pickle.dumps(msg[1]))
    except Exception:  # noqa: BLE001 - a result or an error that cannot cross processes
        what = msg[1]
        msg = ("error", RuntimeError(f"{type(what).__name__}: {what}"))
    conn.send(msg)
    conn.close()


class _Running:
    def __init__(self, number: int, task: Any, process: Any, conn: Connection) -> None:
        self.number, self.task, self.process, self.conn = number, task, process, conn


def run_local(func: Callable[[T], R], tasks: Sequence[T], workers: int = 1,
              died: Callable[[T, WorkerDied], Died[R, T]] | None = None) -> list[R]:
    """``func`` over ``tasks`` in spawned processes, at most ``workers`` at a time (``workers``
    <= 1 or a single task: in this process); results in task order. ``func`` must be a
    module-level function and the tasks picklable.

    A task whose process dies without a result (:class:`WorkerDied`) gets the result
    ``died(task, err)`` gives; if that names a task to run ``instead``, it is queued and its
    result follows the others'. Without ``died``, the death is an error. An error (raised by
    ``func`` or a death) cancels the tasks still waiting and propagates once the running ones
    end. A Ctrl-C (in this process or a worker) ends the running workers (they get
    :data:`WIND_DOWN_S` s to end on the interrupt they saw, then a SIGINT of their own) and
    raises KeyboardInterrupt; no further task starts."""
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers!r}")
    if workers == 1 or len(tasks) <= 1:
        return [func(t) for t in tasks]
    # spawn, not fork: the parent may hold numba and torch threads
    ctx = multiprocessing.get_context("spawn")
    queue: deque[tuple[int, T]] = deque(enumerate(tasks))
    numbers = len(tasks)
    results: dict[int, R] = {}
    running: dict[Any, _Running] = {}   # by the pipe its result comes through
    error: BaseException | None = None
    try:
        while queue or running:
            while queue and len(running) < workers and error is None:
                number, task = queue.popleft()
                read, write = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_child, args=(func, task, write),
                                   name=f"worker-{number}")
                proc.start()
                write.close()
                running[read] = _Running(number, task, proc, read)
            if not running:
                break
            for conn in wait(list(running)):
                run = running.pop(conn)
                try:
                    kind, value = run.conn.recv()
                except (EOFError, OSError):  # the process ended without a word
                    kind, value = "died", None
                run.conn.close()
                run.process.join()
                if kind == "ok":
                    results[run.number] = value
                elif kind == "died":
                    err = WorkerDied(run.process.pid, run.process.exitcode)
                    if died is None:
                        error = error or err
                        continue
                    outcome = died(run.task, err)
                    results[run.number] = outcome.result
                    if outcome.instead is not None and error is None:
                        queue.append((numbers, outcome.instead))
                        numbers += 1
                else:
                    error = error or (KeyboardInterrupt() if kind == "interrupted" else value)
            if error is not None:
                queue.clear()
    except BaseException:
        _stop([r.process for r in running.values()])
        raise
    if error is not None:
        raise error
    return [results[k] for k in sorted(results)]


def _stop(procs: list[Any]) -> None:
    """End worker processes: time to end on the interrupt they saw, a SIGINT of their own,
    then SIGKILL."""
    for grace, how in ((WIND_DOWN_S, signal.SIGINT), (STOP_S, signal.SIGKILL)):
        t_end = time.monotonic() + grace
        for p in procs:
            p.join(max(0.0, t_end - time.monotonic()))
        alive = [p for p in procs if p.is_alive()]
        for p in alive:
            try:
                os.kill(p.pid, how)
            except OSError:
                pass
        procs = alive
    for p in procs:
        p.join(5.0)


def _finished(out: Path, seed: int) -> dict | None:
    """The row of a seed whose folder already holds a finished run (reused as it is)."""
    import json

    from ..artefacts.checkpoint import META

    if not (out / META).is_file():
        return None
    meta = json.loads((out / META).read_text())
    return {"seed": seed, "out": str(out), "status": "done earlier", "steps": meta.get("steps"),
            "wall_time_s": meta.get("wall_time_s"), "evaluation": meta.get("evaluation")}


def _train_seed(task: dict) -> dict:
    """One seed's training (runs in a worker): its metadata's summary, or the error."""
    import traceback

    from ..artefacts import checkpoint
    from .train import train

    out, seed = Path(task["out"]), int(task["seed"])
    row: dict[str, Any] = {"seed": seed, "out": str(out)}

    def log(line: str) -> None:
        print(f"seed {seed}: {line}", file=sys.stderr, flush=True)

    settings = dataclasses.replace(task["train"], seed=seed, progress_bar=False,
                                   resume=task["train"].resume and bool(checkpoint.generations(out)))
    try:
        meta = train(out, settings, log=log if task.get("verbose") else None)
    except Exception as exc:  # noqa: BLE001 - one seed's failure is reported, the others go on
        if task.get("verbose"):
            traceback.print_exc()
        return {**row, "status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    return {**row, "status": "trained", "steps": meta["steps"], "wall_time_s": meta["wall_time_s"],
            "evaluation": meta["evaluation"]}


def _seed_died(task: dict, err: WorkerDied) -> Died[dict, dict]:
    """The row of a seed whose worker process died (its checkpoints stay: ``--resume``)."""
    return Died({"seed": int(task["seed"]), "out": task["out"], "status": "failed",
                 "error": f"{err}; --resume continues it from its last checkpoint"})


def train_seeds(out: str | Path, seeds: Sequence[int], settings: TrainSettings,
                workers: int = 1, verbose: bool = False) -> dict:
    """Train one run per seed into ``out/seed-<seed>`` (``workers`` processes at a time), then
    aggregate the finished runs (:func:`..evaluation.seeds.aggregate`: IQM and bootstrap CI). A seed whose
    worker process dies is a failed row; the other seeds go on.
    ``settings`` are every run's (:class:`.settings.TrainSettings`; the seed is each run's own,
    the progress bar off; ``resume`` continues a seed's checkpoints, if it has some). Returns
    ``runs`` (one row per seed: status, steps, wall time, final evaluation or error) and
    ``aggregate`` (None if no run finished)."""
    from ..evaluation.seeds import aggregate

    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"give distinct seeds, got {seeds!r}")
    if settings.seed is not None:
        raise ValueError("seed is set per seed by train_seeds")
    from .train import recipe

    recipe(settings)   # a recipe every seed would refuse is refused once, here
    earlier = {s: _finished(Path(out) / f"seed-{s}", s) for s in seeds}
    tasks = [{"out": str(Path(out) / f"seed-{s}"), "seed": s, "train": settings,
              "verbose": verbose} for s in seeds if earlier[s] is None]
    trained = iter(run_local(_train_seed, tasks, workers, died=_seed_died))
    rows = [earlier[s] or next(trained) for s in seeds]
    done = [r["out"] for r in rows if r["status"] != "failed"]
    return {"out": str(out), "workers": workers, "runs": rows,
            "aggregate": aggregate(done) if done else None}
