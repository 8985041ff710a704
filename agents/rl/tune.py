"""Hyperparameter search for PPO with Optuna on a shared storage: ``microconveyor tune``.

One Optuna study (``study_name``) in a real storage: SQLite by default (``OUT/optuna.db``, one
machine), any SQLAlchemy database URL for many (``postgresql://...``, ``mysql+pymysql://...``).
Each worker process loads the study and runs its share of the trials; workers on other machines
join by running the same command with the same ``storage`` and ``study_name``. A trial is one
:func:`.train.train` run (``OUT/<study>/trial-<number>``) with sampled hyperparameters
(:mod:`.tune_space`) over the base config entry, a step budget and an optional wall budget; its
value is the final fixed-target success within +-50 um, minus ``0.01 x`` the median error [m]
(capped at 10 mm, so at most 1e-4: a tie-break that never outweighs one target in 10,000).
Periodic evaluations report the same value and Optuna's median pruner stops trials below the
median of earlier ones at the same step. Failed trials are recorded with their error and the
worker goes on; a worker that dies leaves its trial RUNNING until its heartbeat goes stale, then
the next worker marks it failed.
"""
from __future__ import annotations

import os
import socket
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from . import hyperparams, tune_space
from .parallel import run_local

DEFAULT_STUDY = "microconveyor-ppo"
HEARTBEAT_S = 60            # a running trial's heartbeat; stale after GRACE_S without one
GRACE_S = 180


def score(ev: dict) -> float:
    """The objective of an evaluation: success within +-50 um, tie-broken by the median error."""
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
    except Exception:  # noqa: BLE001 - not a URL sqlalchemy parses: Optuna will say so
        return url


def open_storage(url: str) -> Any:
    """An Optuna RDB storage at ``url`` with heartbeats (stale trials of dead workers are marked
    failed); SQLite waits up to 60 s for a lock rather than failing."""
    import warnings

    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # our own line per trial instead
    kw = {"connect_args": {"timeout": 60}} if url.startswith("sqlite") else {}
    with warnings.catch_warnings():  # heartbeats are "experimental" (since Optuna 2.9)
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return optuna.storages.RDBStorage(url, engine_kwargs=kw, heartbeat_interval=HEARTBEAT_S,
                                          grace_period=GRACE_S)


def _study(job: dict, sampler_seed: int | None = None) -> Any:
    import optuna

    return optuna.create_study(
        study_name=job["study_name"], storage=open_storage(job["storage"]), load_if_exists=True,
        direction="maximize",
        sampler=optuna.samplers.TPESampler(seed=sampler_seed, constant_liar=True),
        pruner=(optuna.pruners.MedianPruner(n_startup_trials=5) if job["prune"]
                else optuna.pruners.NopPruner()))


def _open_study(job: dict) -> Any:
    """:func:`_study`, its failures to reach the storage as one ValueError naming it (password
    masked) and, for a missing database driver, what to install."""
    url = shown(job["storage"])
    try:
        return _study(job)
    except ImportError:  # Optuna's "Failed to import DB access module"
        raise ValueError(f"the storage {url} needs a database driver that is not installed "
                         "(PostgreSQL: pip install psycopg2-binary; MySQL: pip install pymysql "
                         "and a mysql+pymysql:// URL)") from None
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001 - sqlalchemy's errors: a wrong URL, no server, ...
        raise ValueError(f"cannot open the Optuna storage {url}: {type(exc).__name__}: "
                         f"{exc}") from None


def _objective(job: dict, worker: str) -> Callable[[Any], float]:
    import optuna

    from .train import train

    base = hyperparams.load(job["conf_file"], job["env_id"])
    steps = int(job["trial_steps"])

    def objective(trial: Any) -> float:
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

        try:
            meta = train(run, steps=steps, seed=job["seed"], conf_file=job["conf_file"],
                         env_id=job["env_id"], env_kwargs=job["env_kwargs"],
                         overrides=tune_space.overrides(base, flat),
                         max_minutes=job["trial_minutes"], eval_freq=job["eval_freq"],
                         eval_targets=job["eval_targets"], eval_seed=job["eval_seed"],
                         checkpoint_freq=10**12, progress_bar=False, tensorboard=False,
                         on_eval=on_eval)
        except optuna.TrialPruned:
            raise
        except Exception as exc:
            trial.set_user_attr("error", f"{type(exc).__name__}: {exc}")
            raise
        ev = meta["evaluation"]
        for k in ("success_rate_50um", "median_abs_error_m"):
            trial.set_user_attr(k, ev[k])
        trial.set_user_attr("steps", meta["steps"])
        trial.set_user_attr("wall_time_s", meta["wall_time_s"])
        return score(ev)
    return objective


def _worker(task: dict) -> list[dict]:
    """One worker (in its own process): ``task["n_trials"]`` trials of the study; rows of the
    trials it ran (number, state, value)."""
    import optuna

    job, i = task["job"], int(task["index"])
    worker = f"{socket.gethostname()}:{os.getpid()}"
    log = (lambda line: print(f"worker {i}: {line}", file=sys.stderr, flush=True)) \
        if task.get("verbose") else None
    seed = None if job["sampler_seed"] is None else int(job["sampler_seed"]) + i
    study = _study(job, seed)
    if not os.environ.get("MICROCONVEYOR_DEBUG"):  # failures get one line below, not a traceback
        optuna.logging.set_verbosity(optuna.logging.ERROR)
    rows: list[dict] = []

    def done(_study: Any, t: Any) -> None:
        rows.append({"number": t.number, "state": t.state.name, "value": t.value,
                     "worker": worker})
        if log:
            a = t.user_attrs
            if "success_rate_50um" in a:
                what = (f"value {t.value:.4g} (success +-50 um {a['success_rate_50um']:.2f}, "
                        f"median |error| {a['median_abs_error_m'] * 1e6:.0f} um)")
            elif "pruned_at" in a:
                what = f"at step {a['pruned_at']} (value {t.value:.4g})"
            else:
                what = a.get("error", "")
            log(f"trial {t.number} {t.state.name.lower()} {what}".rstrip())

    study.optimize(_objective(job, worker), n_trials=int(task["n_trials"]),
                   catch=(Exception,), callbacks=[done], gc_after_trial=True)
    return rows


def shares(n: int, workers: int) -> list[int]:
    """``n`` trials split over ``workers`` (the first ones take the remainder; no empty share)."""
    return [s for s in (n // workers + (i < n % workers) for i in range(workers)) if s]


def tune(out: str | Path = "runs/tune", n_trials: int = 20, workers: int = 1,
         storage: str | None = None, study_name: str = DEFAULT_STUDY,
         env_id: str = hyperparams.ENV_ID, env_kwargs: dict | None = None,
         conf_file: str | None = None, trial_steps: int = 1_000_000,
         trial_minutes: float | None = None, eval_freq: int = 250_000, eval_targets: int = 100,
         eval_seed: int = 12345, seed: int = 0, fixed: dict | None = None, prune: bool = True,
         sampler_seed: int | None = None, best_file: str | Path | None = None,
         verbose: bool = False) -> dict:
    """Run ``n_trials`` trials of the study in ``workers`` local processes (module docstring);
    every trial trains with ``seed`` and is evaluated on the same ``eval_targets`` targets.
    Returns :func:`summary` of the whole study (all machines' trials) and this run's rows; with
    a finished trial the best one's full config entry is written to ``best_file`` (default
    ``OUT/<study>/best.yml``)."""
    from .train import check_budgets

    check_budgets(trial_steps, trial_minutes, 1, eval_freq, eval_targets)
    if eval_targets < 1:
        raise ValueError("eval_targets must be >= 1: the objective is the final evaluation")
    if n_trials < 1 or workers < 1:
        raise ValueError(f"n_trials and workers must be >= 1, got {n_trials!r}, {workers!r}")
    tune_space.check_fixed(fixed)         # refuse unknown keys here, not in each worker
    hyperparams.load(conf_file, env_id)   # and a conf file without the env's entry
    Path(out).mkdir(parents=True, exist_ok=True)
    url = storage or default_storage(out)
    job = {"out": str(out), "storage": url, "study_name": study_name,
           "env_id": env_id, "env_kwargs": env_kwargs or None, "conf_file": conf_file,
           "trial_steps": trial_steps, "trial_minutes": trial_minutes, "eval_freq": eval_freq,
           "eval_targets": eval_targets, "eval_seed": eval_seed, "seed": seed,
           "fixed": dict(fixed or {}), "prune": prune, "sampler_seed": sampler_seed}
    _check_protocol(_open_study(job), job)  # created once here: workers only load it
    tasks = [{"job": job, "index": i, "n_trials": n, "verbose": verbose}
             for i, n in enumerate(shares(n_trials, workers))]
    rows = [r for rs in run_local(_worker, tasks, workers) for r in rs]
    res = summary(url, study_name)
    res.update(this_run=rows, storage=shown(url), env_id=env_id)
    if res["best"] is not None:
        path = Path(best_file) if best_file else Path(out) / study_name / "best.yml"
        write_best(res["best"], path, env_id, conf_file, env_kwargs, study_name)
        res["best_file"] = str(path)
    return res


# what every trial of a study must share for their values to be comparable
PROTOCOL = ("env_id", "env_kwargs", "trial_steps", "trial_minutes", "eval_freq", "eval_targets",
            "eval_seed", "seed")


def _check_protocol(study: Any, job: dict) -> None:
    """Record the trial protocol (:data:`PROTOCOL` and a hash of the base config entry) in a new
    study; refuse a command whose protocol differs from the study's (ValueError naming the keys):
    its values would not compare with the others'."""
    import hashlib
    import json

    base = hyperparams.load(job["conf_file"], job["env_id"])
    mine = json.loads(json.dumps({**{k: job[k] for k in PROTOCOL}, "base_config": hashlib.sha256(
        json.dumps(base, sort_keys=True, default=str).encode()).hexdigest()[:16]}))
    theirs = study.user_attrs.get("protocol")
    if theirs is None:
        study.set_user_attr("protocol", mine)
        return
    diff = hyperparams.changed_keys(theirs, mine)
    if diff:
        was = ", ".join(f"{k}={theirs.get(k)!r}" for k in diff)
        now = ", ".join(f"{k}={mine.get(k)!r}" for k in diff)
        raise ValueError(f"study {job['study_name']!r} in {shown(job['storage'])} runs its "
                         f"trials with {was}, this command with {now}: their values would not "
                         "compare; give the study's settings (--env, --env-kwargs, --conf-file, "
                         "--steps, --trial-minutes, --eval-freq, --eval-targets, --seed) or "
                         "another --study")


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
    note = (f"best trial {best['number']} of Optuna study {study_name!r}: value "
            f"{best['value']:.4f}, success +-50 um {best['success_rate_50um']:.3f}, median "
            f"|error| {best['median_abs_error_m'] * 1e6:.1f} um after {best['steps']} steps "
            f"({best['run']})\ntuned: {json.dumps(best['params'])}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(tune_space.config_yaml(env_id, hp, note))
    return path
