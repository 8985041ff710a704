"""Supervised worker processes and settings checked up front: ``tune``, ``train-seeds`` and the
MPC pool of ``compare``.

A worker killed with SIGKILL costs only its own task (a tune trial, marked failed with the
reason; a train-seeds seed, a failed row) while the others go on and the command ends with a
report and exit 2; workers end when their parent is killed (a tune worker fails its trial
first); bad settings, an in-memory SQLite URL and a missing driver are refused before any
storage exists; commands creating one storage at the same moment all succeed; a trial whose
heartbeat stopped is failed with the reason. Linux: the tests find worker processes in /proc.
"""
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.processes import wait_for
from support.storages import open_at_once

pytest.importorskip("stable_baselines3")
pytest.importorskip("optuna")

from agents.rl.tuning import storage as storage_mod  # noqa: E402
from agents.rl.tuning import study as study_mod  # noqa: E402
from agents.rl.training.parallel import Died, WorkerDied, run_local  # noqa: E402
from agents.rl.tuning.settings import TuneSettings  # noqa: E402
from agents.rl.tuning.storage import open_storage  # noqa: E402
from agents.rl.tuning.study import fail_stale  # noqa: E402
from agents.rl.tuning.tune import tune  # noqa: E402

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="finds worker processes through /proc (Linux)")

ENV = "MicroConveyor-v0"
TINY = {"n_envs": 8, "n_steps": 32, "batch_size": 64, "n_epochs": 2, "net_width": 64}
TINY_ARGS = ["--env", ENV, "--fix", *(f"{k}:{v}" for k, v in TINY.items()),
             "--eval-freq", "1024", "--eval-targets", "5"]
CLI = [sys.executable, "-m", "microconveyor_env.cli"]
HOST = socket.gethostname()
DEADLINE_S = 300   # bounds every wait on a subprocess (a hang fails the test, nothing is timed)


def _children(pid: int) -> list[int]:
    """The multiprocessing workers (spawned) of process ``pid``."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmd = (stat.parent / "cmdline").read_bytes()
        except OSError:
            continue
        if int(fields[1]) == pid and b"spawn_main" in cmd and b"pipe_handle" in cmd:
            out.append(int(stat.parent.name))
    return sorted(out)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _wait(cond, what: str):
    return wait_for(cond, what)


def _trials(storage, study: str = "s") -> list:
    try:
        return storage.get_all_trials(storage.get_study_id_from_name(study), deepcopy=False)
    except KeyError:  # the command has not created the study yet
        return []


def _running_with_worker(storage, n: int):
    """``n`` running trials that name their worker (host:pid), or None."""
    running = [t for t in _trials(storage) if t.state.name == "RUNNING"
               and "worker" in t.user_attrs]
    return running if len(running) >= n else None


# ----------------------------------------------------------------------------- run_local
def test_a_dead_worker_costs_only_its_task_and_may_be_replaced(tmp_path):
    """run_local over time.sleep: the worker of the long task is killed; its task gets the
    died hook's result, the task it names instead runs, the others complete; without a hook the
    death is an error raised once the others end."""
    seen = []

    def died(task, err):
        seen.append((task, err))
        return Died(f"died: {err}", instead=0.01)

    import threading

    def kill_the_long_one():
        # both tasks start; the short one's process ends at once: the one left is the long one
        seen: set[int] = set()

        def left():
            alive = [p for p in _children(os.getpid()) if p not in before]
            seen.update(alive)
            return alive if len(seen) == 2 and len(alive) == 1 else None
        victim.extend(_wait(left, "the short task to end"))
        os.kill(victim[0], signal.SIGKILL)

    before = set(_children(os.getpid()))
    victim: list[int] = []
    t = threading.Thread(target=kill_the_long_one)
    t.start()
    res = run_local(time.sleep, [600, 0.01], workers=1 + 1, died=died)
    t.join()
    # the killed one is the long task: the short one ended (and its process) at once
    assert len(seen) == 1 and seen[0][0] == 600 and isinstance(seen[0][1], WorkerDied)
    assert seen[0][1].exitcode == -signal.SIGKILL
    assert res == [f"died: worker process {victim[0]} died (killed by SIGKILL)", None, None]

    before = set(_children(os.getpid()))
    victim.clear()
    t = threading.Thread(target=kill_the_long_one)
    t.start()
    with pytest.raises(WorkerDied, match="killed by SIGKILL"):
        run_local(time.sleep, [600, 0.01], workers=2)
    t.join()


def test_workers_end_when_their_parent_is_killed(tmp_path):
    code = ("import time\nfrom agents.rl.training.parallel import run_local\n"
            "run_local(time.sleep, [600, 600], workers=2)")
    _workers_end_with_parent(code, "two workers")


def test_mpc_pool_workers_end_when_their_parent_is_killed(tmp_path):
    """The MPC's pool (compare --workers) with episodes under way: kill -9 of its process."""
    code = ("import numpy as np\n"
            "from agents.mpc import MPCRollout, MPCSettings\n"
            "from microconveyor_env.envs import env_config\n"
            "with MPCRollout(MPCSettings(first_budget=1000, replan_budget=300), workers=2) as r:\n"
            "    r(env_config('MicroConveyor-v0'), np.full(400, 3e-3), 0)\n")
    _workers_end_with_parent(code, "the MPC pool", settle_s=2.0)  # episodes under way


def _workers_end_with_parent(code: str, what: str, settle_s: float = 0.0) -> None:
    """Run ``code`` (which starts two worker processes), kill -9 it once both run (and
    ``settle_s`` later), and wait for both workers to end."""
    p = subprocess.Popen([sys.executable, "-c", code])
    try:
        workers = _wait(lambda: (lambda c: c if len(c) == 2 else None)(_children(p.pid)), what)
        time.sleep(settle_s)
        assert p.poll() is None
        p.kill()
        p.wait()
        _wait(lambda: not any(_alive(w) for w in workers), f"the workers of {what} to end")
    finally:
        if p.poll() is None:
            p.kill()


# ----------------------------------------------------------------------------- tune
@pytest.mark.slow   # ~32 s; the slow tier also kills a train-seeds worker the same way
def test_a_killed_tune_worker_fails_only_its_trial(tmp_path):
    """tune --workers 2 --trials 4: one worker killed mid-trial. Its trial is failed with the
    reason at once, a new worker runs the rest of its share, the other worker's trials
    complete; the command reports it all, writes best.yml and exits 2 with one line."""
    out = tmp_path / "t"
    out.mkdir()
    p = subprocess.Popen(CLI + ["tune", "--json", "--study", "s", "--trials", "4", "--workers",
                                "2", "--steps", "4096", "--out", str(out), *TINY_ARGS],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        storage = open_storage(f"sqlite:///{out / 'optuna.db'}", None)
        trial = _wait(lambda: _running_with_worker(storage, 1), "a running trial")[0]
        worker = trial.user_attrs["worker"]
        os.kill(int(worker.split(":")[1]), signal.SIGKILL)
        stdout, stderr = p.communicate(timeout=DEADLINE_S)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 2, stderr
    res, error = (json.loads(line) for line in stdout.splitlines())
    assert res["trials"] == 4 and res["states"] == {"complete": 3, "fail": 1}, res
    assert sorted(r["number"] for r in res["this_run"]) == [0, 1, 2, 3]
    reason = f"its worker process {worker} died (killed by SIGKILL)"
    assert res["failed"] == [{"number": trial.number, "worker": worker, "error": reason}]
    assert res["died"] == [{"worker": worker, "how": "killed by SIGKILL", "trial": trial.number,
                            "not_run": 0}]
    # killed in its first trial, its second went to a new worker: three workers in all
    assert len(res["workers"]) == (3 if res["workers"][worker] == 1 else 2), res["workers"]
    assert Path(res["best_file"]).is_file()
    assert error["error"].startswith(f"ValueError: 1 of this run's 4 trials failed (trial "
                                     f"{trial.number}: {reason})")
    assert stderr.splitlines()[-1] == f"microconveyor tune: {error['error']}"
    assert f"died (killed by SIGKILL) in trial {trial.number}, marked failed" in stderr
    assert "Traceback" not in stderr


@pytest.mark.slow   # ~12 s; CI's slow tier runs it (.ci/run)
def test_tune_workers_end_and_fail_their_trials_when_the_command_is_killed(tmp_path):
    out = tmp_path / "t"
    out.mkdir()
    p = subprocess.Popen(CLI + ["tune", "--study", "s", "--trials", "2", "--workers", "2",
                                "--steps", "200000", "--out", str(out), *TINY_ARGS],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        storage = open_storage(f"sqlite:///{out / 'optuna.db'}", None)
        running = _wait(lambda: _running_with_worker(storage, 2), "two running trials")
        p.kill()
        p.wait()
        pids = [int(t.user_attrs["worker"].split(":")[1]) for t in running]
        _wait(lambda: not any(_alive(w) for w in pids), "the workers to end")
    finally:
        if p.poll() is None:
            p.kill()
    trials = _trials(storage)
    assert [t.state.name for t in trials] == ["FAIL", "FAIL"]
    for t in trials:
        assert t.user_attrs["error"] == (f"its command (process {p.pid}) ended, and its worker "
                                         f"{t.user_attrs['worker']} with it")


@pytest.mark.slow   # ~25 s; a killed worker's trial: also test_a_killed_tune_worker_fails_only_its_trial
def test_a_killed_train_seeds_worker_fails_only_its_seed(tmp_path):
    conf = tmp_path / "conf.yml"
    conf.write_text(f"{ENV}:\n  n_envs: 8\n  n_steps: 32\n  batch_size: 64\n  n_epochs: 2\n"
                    "  policy: MlpPolicy\n  n_timesteps: 8192\n")
    out = tmp_path / "runs"
    p = subprocess.Popen(CLI + ["train-seeds", "--json", "--env", ENV, "--seeds", "0", "1",
                                "--workers", "2", "--conf-file", str(conf), "--eval-freq", "0",
                                "--eval-targets", "5", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait(lambda: all((out / f"seed-{s}" / ".lock").exists() for s in (0, 1)),
              "both trainings to start")
        victim = _children(p.pid)[0]
        os.kill(victim, signal.SIGKILL)
        stdout, stderr = p.communicate(timeout=DEADLINE_S)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 2, stderr
    res, error = (json.loads(line) for line in stdout.splitlines())
    status = sorted(r["status"] for r in res["runs"])
    assert status == ["failed", "trained"], res["runs"]
    dead = next(r for r in res["runs"] if r["status"] == "failed")
    assert dead["error"] == (f"worker process {victim} died (killed by SIGKILL); --resume "
                             "continues it from its last checkpoint")
    assert res["aggregate"]["runs"] == [r["out"] for r in res["runs"] if r["status"] == "trained"]
    assert error["error"].startswith("ValueError: 1 seed(s) failed")


# ----------------------------------------------------------------------------- settings first
def test_bad_settings_are_refused_before_any_storage_exists(tmp_path):
    out = tmp_path / "t"
    db = out / "optuna.db"
    kw = dict(n_trials=1, env_id=ENV, trial_steps=1024, eval_freq=1024, eval_targets=5,
              fixed=TINY, study_name="s")
    bad_conf = tmp_path / "bad.yml"
    bad_conf.write_text(f"{ENV}:\n  n_envs: 8\n  policy: MlpPolicy\n  not_a_ppo_argument: 1\n")
    refusals = [
        (dict(env_kwargs={"bogus_key": 1}), "the env MicroConveyor-v0 with env_kwargs .* cannot "
                                            "be made: EnvConfig: unknown keys \\['bogus_key'\\]"),
        (dict(env_kwargs={"n_actuators": 0}), "cannot be made"),
        (dict(conf_file=str(bad_conf)), "do not make a PPO model: TypeError: .*not_a_ppo_argument"),
        (dict(fixed={**TINY, "gamma": 2.0}), "gamma must be in \\(0, 1\\]"),
        (dict(trial_steps=0), "steps must be a whole number >= 1"),
        (dict(env_id="MicroConveyor-v9"), "v9"),
        (dict(storage="sqlite://"), "the storage sqlite:// is an SQLite database in memory"),
        (dict(storage="sqlite:///:memory:"), "in memory"),
        (dict(storage="sqlite:///file:x?mode=memory&cache=shared&uri=true"), "in memory"),
        (dict(heartbeat_s=0), "heartbeat_s must be a whole number of seconds >= 1"),
    ]
    for bad, match in refusals:
        with pytest.raises(ValueError, match=match):
            tune(TuneSettings(out=out, **{**kw, **bad}))
        assert not db.exists(), bad
    (tmp_path / "file").write_text("")
    with pytest.raises(OSError):
        tune(TuneSettings(out=tmp_path / "file", **kw))
    # the corrected command makes the study (nothing recorded the bad kwargs)
    res = tune(TuneSettings(out=out, **kw))
    assert res["states"] == {"complete": 1} and res["failed"] == [] and res["died"] == []


def test_a_missing_driver_names_the_package(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "psycopg", None)   # as if not installed
    monkeypatch.setitem(sys.modules, "psycopg2", None)
    with pytest.raises(ValueError) as err:
        storage_mod.check_storage("postgresql+psycopg://tuner:s3cret@db.example/optuna")
    assert str(err.value) == (
        "the storage postgresql+psycopg://tuner:***@db.example/optuna needs the database driver "
        "'psycopg', which is not installed: pip install 'psycopg[binary]' (the 'agents' extra "
        "has it: pip install 'microconveyor-env[agents]')")
    with pytest.raises(ValueError, match="needs the database driver 'psycopg2?', which is not "
                                         "installed: pip install (psycopg2-binary|'psycopg)"):
        storage_mod.check_storage("postgresql://tuner@db.example/optuna")
    with pytest.raises(ValueError, match="not installed: pip install pymysql"):
        monkeypatch.setitem(sys.modules, "pymysql", None)
        storage_mod.check_storage("mysql+pymysql://tuner@db.example/optuna")


def test_commands_creating_one_sqlite_storage_at_once_all_open_it(tmp_path):
    for i in range(2):
        assert open_at_once(f"sqlite:///{tmp_path / f's{i}.db'}", 4, tmp_path) == ["ok"] * 4


def test_trial_folders_of_another_study_are_refused(tmp_path):
    (tmp_path / "t" / "s" / "trial-0000").mkdir(parents=True)
    with pytest.raises(ValueError, match="holds trial folders that are not trials of study 's' "
                                         ".*trial-0000.*choose another --out or --study"):
        tune(TuneSettings(out=tmp_path / "t", n_trials=1, env_id=ENV, trial_steps=1024,
                          eval_freq=1024, eval_targets=5, fixed=TINY, study_name="s"))


@pytest.mark.filterwarnings("ignore:Heartbeat of storage is supposed to be used")  # ask(), here
def test_a_trial_without_heartbeat_is_failed_with_the_reason(tmp_path):
    import optuna

    url = f"sqlite:///{tmp_path / 'h.db'}"
    storage = open_storage(url, 1)
    study = optuna.create_study(study_name="s", storage=storage)
    trial = study.ask()
    trial.set_user_attr("worker", "elsewhere:1")
    storage.record_heartbeat(trial._trial_id)   # then nothing: its worker is gone
    assert fail_stale(storage, "s") == []        # not stale yet
    time.sleep(3 * 1 + 1.5)
    assert fail_stale(storage, "s") == [0]
    t = study.trials[0]
    assert t.state.name == "FAIL"
    assert t.user_attrs["error"] == ("no heartbeat from its worker elsewhere:1 for 3 s: the "
                                     "worker stopped (killed, or its machine or its connection "
                                     "to the storage lost)")
    # a command asking another heartbeat than the study's is refused (protocol recorded first)
    job = {"out": str(tmp_path), "storage": url, "study_name": "s", "env_id": ENV,
           "env_kwargs": None, "conf_file": None, "trial_steps": 1024, "trial_minutes": None,
           "eval_freq": 1024, "eval_targets": 5, "eval_seed": 1, "seed": 0, "heartbeat_s": 1}
    assert study_mod._check_protocol(study, job) == 1
    assert study_mod._check_protocol(study, {**job, "heartbeat_s": None}) == 1
    with pytest.raises(ValueError, match="heartbeat every 1 s, this command asks for 5 s"):
        study_mod._check_protocol(study, {**job, "heartbeat_s": 5})
