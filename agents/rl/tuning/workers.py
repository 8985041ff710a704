"""The tuning workers: each runs its share of a study's trials (one training each, scored on its
final evaluation and pruned on its periodic ones), and the command's handling of a worker that
died."""
from __future__ import annotations

import contextlib
import os
import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..training import hyperparams
from ..training.parallel import Died, WorkerDied, exit_status, exit_with_parent
from . import space as tune_space
from .storage import StorageLost, _db_error, mask, open_storage, storage_errors
from .study import _fail_trial, _study, fail_stale


def score(ev: dict) -> float:
    """The objective of an evaluation: success within ±50 µm, tie-broken by the median error."""
    return float(ev["success_rate_50um"]) - 0.01 * min(float(ev["median_abs_error_m"]), 0.01)


def _objective(job: dict, worker: str, now: dict | None = None) -> Callable[[Any], float]:
    import optuna

    from ..training.settings import TrainSettings
    from ..training.train import train

    base = hyperparams.load(job["conf_file"], job["env_id"])
    steps = int(job["trial_steps"])
    now = {} if now is None else now

    def objective(trial: Any) -> float:
        now["number"] = trial.number   # for exit_with_parent's hook
        try:
            return run(trial)
        except (optuna.TrialPruned, StorageLost):
            raise
        except KeyboardInterrupt:
            with contextlib.suppress(Exception):
                trial.set_user_attr("error", "interrupted (Ctrl-C)")
            raise
        except Exception as exc:
            if _db_error(exc) is not None:
                raise StorageLost() from exc
            try:
                trial.set_user_attr("error", f"{type(exc).__name__}: {exc}")
            except Exception as again:
                if _db_error(again) is not None:
                    raise StorageLost() from again
                raise
            raise

    def run(trial: Any) -> float:
        trial.set_user_attr("worker", worker)
        flat = tune_space.sample(trial, job["fixed"])
        trial.set_user_attr("params", flat)
        run = Path(job["out"]) / job["study_name"] / f"trial-{trial.number:04d}"
        trial.set_user_attr("run", str(run))

        def on_eval(res: dict) -> None:
            if res["steps"] >= steps:
                return
            # at the evaluation's nominal step (a multiple of eval_freq; the run passes it by
            # less than n_envs steps): the median pruner compares trials at equal steps
            at = res["steps"] // job["eval_freq"] * job["eval_freq"]
            trial.report(score(res), at)
            if trial.should_prune():
                trial.set_user_attr("pruned_at", at)
                raise optuna.TrialPruned(f"pruned at step {at}")

        settings = TrainSettings(
            steps=steps, seed=job["seed"], conf_file=job["conf_file"], env_id=job["env_id"],
            env_kwargs=job["env_kwargs"], overrides=tune_space.overrides(base, flat),
            max_minutes=job["trial_minutes"], eval_freq=job["eval_freq"],
            eval_targets=job["eval_targets"], eval_seed=job["eval_seed"],
            checkpoint_freq=10**12, progress_bar=False, tensorboard=False)
        meta = train(run, settings, on_eval=on_eval)
        ev = meta["evaluation"]
        for k in ("success_rate_50um", "median_abs_error_m"):
            trial.set_user_attr(k, ev[k])
        trial.set_user_attr("steps", meta["steps"])
        trial.set_user_attr("wall_time_s", meta["wall_time_s"])
        return score(ev)
    return objective


def _row(t: Any, worker: str) -> dict:
    """A trial of this run as the result lists it: number, state, value, worker (and error)."""
    row = {"number": t.number, "state": t.state.name, "value": t.value, "worker": worker}
    if t.state.name == "FAIL":
        row["error"] = t.user_attrs.get("error", "no reason recorded")
    return row


def _worker(task: dict) -> dict:
    """One worker (in its own process, or the command's with one worker): ``task["n_trials"]``
    trials of the study. Returns ``rows`` (the trials it ran: number, state, value, worker,
    error) and ``died`` (None: see :func:`_worker_died`)."""
    import optuna

    job, i = task["job"], int(task["index"])
    worker = f"{socket.gethostname()}:{os.getpid()}"
    log = _log(i, job["storage"]) if task.get("verbose") else None
    seed = None if job["sampler_seed"] is None else int(job["sampler_seed"]) + i
    name = job["study_name"]
    with storage_errors(job["storage"], opening=True):
        storage = open_storage(job["storage"], job["heartbeat_s"])
        study = _study(job, storage, seed)
    now: dict = {}   # the trial this worker runs
    command = os.getppid()

    def orphaned() -> None:  # the command died: fail the running trial, then this process ends
        if "number" in now:
            _fail_trial(storage, name, now["number"], f"its command (process {command}) "
                        f"ended, and its worker {worker} with it")
    exit_with_parent(orphaned)
    if not os.environ.get("MICROCONVEYOR_DEBUG"):  # failures get one line below, not a traceback
        optuna.logging.set_verbosity(optuna.logging.ERROR)
    rows: list[dict] = []

    def done(_study: Any, t: Any) -> None:
        now.pop("number", None)
        rows.append(_row(t, worker))
        if log:
            a = t.user_attrs
            if "success_rate_50um" in a:
                what = (f"{a['success_rate_50um']:.0%} within ±50 µm, median |error| "
                        f"{a['median_abs_error_m'] * 1e6:.0f} µm")
            elif "pruned_at" in a:
                what = f"at step {a['pruned_at']:,}"
            else:
                what = a.get("error", "")
            log(f"trial {t.number} {t.state.name.lower()} {what}".rstrip())
        stale(log)

    def stale(log: Callable[[str], None] | None) -> None:
        for n in fail_stale(storage, name):
            if log:
                log(f"trial {n} failed: no heartbeat for {storage.grace_period} s (its worker "
                    "stopped)")

    with storage_errors(job["storage"]):
        stale(log)
        study.optimize(_objective(job, worker, now), n_trials=int(task["n_trials"]),
                       catch=(Exception,), callbacks=[done], gc_after_trial=True)
    return {"rows": rows, "died": None}


def _log(i: int, url: str) -> Callable[[str], None]:
    """Worker ``i``'s progress lines on stderr, the storage ``url``'s secrets masked."""
    return lambda line: print(mask(f"worker {i}: {line}", url), file=sys.stderr, flush=True)


def _worker_died(task: dict, err: WorkerDied) -> Died[dict, dict]:
    """In the command: worker ``task`` died (:class:`WorkerDied`). Its running trial is marked
    failed with the reason, its finished trials are its rows, and a new worker takes the rest of
    its share if it had started a trial (a worker that dies before its first trial gets no
    successor: that would repeat)."""
    from optuna.trial import TrialState

    job = task["job"]
    worker = f"{socket.gethostname()}:{err.pid}"
    how = exit_status(err.exitcode)
    reason = f"its worker process {worker} died ({how})"
    rows: list[dict] = []
    failed = None
    try:
        with storage_errors(job["storage"]):
            storage = open_storage(job["storage"], None)
            study_id = storage.get_study_id_from_name(job["study_name"])
            mine = [t for t in storage.get_all_trials(study_id, deepcopy=False)
                    if t.user_attrs.get("worker") == worker]
            for t in mine:
                if t.state == TrialState.RUNNING and _fail_trial(storage, job["study_name"],
                                                                 t.number, reason):
                    failed = t.number
                    t = storage.get_trial(storage.get_trial_id_from_study_id_trial_number(
                        study_id, t.number))
                rows.append(_row(t, worker))
    except ValueError as exc:  # the storage is away too: the heartbeat fails the trial later
        mine, reason = [], f"{reason}; {exc}"
    left = int(task["n_trials"]) - len(mine)
    instead = ({**task, "index": int(task["index"]) + int(task["of"]), "n_trials": left}
               if mine and left > 0 else None)
    if task.get("verbose"):
        _log(int(task["index"]), job["storage"])(
            f"died ({how})" + (f" in trial {failed}, marked failed" if failed is not None
                               else "") +
            (f"; a new worker runs its {left} remaining trial(s)" if instead else
             f"; its {left} remaining trial(s) not run" if left > 0 else ""))
    return Died({"rows": rows, "died": {"worker": worker, "how": how, "trial": failed,
                                        "not_run": 0 if instead else left}}, instead)


def shares(n: int, workers: int) -> list[int]:
    """``n`` trials split over ``workers`` (the first ones take the remainder; no empty share)."""
    return [s for s in (n // workers + (i < n % workers) for i in range(workers)) if s]
