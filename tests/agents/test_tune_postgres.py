"""``microconveyor tune`` on a real PostgreSQL server, as docs/studies.md §5 tells users to run
it on many machines.

The test starts a throwaway server (a cluster in a temporary folder owned by ``postgres`` when
run as root, on 127.0.0.1 at a free port, trust authentication; stopped and removed afterwards,
also on failure) and drives the ``tune`` command line against it:

1. processes creating the storage's tables at the same instant all open it;
2. three commands started together, as on three machines (their own out folders), share one
   study; one of them is killed mid-trial (its machine lost); the other two run all their
   trials, numbers are not repeated, each reports its own trials and writes a valid best.yml;
3. the server stopped while two more commands train: each ends with exit 2 and one line naming
   the storage (with --json one error object); once the server is back the study resumes;
4. every trial is accounted for: complete, or failed with the reason (the killed machine's
   trial and the two the outage cut, once their heartbeats were stale: by the next commands).

Skipped where the PostgreSQL server binaries or the psycopg driver are missing.
"""
import glob
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from support.processes import wait_for
from support.storages import open_at_once

pytest.importorskip("stable_baselines3")
optuna = pytest.importorskip("optuna")
psycopg = pytest.importorskip("psycopg", reason="the PostgreSQL driver (psycopg, v3) is not "
                                                 "installed: pip install 'psycopg[binary]'")

from agents.rl.tuning.storage import open_storage  # noqa: E402


def _pg_bin() -> Path | None:
    on_path = shutil.which("pg_ctl")
    candidates = ([Path(on_path).parent] if on_path else []) + [
        Path(p) for p in sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True)]
    for d in candidates:
        if all((d / x).is_file() for x in ("initdb", "pg_ctl", "postgres")):
            return d
    return None


PG_BIN = _pg_bin()
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def _postgres_user() -> bool:
    try:
        import pwd

        pwd.getpwnam("postgres")
    except (ImportError, KeyError):
        return False
    return shutil.which("runuser") is not None


pytestmark = [
    pytest.mark.skipif(PG_BIN is None, reason="no PostgreSQL server binaries (initdb, pg_ctl, "
                                              "postgres) on PATH or in /usr/lib/postgresql"),
    pytest.mark.skipif(AS_ROOT and not _postgres_user(),
                       reason="running as root: the cluster must run as the 'postgres' user "
                              "(none, or no runuser)"),
]

ENV = "MicroConveyor-v0"
TINY = ["--env", ENV, "--fix", "n_envs:8", "n_steps:32", "batch_size:64", "n_epochs:2",
        "net_width:64", "--eval-freq", "1024", "--eval-targets", "5", "--heartbeat", "1",
        "--steps", "2048"]   # a later --steps wins
GRACE_S = 3        # --heartbeat 1: a trial is stale 3 s after its last heartbeat
CLI = [sys.executable, "-m", "microconveyor_env.cli", "tune"]
DEADLINE_S = 300   # bounds every wait (a hang fails the test; nothing is timed)


class Server:
    """A PostgreSQL cluster in ``folder``, listening on 127.0.0.1:``port`` only."""

    def __init__(self, folder: Path, port: int) -> None:
        self.folder, self.port = folder, port
        self.data, self.log = folder / "data", folder / "log"

    def run(self, *cmd: str) -> None:
        prefix = ["runuser", "-u", "postgres", "--"] if AS_ROOT else []
        subprocess.run(prefix + [str(PG_BIN / cmd[0]), *cmd[1:]], check=True, cwd=self.folder,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=120)

    def init(self) -> None:
        self.run("initdb", "-D", str(self.data), "-A", "trust", "-U", "postgres", "-E", "UTF8",
                 "--no-sync")

    def start(self) -> None:
        opts = (f"-h 127.0.0.1 -p {self.port} -k '' -c fsync=off -c synchronous_commit=off "
                "-c full_page_writes=off")
        self.run("pg_ctl", "-D", str(self.data), "-l", str(self.log), "-w", "-t", "60",
                 "-o", opts, "start")

    def stop(self, mode: str = "fast") -> None:
        self.run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "-t", "60", "stop")

    def url(self, db: str) -> str:
        return f"postgresql://postgres@127.0.0.1:{self.port}/{db}"

    def create_db(self, name: str) -> str:
        with psycopg.connect(self.url("postgres"), autocommit=True) as conn:
            conn.execute(f"CREATE DATABASE {name}")
        return self.url(name)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def pg():
    # /tmp, not pytest's tree: every folder above the cluster must be open to 'postgres'
    folder = Path(tempfile.mkdtemp(prefix="microconveyor-pg-", dir="/tmp"))
    server = Server(folder, _free_port())
    try:
        if AS_ROOT:
            shutil.chown(folder, "postgres")
        server.init()
        server.start()
        yield server
    finally:
        try:
            server.stop("immediate")
        except Exception:  # noqa: BLE001 - not running (never started, or stopped by the test)
            pass
        shutil.rmtree(folder, ignore_errors=True)


def _tune(url: str, out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen(CLI + ["--json", "--storage", url, "--study", "s", "--out",
                                   str(out), *TINY, *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(p: subprocess.Popen) -> tuple[int, list[dict], str]:
    out, err = p.communicate(timeout=DEADLINE_S)
    return p.returncode, [json.loads(line) for line in out.splitlines()], err


def _wait(cond, what: str):
    return wait_for(cond, what)


def _trials(url: str) -> list:
    storage = open_storage(url, None)
    try:
        return storage.get_all_trials(storage.get_study_id_from_name("s"))
    except KeyError:
        return []
    finally:
        storage.engine.dispose()


def _running_of(url: str, pid: int) -> list:
    """Running trials of the command whose (only) worker is process ``pid``."""
    return [t for t in _trials(url) if t.state.name == "RUNNING"
            and t.user_attrs.get("worker", "").endswith(f":{pid}")]


def _pause_mid_trial(p: subprocess.Popen, url: str):
    """SIGSTOP command ``p`` while one of its trials runs (a trial can end between a look and
    the signal: then it goes on and the next is awaited); that trial."""
    while True:
        _wait(lambda: _running_of(url, p.pid) or p.poll() is not None, "a running trial")
        assert p.poll() is None, p.communicate()
        os.kill(p.pid, signal.SIGSTOP)
        running = _running_of(url, p.pid)
        if running:
            return running[0]
        os.kill(p.pid, signal.SIGCONT)


def _accounted(trials: list) -> None:
    """Every trial finished (complete, pruned, or failed with its reason); numbers 0..n-1."""
    assert sorted(t.number for t in trials) == list(range(len(trials)))
    for t in trials:
        assert t.state.name in ("COMPLETE", "PRUNED", "FAIL"), (t.number, t.state)
        if t.state.name == "FAIL":
            assert t.user_attrs.get("error"), t.number


@pytest.mark.slow   # ~65 s; the default suite shares a SQLite study between processes (tests/agents/test_tune.py)
def test_many_machines_share_one_postgresql_study(pg, tmp_path):
    # 1. the tables, created by four processes at once
    assert open_at_once(pg.create_db("race"), 4, tmp_path, imports="psycopg") == ["ok"] * 4

    # 2. three commands started together on a new database, as on three machines; one of them
    # is killed mid-trial (its machine lost), the other two run their trials to the end
    t0 = time.monotonic()
    url = pg.create_db("optuna")
    a, b, c = (_tune(url, tmp_path / m, "--trials", n)
               for m, n in (("host-a", "2"), ("host-b", "2"), ("host-c", "3")))
    try:
        lost = _pause_mid_trial(c, url)
        c.kill()
        c.wait()
        (ra, [res_a], err_a), (rb, [res_b], err_b) = _finish(a), _finish(b)
    finally:
        for p in (a, b, c):
            if p.poll() is None:
                p.kill()
    assert (ra, rb) == (0, 0), (err_a, err_b)
    for res in (res_a, res_b):
        assert len(res["this_run"]) == 2 and res["failed"] == [] and res["died"] == []
        assert {r["state"] for r in res["this_run"]} == {"COMPLETE"}
        assert res["storage"] == url and res["heartbeat_s"] == 1
    mine = [r["number"] for r in res_a["this_run"] + res_b["this_run"]]
    assert len(set(mine)) == 4                                 # no trial counted twice
    from agents.rl.training import hyperparams

    # each command's best is a complete trial of the shared study, and the one that summed up
    # last (after every trial had ended; which one it is, is a race) names the study's best
    complete = [t for t in _trials(url) if t.state.name == "COMPLETE"]
    assert {r["best"]["value"] for r in (res_a, res_b)} <= {t.value for t in complete}
    assert max(r["best"]["value"] for r in (res_a, res_b)) == max(t.value for t in complete)
    for res in (res_a, res_b):
        hp = hyperparams.load(res["best_file"], ENV)          # a valid rl-zoo3 entry
        assert hp["n_envs"] == 8 and hp["policy_kwargs"]["net_arch"]["pi"] == [64, 64]
    print(f"\nthree commands at once: host-a {len(res_a['this_run'])} trials, host-b "
          f"{len(res_b['this_run'])}, host-c killed in trial {lost.number}; "
          f"{time.monotonic() - t0:.0f} s")

    # 3. the server stops while two commands train; the study resumes once it is back
    e = _tune(url, tmp_path / "host-e", "--trials", "2")
    f = subprocess.Popen(CLI + ["--storage", url, "--study", "s", "--out",
                                str(tmp_path / "host-f"), *TINY, "--trials", "2"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        t1 = time.monotonic()
        cut = [_pause_mid_trial(p, url) for p in (e, f)]
        # both started after host-c's trial went stale: their first look failed it
        t = next(t for t in _trials(url) if t.number == lost.number)
        assert t.state.name == "FAIL"
        assert t.user_attrs["error"] == (
            f"no heartbeat from its worker {lost.user_attrs['worker']} for {GRACE_S} s: the "
            "worker stopped (killed, or its machine or its connection to the storage lost)")
        pg.stop("fast")
        for p in (e, f):
            os.kill(p.pid, signal.SIGCONT)   # they go on training, without their server
        re_, out_e, err_e = _finish(e)
        out_f, err_f = f.communicate(timeout=DEADLINE_S)
        print(f"server stopped {time.monotonic() - t1:.0f} s after host-e and host-f started; "
              "both ended")
    finally:
        for p in (e, f):
            if p.poll() is None:
                p.kill()
    lost_line = f"microconveyor tune: ValueError: lost the Optuna storage {url} ("
    for code, err in ((re_, err_e), (f.returncode, err_f)):
        assert code == 2, err
        assert err.splitlines()[-1].startswith(lost_line), err
        assert err.splitlines()[-1].endswith("the study is kept there: run the command again "
                                             "once the storage is back")
        assert "Traceback" not in err and "Exception in thread" not in err
    assert len(out_e) == 1 and out_e[0]["error"].startswith("ValueError: lost the Optuna "
                                                            f"storage {url} (")
    assert out_f == ""

    pg.start()
    g = _tune(url, tmp_path / "host-g", "--trials", "1")
    rg, [res_g], err_g = _finish(g)
    assert rg == 0, err_g
    assert len(res_g["this_run"]) == 1 and res_g["this_run"][0]["state"] in ("COMPLETE",
                                                                            "PRUNED")
    assert sorted(res_g["failed_stale"]) == sorted(t.number for t in cut)
    trials = _trials(url)
    _accounted(trials)
    for t in cut:
        assert trials[t.number].user_attrs["error"] == (
            f"no heartbeat from its worker {t.user_attrs['worker']} for {GRACE_S} s: the "
            "worker stopped (killed, or its machine or its connection to the storage lost)")
    of_c = [t for t in trials if t.user_attrs["worker"] == lost.user_attrs["worker"]]
    assert of_c[-1].number == lost.number          # host-c ran until it was killed
    # host-e and host-f may each end a trial before the pause caught them in the next one: their
    # trials are counted by worker, each worker's last one the trial the server's loss cut
    ef_workers = {t.user_attrs["worker"] for t in cut}
    assert len(ef_workers) == 2
    of_ef = [t for t in trials if t.user_attrs["worker"] in ef_workers]
    for w in ef_workers:
        mine = [t for t in of_ef if t.user_attrs["worker"] == w]
        assert mine[-1].number in {t.number for t in cut}
        assert all(t.state.name in ("COMPLETE", "PRUNED") for t in mine[:-1])
    assert res_g["trials"] == len(trials) == 4 + len(of_c) + len(of_ef) + 1   # a+b, c, e+f, g
    print(f"server lost and back: host-e, host-f exit 2, trials {[t.number for t in cut]} "
          f"failed by host-g's start, host-g {res_g['this_run'][0]['state'].lower()}; study: "
          f"{res_g['states']}; {time.monotonic() - t0:.0f} s in all")
