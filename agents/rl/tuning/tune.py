"""Hyperparameter search for PPO with Optuna on a shared storage: ``microconveyor tune``.

One Optuna study (``study_name``) in a real storage: SQLite by default (``OUT/optuna.db``, one
machine), any SQLAlchemy database URL for many (``postgresql://...``, ``mysql+pymysql://...``).
Each worker process loads the study and runs its share of the trials; workers on other machines
join by running the same command with the same ``storage`` and ``study_name``. A trial is one
:func:`..training.train.train` run (``OUT/<study>/trial-<number>``) with sampled hyperparameters
(:mod:`.space`) over the base config entry, a step budget and an optional wall budget; its
value is the final fixed-target success within ±50 µm, minus ``0.01 x`` the median error [m]
(capped at 10 mm, so at most 1e-4: a tie-break that never outweighs one target in 10,000).
Periodic evaluations report the same value and Optuna's median pruner stops trials below the
median of earlier ones at the same step.

Every setting is checked before the storage is touched (the env and its kwargs make a config,
one trial's hyperparameters make a model, the budgets and seeds, the out folder, the best file,
the storage URL and its driver). A storage's secrets (its URL's password, password parameters)
are masked in everything printed. Commands that create the storage's tables at the same
moment retry (Optuna's first-time schema creation is not safe against a concurrent one). Failed
trials are recorded with their error (trial attribute ``error``) and the worker goes on. A local worker process that dies fails
its own trial at once (the command's other workers go on, and a new worker takes the rest of its
share); a worker whose command dies fails its trial and stops; a trial whose worker vanished
with its machine is failed once its heartbeat is ``3 x heartbeat_s`` old, by the next worker of
the study to look. Losing the storage ends each command with one error naming it; the study
resumes when the storage is back.

Where it is written: the settings (:mod:`.settings`), the storage (:mod:`.storage`), the study
(:mod:`.study`), the workers and their trials (:mod:`.workers`).
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from ..artefacts.folders import check_file_target
from ..training import hyperparams
from ..training.parallel import run_local
from . import space as tune_space
from .settings import TuneSettings
from .storage import GRACE, check_storage, default_storage, shown, storage_errors
from .study import _check_protocol, _check_trial_folders, _open_study, fail_stale, summary, \
    write_best
from .workers import _worker, _worker_died, shares


def check_settings(job: dict) -> None:
    """Refuse settings that would fail every trial, before the storage is touched (ValueError
    naming what is wrong; the budgets: :class:`.settings.TuneSettings`): the fixed parameters,
    the conf file's entry for the env (a recipe training takes), the env with its kwargs, and
    one trial's hyperparameters (the fixed ones, the search space's :data:`.space.PROBE` for
    the others), which must make a PPO model on that env."""
    import optuna

    from microconveyor_env.envs.core.versions import scene_config

    from ..training.settings import TrainSettings
    from ..training.train import make_env, new_model, recipe

    fixed = tune_space.check_fixed(job["fixed"])  # unknown keys, impossible values
    recipe(TrainSettings(env_id=job["env_id"], conf_file=job["conf_file"]))
    base = hyperparams.load(job["conf_file"], job["env_id"])  # the env's entry exists
    kwargs = {**(base.get("env_kwargs") or {}), **(job["env_kwargs"] or {})}
    try:
        cfg = scene_config(job["env_id"], **kwargs)
    except ValueError as exc:
        raise ValueError(f"the env {job['env_id']} with env_kwargs {kwargs} cannot be made: "
                         f"{exc}") from None
    flat = tune_space.sample(optuna.trial.FixedTrial(tune_space.PROBE), fixed)
    hp = {**base, **tune_space.overrides(base, flat), "env_kwargs": kwargs}
    try:
        env = make_env(cfg, hp, 0, job["env_id"])
        try:
            new_model(env, hp, 0, None, "ppo")
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


def tune(settings: TuneSettings) -> dict:
    """Run ``settings.n_trials`` trials of the study in ``settings.workers`` local processes
    (module docstring); every trial trains with the same seed and is evaluated on the same
    targets. Returns :func:`.study.summary` of the whole study (all machines' trials), this
    run's rows (``this_run``), its failed trials (``failed``: number, worker, error), its
    workers that died (``died``: worker, how, trial, trials not run), the trials of vanished
    workers it failed (``failed_stale``: numbers) and its ``wall_time_s``; with a finished
    trial the best one's full config entry is written to ``best_file``."""
    s = settings
    t0 = time.monotonic()
    out, study_name, verbose = s.out, s.study_name, s.verbose
    url = s.storage or default_storage(out)
    job = s.job(url)
    check_settings(job)     # nothing of the storage touched yet
    _check_out(Path(out))
    best_file = Path(s.best_file) if s.best_file else Path(out) / study_name / "best.yml"
    check_file_target(best_file, "--best")
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
    parts = shares(s.n_trials, s.workers)
    tasks = [{"job": job, "index": i, "of": len(parts), "n_trials": n, "verbose": verbose}
             for i, n in enumerate(parts)]
    runs = run_local(_worker, tasks, s.workers, died=_worker_died)
    rows = [r for res in runs for r in res["rows"]]
    with storage_errors(url):
        stale += fail_stale(db, study_name)
        res = summary(url, study_name)
    res.update(this_run=rows, storage=shown(url), env_id=s.env_id,
               failed=[{k: r[k] for k in ("number", "worker", "error")}
                       for r in rows if r["state"] == "FAIL"],
               died=[r["died"] for r in runs if r["died"] is not None],
               heartbeat_s=job["heartbeat_s"], failed_stale=stale)
    if res["best"] is not None:
        write_best(res["best"], best_file, s.env_id, s.conf_file, s.env_kwargs, study_name)
        res["best_file"] = str(best_file)
    res["wall_time_s"] = time.monotonic() - t0
    return res


# what every trial of a study must share for their values to be comparable