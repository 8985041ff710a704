"""One study in its storage: created or loaded, its trial protocol, stale trials failed, its summary
and its best trial written as a config entry."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ..artefacts.folders import write_file
from ..training import hyperparams
from . import space as tune_space
from .settings import DEFAULT_STUDY
from .storage import HEARTBEAT_S, open_storage, shown, storage_errors


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
    return write_file(path, tune_space.config_yaml(env_id, hp, note))  # whole, never via a link
