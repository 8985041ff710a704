"""Hyperparameter search for PPO with Optuna on a shared storage: ``microconveyor tune``.

One Optuna study (``study_name``) in a real storage: SQLite by default (``OUT/optuna.db``, one
machine), any SQLAlchemy database URL for many (``postgresql://...``, ``mysql+pymysql://...``).
Each worker process loads the study and runs its share of the trials; workers on other machines
join by running the same command with the same ``storage`` and ``study_name``. A trial is one
:func:`.train.train` run (``OUT/<study>/trial-<number>``) with sampled hyperparameters
(:mod:`.tune_space`) over the base config entry, a step budget and an optional wall budget; its
value is the final fixed-target success within ±50 µm, minus ``0.01 x`` the median error [m]
(capped at 10 mm, so at most 1e-4: a tie-break that never outweighs one target in 10,000).
Periodic evaluations report the same value and Optuna's median pruner stops trials below the
median of earlier ones at the same step.

Every setting is checked before the storage is touched (the env and its kwargs make a config,
one trial's hyperparameters make a model, the budgets, the out folder, the storage URL and its
driver). Commands that create the storage's tables at the same moment retry (Optuna's first-time
schema creation is not safe against a concurrent one). Failed trials are recorded with their
error (trial attribute ``error``) and the worker goes on. A local worker process that dies fails
its own trial at once (the command's other workers go on, and a new worker takes the rest of its
share); a worker whose command dies fails its trial and stops; a trial whose worker vanished
with its machine is failed once its heartbeat is ``3 x heartbeat_s`` old, by the next worker of
the study to look. Losing the storage ends each command with one error naming it; the study
resumes when the storage is back.
"""
from __future__ import annotations

import contextlib
import os
import random
import socket
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..training import hyperparams
from . import space as tune_space
from ..training.parallel import Died, WorkerDied, exit_status, exit_with_parent, run_local

DEFAULT_STUDY = "microconveyor-ppo"
HEARTBEAT_S = 60            # a running trial's heartbeat (a new study's default) [s]
GRACE = 3                   # a trial without a heartbeat for GRACE x the interval is stale
SCHEMA_TRIES = 10           # attempts at opening a storage whose tables another process creates
CONNECT_TIMEOUT_S = 10      # a database server that does not answer within this is unreachable


def score(ev: dict) -> float:
    """The objective of an evaluation: success within ±50 µm, tie-broken by the median error."""
    return float(ev["success_rate_50um"]) - 0.01 * min(float(ev["median_abs_error_m"]), 0.01)


STORAGE_ENV = "MICROCONVEYOR_TUNE_STORAGE"  # the storage URL when none is given (keeps a
                                           # database password out of the command line)


def default_storage(out: str | Path) -> str:
    """``$MICROCONVEYOR_TUNE_STORAGE`` if set, else SQLite in ``out``."""
    return os.environ.get(STORAGE_ENV) or f"sqlite:///{Path(out) / 'optuna.db'}"


def shown(url: str) -> str:
    """``url`` as printed: its password masked."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - not a URL sqlalchemy parses: check_storage says so
        return url


# database drivers a storage URL may need: module -> what to pip install
DRIVERS = {"psycopg": "'psycopg[binary]'", "psycopg2": "psycopg2-binary", "pymysql": "pymysql",
           "MySQLdb": "mysqlclient", "pg8000": "pg8000", "asyncpg": "asyncpg"}


def _engine_url(url: str) -> str:
    """The URL SQLAlchemy opens: ``postgresql://`` without a driver means psycopg (v3, the
    ``agents`` extra's driver) where it is installed, as SQLAlchemy 2.1 reads it (2.0 would
    look for psycopg2)."""
    import importlib.util

    from sqlalchemy.engine import make_url

    u = make_url(url)
    if u.drivername == "postgresql" and importlib.util.find_spec("psycopg") is not None:
        return u.set(drivername="postgresql+psycopg").render_as_string(hide_password=False)
    return url


def check_storage(url: str) -> None:
    """Refuse, without connecting, a storage URL that cannot work (ValueError naming it, its
    password masked): not a database URL, SQLite in memory (the workers are other processes and
    the study would end with the command), a database driver that is not installed (naming the
    package to install)."""
    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url

    where = shown(url)
    try:
        u = make_url(url)
    except Exception as exc:  # noqa: BLE001 - sqlalchemy's ArgumentError
        raise ValueError(f"cannot open the Optuna storage {where}: not a database URL "
                         f"({exc})") from None
    if u.get_backend_name() == "sqlite" and (u.database in (None, "", ":memory:")
                                             or u.query.get("mode") == "memory"):
        raise ValueError(f"the storage {where} is an SQLite database in memory: the workers "
                         "(other processes) cannot share it and it ends with the command; give "
                         "a file, sqlite:///PATH (or leave --storage out: OUT/optuna.db)")
    try:
        create_engine(_engine_url(url)).dispose()  # imports the driver; connects to nothing
    except ImportError as exc:
        mod = exc.name or ""
        pkg = DRIVERS.get(mod.split(".")[0], mod)
        extra = (" (the 'agents' extra has it: pip install 'microconveyor-env[agents]')"
                 if mod == "psycopg" else "")
        raise ValueError(f"the storage {where} needs the database driver {mod!r}, which is not "
                         f"installed: pip install {pkg}{extra}") from None
    except Exception as exc:  # noqa: BLE001 - an unknown dialect, a bad argument
        raise ValueError(f"cannot open the Optuna storage {where}: {type(exc).__name__}: "
                         f"{_first_line(exc)}") from None


def _first_line(exc: BaseException) -> str:
    """A database error's own message (the driver's, without SQLAlchemy's SQL and links)."""
    text = str(getattr(exc, "orig", None) or exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _db_error(exc: BaseException) -> BaseException | None:
    """The database error behind ``exc`` (its causes and contexts searched): SQLAlchemy's, else
    Optuna's StorageInternalError; None if ``exc`` does not come from the storage."""
    from optuna.exceptions import StorageInternalError
    from sqlalchemy.exc import SQLAlchemyError

    found: BaseException | None = None
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, SQLAlchemyError):
            return e
        if isinstance(e, StorageInternalError) and found is None:
            found = e
        e = e.__cause__ if e.__cause__ is not None else (
            None if e.__suppress_context__ else e.__context__)
    return found


def _schema_race(exc: BaseException) -> bool:
    """Whether ``exc`` is what creating a storage's tables raises while another process creates
    them: a duplicate key, table or type (PostgreSQL SQLSTATE 23505, 42P07, 42710), SQLite's and
    MySQL's "already exists"."""
    from sqlalchemy import exc as sa

    err = _db_error(exc)
    if isinstance(err, sa.IntegrityError):
        return True
    if isinstance(err, (sa.ProgrammingError, sa.OperationalError)):
        orig = getattr(err, "orig", None)
        code = getattr(orig, "sqlstate", None) or getattr(orig, "pgcode", None)
        return code in ("23505", "42P07", "42710") or "already exists" in str(orig).lower()
    return False


def open_storage(url: str, heartbeat_s: int | None = HEARTBEAT_S) -> Any:
    """An Optuna RDB storage at ``url``: trials send a heartbeat every ``heartbeat_s`` s (None:
    no heartbeat) and are stale after :data:`GRACE` times that; a heartbeat the storage cannot
    take (the server away) is tried again at the next beat instead of ending the trial. SQLite
    waits up to 60 s for a lock; a database server gets :data:`CONNECT_TIMEOUT_S` s to answer
    and every pooled connection is checked before use (a restarted server costs no error).
    Creating the tables while another process creates them is retried."""
    import warnings

    import optuna
    from sqlalchemy.engine import make_url

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # our own line per trial instead
    backend = make_url(url).get_backend_name()
    kw: dict[str, Any] = ({"connect_args": {"timeout": 60}} if backend == "sqlite" else
                          {"pool_pre_ping": True})
    if backend in ("postgresql", "mysql"):
        kw["connect_args"] = {"connect_timeout": CONNECT_TIMEOUT_S}
    beat_s = None if heartbeat_s is None else int(heartbeat_s)
    for attempt in range(SCHEMA_TRIES):
        try:
            with warnings.catch_warnings():  # heartbeats are "experimental" (since Optuna 2.9)
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                storage = optuna.storages.RDBStorage(
                    _engine_url(url), engine_kwargs=kw, heartbeat_interval=beat_s,
                    grace_period=None if beat_s is None else GRACE * beat_s)
            break
        except Exception as exc:
            if attempt + 1 == SCHEMA_TRIES or not _schema_race(exc):
                raise
            time.sleep(random.uniform(0.05, 0.25) * (attempt + 1))  # the other one finishes
    beat = storage.record_heartbeat

    def record_heartbeat(trial_id: int) -> None:
        try:
            beat(trial_id)
        except Exception as exc:
            if _db_error(exc) is None:
                raise
            # the storage is away: the trial notices when it next writes; beat again later
    storage.record_heartbeat = record_heartbeat  # type: ignore[method-assign]
    return storage


class StorageLost(BaseException):
    """Raised out of a trial when its storage fails: a BaseException, so that Optuna does not
    try to record the trial's failure in the storage that just failed."""


@contextlib.contextmanager
def storage_errors(url: str, opening: bool = False) -> Iterator[None]:
    """Turn an error of the storage at ``url`` (raised inside, however wrapped) into one
    ValueError naming it (password masked): ``cannot open`` it (``opening``) or ``lost`` it."""
    try:
        yield
    except (Exception, StorageLost) as exc:
        err = _db_error(exc)
        if err is None:
            raise
        what = f"{type(err).__name__}: {_first_line(err)}"
        if opening:
            raise ValueError(f"cannot open the Optuna storage {shown(url)}: {what}") from None
        raise ValueError(f"lost the Optuna storage {shown(url)} ({what}); the study is kept "
                         "there: run the command again once the storage is back") from None


def _study(job: dict, storage: Any, sampler_seed: int | None = None) -> Any:
    import optuna

    return optuna.create_study(
        study_name=job["study_name"], storage=storage, load_if_exists=True,
        direction="maximize",
        sampler=optuna.samplers.TPESampler(seed=sampler_seed, constant_liar=True),
        pruner=(optuna.pruners.MedianPruner(n_startup_trials=5) if job["prune"]
                else optuna.pruners.NopPruner()))


def _open_study(job: dict) -> tuple[Any, Any]:
    """The study (created if new) and its storage (no heartbeat of its own); a storage that
    cannot be opened is one ValueError naming it (password masked)."""
    with storage_errors(job["storage"], opening=True):
        storage = open_storage(job["storage"], None)
        return _study(job, storage), storage


def _fail_trial(storage: Any, study_name: str, number: int, reason: str) -> bool:
    """Mark trial ``number`` of the study failed with ``reason`` (trial attribute ``error``);
    False if it had already finished."""
    from optuna.exceptions import UpdateFinishedTrialError
    from optuna.trial import TrialState

    trial_id = storage.get_trial_id_from_study_id_trial_number(
        storage.get_study_id_from_name(study_name), number)
    try:
        storage.set_trial_user_attr(trial_id, "error", reason)
        return bool(storage.set_trial_state_values(trial_id, TrialState.FAIL))
    except UpdateFinishedTrialError:
        return False


def fail_stale(storage: Any, study_name: str) -> list[int]:
    """Fail the study's running trials whose heartbeat is older than the storage's grace
    period (their worker was killed with its command, or its machine or connection lost), each
    with the reason; the numbers of those it failed. (Optuna fails them too when a worker
    starts a trial, but without a reason.)"""
    if storage.heartbeat_interval is None:
        return []
    study_id = storage.get_study_id_from_name(study_name)
    failed = []
    for trial_id in storage._get_stale_trial_ids(study_id):  # Optuna's own test of staleness
        t = storage.get_trial(trial_id)
        worker = t.user_attrs.get("worker", "?")
        reason = (f"no heartbeat from its worker {worker} for {storage.grace_period} s: the "
                  "worker stopped (killed, or its machine or its connection to the storage "
                  "lost)")
        if _fail_trial(storage, study_name, t.number, reason):
            failed.append(t.number)
    return failed


def _objective(job: dict, worker: str, now: dict | None = None) -> Callable[[Any], float]:
    import optuna

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

        meta = train(run, steps=steps, seed=job["seed"], conf_file=job["conf_file"],
                     env_id=job["env_id"], env_kwargs=job["env_kwargs"],
                     overrides=tune_space.overrides(base, flat),
                     max_minutes=job["trial_minutes"], eval_freq=job["eval_freq"],
                     eval_targets=job["eval_targets"], eval_seed=job["eval_seed"],
                     checkpoint_freq=10**12, progress_bar=False, tensorboard=False,
                     on_eval=on_eval)
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
    log = _log(i) if task.get("verbose") else None
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


def _log(i: int) -> Callable[[str], None]:
    return lambda line: print(f"worker {i}: {line}", file=sys.stderr, flush=True)


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
        _log(int(task["index"]))(
            f"died ({how})" + (f" in trial {failed}, marked failed" if failed is not None
                               else "") +
            (f"; a new worker runs its {left} remaining trial(s)" if instead else
             f"; its {left} remaining trial(s) not run" if left > 0 else ""))
    return Died({"rows": rows, "died": {"worker": worker, "how": how, "trial": failed,
                                        "not_run": 0 if instead else left}}, instead)


def shares(n: int, workers: int) -> list[int]:
    """``n`` trials split over ``workers`` (the first ones take the remainder; no empty share)."""
    return [s for s in (n // workers + (i < n % workers) for i in range(workers)) if s]


def check_settings(job: dict) -> None:
    """Refuse settings that would fail every trial, before the storage is touched (ValueError
    naming what is wrong): the budgets, the fixed parameters, the conf file's entry for the env,
    the env with its kwargs, and one trial's hyperparameters (the fixed ones, the search
    space's :data:`.tune_space.PROBE` for the others), which must make a PPO model on that env."""
    import optuna

    from microconveyor_env.envs import env_config

    from ..training.train import _new_model, check_budgets, make_env

    check_budgets(job["trial_steps"], job["trial_minutes"], 1, job["eval_freq"],
                  job["eval_targets"])
    if job["eval_targets"] < 1:
        raise ValueError("eval_targets must be >= 1: the objective is the final evaluation")
    fixed = tune_space.check_fixed(job["fixed"])  # unknown keys, impossible values
    base = hyperparams.load(job["conf_file"], job["env_id"])  # the env's entry exists
    kwargs = {**(base.get("env_kwargs") or {}), **(job["env_kwargs"] or {})}
    try:
        cfg = env_config(job["env_id"], **kwargs)
    except ValueError as exc:
        raise ValueError(f"the env {job['env_id']} with env_kwargs {kwargs} cannot be made: "
                         f"{exc}") from None
    flat = tune_space.sample(optuna.trial.FixedTrial(tune_space.PROBE), fixed)
    hp = {**base, **tune_space.overrides(base, flat), "env_kwargs": kwargs}
    try:
        env = make_env(cfg, hp, 0, job["env_id"])
        try:
            _new_model(env, hp, 0, None, "ppo")
        finally:
            env.close()
    except Exception as exc:  # noqa: BLE001 - a conf entry SB3 refuses: TypeError, ValueError
        where = job["conf_file"] or "configs/ppo.yml"
        raise ValueError(f"the hyperparameters of {job['env_id']} ({where}) with {flat} do not "
                         f"make a PPO model: {type(exc).__name__}: {exc}") from None


def _check_out(out: Path) -> None:
    """``out`` exists (created) and takes files."""
    out.mkdir(parents=True, exist_ok=True)
    probe = out / f".probe-{os.getpid()}"
    probe.write_text("")
    probe.unlink()


def tune(out: str | Path = "runs/tune", n_trials: int = 20, workers: int = 1,
         storage: str | None = None, study_name: str = DEFAULT_STUDY,
         env_id: str = hyperparams.ENV_ID, env_kwargs: dict | None = None,
         conf_file: str | None = None, trial_steps: int = 1_000_000,
         trial_minutes: float | None = None, eval_freq: int = 250_000, eval_targets: int = 100,
         eval_seed: int = 12345, seed: int = 0, fixed: dict | None = None, prune: bool = True,
         sampler_seed: int | None = None, best_file: str | Path | None = None,
         verbose: bool = False, heartbeat_s: int | None = None) -> dict:
    """Run ``n_trials`` trials of the study in ``workers`` local processes (module docstring);
    every trial trains with ``seed`` and is evaluated on the same ``eval_targets`` targets.
    ``heartbeat_s``: a new study's heartbeat interval [s] (default :data:`HEARTBEAT_S`; a study
    keeps the one it was created with). Returns :func:`summary` of the whole study (all
    machines' trials), this run's rows (``this_run``), its failed trials (``failed``: number,
    worker, error), its workers that died (``died``: worker, how, trial, trials not run), the
    trials of vanished workers it failed (``failed_stale``: numbers) and its ``wall_time_s``; with a finished trial the best one's full config entry is written to
    ``best_file`` (default ``OUT/<study>/best.yml``)."""
    t0 = time.monotonic()
    if n_trials < 1 or workers < 1:
        raise ValueError(f"n_trials and workers must be >= 1, got {n_trials!r}, {workers!r}")
    if heartbeat_s is not None and (isinstance(heartbeat_s, bool) or
                                    not isinstance(heartbeat_s, int) or heartbeat_s < 1):
        raise ValueError(f"heartbeat_s must be a whole number of seconds >= 1, got "
                         f"{heartbeat_s!r}")
    url = storage or default_storage(out)
    job: dict[str, Any] = {
        "out": str(out), "storage": url, "study_name": study_name, "env_id": env_id,
        "env_kwargs": env_kwargs or None, "conf_file": conf_file, "trial_steps": trial_steps,
        "trial_minutes": trial_minutes, "eval_freq": eval_freq, "eval_targets": eval_targets,
        "eval_seed": eval_seed, "seed": seed, "fixed": dict(fixed or {}), "prune": prune,
        "sampler_seed": sampler_seed, "heartbeat_s": heartbeat_s}
    check_settings(job)     # nothing of the storage touched yet
    _check_out(Path(out))
    check_storage(url)
    study, db = _open_study(job)  # created once here: workers only load it
    with storage_errors(url):
        job["heartbeat_s"] = _check_protocol(study, job)
        _check_trial_folders(study, job)
        db.heartbeat_interval, db.grace_period = job["heartbeat_s"], GRACE * job["heartbeat_s"]
        stale = fail_stale(db, study_name)
    for n in stale if verbose else ():
        print(f"trial {n} failed: no heartbeat for {db.grace_period} s (its worker stopped)",
              file=sys.stderr, flush=True)
    parts = shares(n_trials, workers)
    tasks = [{"job": job, "index": i, "of": len(parts), "n_trials": n, "verbose": verbose}
             for i, n in enumerate(parts)]
    runs = run_local(_worker, tasks, workers, died=_worker_died)
    rows = [r for res in runs for r in res["rows"]]
    with storage_errors(url):
        stale += fail_stale(db, study_name)
        res = summary(url, study_name)
    res.update(this_run=rows, storage=shown(url), env_id=env_id,
               failed=[{k: r[k] for k in ("number", "worker", "error")}
                       for r in rows if r["state"] == "FAIL"],
               died=[r["died"] for r in runs if r["died"] is not None],
               heartbeat_s=job["heartbeat_s"], failed_stale=stale)
    if res["best"] is not None:
        path = Path(best_file) if best_file else Path(out) / study_name / "best.yml"
        write_best(res["best"], path, env_id, conf_file, env_kwargs, study_name)
        res["best_file"] = str(path)
    res["wall_time_s"] = time.monotonic() - t0
    return res


# what every trial of a study must share for their values to be comparable
PROTOCOL = ("env_id", "env_kwargs", "trial_steps", "trial_minutes", "eval_freq", "eval_targets",
            "eval_seed", "seed")


def _settled(study: Any, key: str, value: Any) -> Any:
    """The study's user attribute ``key``, set to ``value`` if it has none yet; when commands
    set it at the same moment, the one the storage kept."""
    if key not in study.user_attrs:
        study.set_user_attr(key, value)  # Optuna ignores the loser's write of a race
    return study.user_attrs[key]


def _check_protocol(study: Any, job: dict) -> int:
    """Record the trial protocol (:data:`PROTOCOL` and a hash of the base config entry) and the
    heartbeat interval in a new study; refuse a command whose protocol differs from the study's
    (ValueError naming the keys: its values would not compare with the others'), or that asks
    for another heartbeat. Returns the study's heartbeat interval [s]."""
    import hashlib
    import json

    base = hyperparams.load(job["conf_file"], job["env_id"])
    mine = json.loads(json.dumps({**{k: job[k] for k in PROTOCOL}, "base_config": hashlib.sha256(
        json.dumps(base, sort_keys=True, default=str).encode()).hexdigest()[:16]}))
    theirs = _settled(study, "protocol", mine)
    diff = hyperparams.changed_keys(theirs, mine)
    if diff:
        was = ", ".join(f"{k}={theirs.get(k)!r}" for k in diff)
        now = ", ".join(f"{k}={mine.get(k)!r}" for k in diff)
        raise ValueError(f"study {job['study_name']!r} in {shown(job['storage'])} runs its "
                         f"trials with {was}, this command with {now}: their values would not "
                         "compare; give the study's settings (--env, --env-kwargs, --conf-file, "
                         "--steps, --trial-minutes, --eval-freq, --eval-targets, --seed) or "
                         "another --study")
    # a study made before heartbeats were recorded ran with the default
    hb = int(_settled(study, "heartbeat_s", job["heartbeat_s"] or HEARTBEAT_S))
    if job["heartbeat_s"] not in (None, hb):
        raise ValueError(f"study {job['study_name']!r} in {shown(job['storage'])} has its "
                         f"workers send a heartbeat every {hb} s, this command asks for "
                         f"{job['heartbeat_s']} s: leave --heartbeat out (its workers would "
                         "judge the others' trials stale too early or too late)")
    return hb


def _check_trial_folders(study: Any, job: dict) -> None:
    """Refuse an out folder holding trial folders that are not the study's (another study of
    that name, in another storage): its trials of those numbers could not train there."""
    folder = Path(job["out"]) / job["study_name"]
    here = sorted(p.name for p in folder.glob("trial-*") if p.is_dir())  # before the trials:
    numbers = {t.number for t in study.get_trials(deepcopy=False)}       # a new one has both
    foreign = [n for n in here if not (n[6:].isdigit() and int(n[6:]) in numbers)]
    if foreign:
        raise ValueError(f"{str(folder)!r} holds trial folders that are not trials of study "
                         f"{job['study_name']!r} in {shown(job['storage'])} ({', '.join(foreign[:3])}"
                         f"{', ...' if len(foreign) > 3 else ''}): another study of that name "
                         "ran there; choose another --out or --study")


def summary(storage: str, study_name: str = DEFAULT_STUDY) -> dict:
    """The study at a glance: trials by state, trials per worker (``host:pid``), the best trial
    (number, value, tuned parameters, success, median error, steps, wall time, run folder)."""
    import optuna

    study = optuna.load_study(study_name=study_name, storage=open_storage(storage))
    trials = study.get_trials(deepcopy=False)
    states: dict[str, int] = {}
    per_worker: dict[str, int] = {}
    for t in trials:
        states[t.state.name.lower()] = states.get(t.state.name.lower(), 0) + 1
        w = t.user_attrs.get("worker", "?")
        per_worker[w] = per_worker.get(w, 0) + 1
    best = None
    if any(t.state == optuna.trial.TrialState.COMPLETE for t in trials):
        b = study.best_trial
        best = {"number": b.number, "value": b.value, "params": b.user_attrs.get("params"),
                **{k: b.user_attrs.get(k) for k in ("success_rate_50um", "median_abs_error_m",
                                                    "steps", "wall_time_s", "run")}}
    return {"study": study_name, "trials": len(trials), "states": states,
            "workers": per_worker, "best": best}


def write_best(best: dict, path: str | Path, env_id: str = hyperparams.ENV_ID,
               conf_file: str | None = None, env_kwargs: dict | None = None,
               study_name: str = "") -> Path:
    """The best trial's full hyperparameters as an rl-zoo3 config entry for ``env_id``: the
    base entry (``conf_file``) with the trial's tuned values and ``env_kwargs``, as the trial
    trained (``n_timesteps`` stays the base entry's)."""
    import json

    base = hyperparams.load(conf_file, env_id)
    hp = {**base, **tune_space.overrides(base, best["params"])}
    if env_kwargs:
        hp["env_kwargs"] = {**(base.get("env_kwargs") or {}), **env_kwargs}
    note = (f"best trial {best['number']} of Optuna study {study_name!r}: objective "
            f"{best['value']:.4f}, {best['success_rate_50um']:.0%} within ±50 µm, median "
            f"|error| {best['median_abs_error_m'] * 1e6:.1f} µm after {best['steps']:,} steps "
            f"({best['run']})\ntuned: {json.dumps(best['params'])}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(tune_space.config_yaml(env_id, hp, note))
    return path
