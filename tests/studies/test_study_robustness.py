"""The studies under trouble (issue 17): a worker lost mid-study, a --scheduler that is not one,
bad --out/--plot paths, Ctrl-C. Loopback addresses only."""
import functools
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from microconveyor_env.cli import main
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.cli.studies import outputs
from microconveyor_env.studies.engine import SchedulerConnectionError, check_scheduler, \
    run_tasks, same_rows
from microconveyor_env.studies.sensitivity import design, run_combination

distributed = pytest.importorskip("distributed")

LEVELS = {"dgamma_J_m2": (1.0,), "sigma_m": (20e-9, 30e-9), "stroke_m": (150e-6, 200e-6),
          "mass_kg": (2e-9,), "wavelength_m": (0.6e-3,), "x0_wl": (0.2, 0.33)}
SCAN = tuple(float(f) for f in (150, 250, 400, 600, 900, 1300, 1900))
STALL_AT = 3  # the task whose worker is killed while it runs (tasks 0..2 were handed out first)


# ----------------------------------------------------------------------------- a lost worker
def _stall_once(marker: str, at: int, func, task):
    """``func(task)``, except that the first run of task ``at`` writes its worker's pid to
    ``marker`` and waits there to be killed (its re-run, on whatever worker, goes through)."""
    i = task.pop("_i")
    if i == at and not os.path.exists(marker):
        Path(marker + ".tmp").write_text(str(os.getpid()))
        os.replace(marker + ".tmp", marker)
        time.sleep(120)
    return func(task)


def _kill_when_stalled(marker: Path, killed: list, timeout: float = 120.0) -> None:
    """SIGKILL the pid ``marker`` names as soon as it appears; record it in ``killed``."""
    t_end = time.monotonic() + timeout
    while not marker.exists() and time.monotonic() < t_end:
        time.sleep(0.02)
    if marker.exists():
        pid = int(marker.read_text())
        os.kill(pid, signal.SIGKILL)
        killed.append(pid)


@pytest.mark.slow   # a Dask cluster started, a worker killed and its task re-run: ~40 s
def test_study_survives_a_killed_worker(tmp_path):
    """A worker process SIGKILLed while it runs a task: the study finishes on the other worker
    (and the restarted one) with the serial run's rows, bit for bit."""
    tasks = [{**t, "n_freq": 3, "preset": "feasibility", "scan_hz": SCAN} for t in design(LEVELS)]
    serial = run_tasks(run_combination, tasks, progress=False)
    marker = tmp_path / "stalled.pid"
    func = functools.partial(_stall_once, str(marker), STALL_AT, run_combination)
    killed: list[int] = []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        worker_pids = set(client.run(os.getpid).values())
        killer = threading.Thread(target=_kill_when_stalled, args=(marker, killed), daemon=True)
        killer.start()
        rows = run_tasks(func, [{**t, "_i": i} for i, t in enumerate(tasks)], client=client,
                         chunk_size=1, progress=False)
        killer.join(5)
    assert len(killed) == 1 and killed[0] in worker_pids  # a worker died mid-study
    assert len(serial) > len(tasks)
    assert same_rows(rows, serial)


# ----------------------------------------------------------------------------- not a scheduler
@contextmanager
def _silent_server():
    """A loopback TCP server that accepts connections and never says a word: its address."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    conns = []

    def accept():
        while True:
            try:
                conns.append(srv.accept()[0])
            except OSError:
                return

    threading.Thread(target=accept, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    finally:
        srv.close()
        for c in conns:
            c.close()


class _Http400(BaseHTTPRequestHandler):
    """Answers anything at once with an HTTP 400, as a web server does to a bad request line
    (distributed would read "HTTP/1.0" as a frame length: 3 EiB)."""

    def handle(self):
        self.request.recv(65536)
        self.request.sendall(b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n")


@contextmanager
def _http_server(handler=_Http400):
    srv = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{srv.server_address[1]}"
    finally:
        srv.shutdown()
        srv.server_close()


def _timed_error(address, timeout):
    t0 = time.perf_counter()
    with pytest.raises(SchedulerConnectionError) as err:
        run_tasks(run_combination, [], scheduler=address, scheduler_timeout=timeout,
                  progress=False)
    return str(err.value), time.perf_counter() - t0


def test_silent_server_times_out():
    with _silent_server() as address:
        msg, wall = _timed_error(address, 1.0)
    assert "no Dask scheduler answered" in msg and "within 1 s" in msg
    assert wall < 5.0


def test_http_server_is_not_a_scheduler():
    with _http_server() as address:
        msg, wall = _timed_error(address, 5.0)
    assert "is not a Dask scheduler" in msg and "MemoryError" not in msg
    assert wall < 5.0


def test_worker_address_is_not_a_scheduler(dask_client):
    worker = next(iter(dask_client.scheduler_info()["workers"]))
    with pytest.raises(SchedulerConnectionError, match="it is a Dask Worker"):
        check_scheduler(worker, 5.0)
    assert check_scheduler(dask_client.scheduler.address, 5.0)["type"] == "Scheduler"


@pytest.mark.parametrize("address", ["notanaddress", "tcp://127.0.0.1:notaport",
                                     "foo://127.0.0.1:8786"])
def test_malformed_scheduler_address_is_a_parameter_error(address):
    with pytest.raises(ParameterError, match="scheduler address"):
        check_scheduler(address, 1.0)


def _cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                          capture_output=True, text=True, timeout=120, **kw)


@pytest.mark.parametrize("server", [_silent_server, _http_server])
def test_cli_scheduler_error_is_one_line_exit_2(tmp_path, server):
    with server() as address:
        t0 = time.perf_counter()
        r = _cli("engage", "--json", "--no-progress", "--scheduler", address,
                 "--scheduler-timeout", "2", "--out", str(tmp_path / "e.csv"))
        wall = time.perf_counter() - t0
    assert r.returncode == 2
    assert len(r.stderr.splitlines()) == 1 and "SchedulerConnectionError" in r.stderr
    err = json.loads(r.stdout)
    assert err["error_type"] == "SchedulerConnectionError" and address in err["error"]
    assert wall < 30.0  # start-up (imports) + at most the 2 s timeout
    assert os.listdir(tmp_path) == []


# ----------------------------------------------------------------------------- --out / --plot
@pytest.mark.parametrize("option, value, text", [
    ("--out", "missing/s.csv", "does not exist"),
    ("--out", "s.txt", ".csv or .parquet"),
    ("--out", ".", "is a folder"),
    ("--plot", "missing/s.png", "does not exist"),
    ("--plot", "s.nope", "unsupported chart format"),
    ("--scheduler-timeout", "0", "positive number of seconds"),
    ("--workers", "-1", "integer in [0"),
])
def test_bad_output_paths_fail_before_any_work(tmp_path, monkeypatch, capsys, option, value,
                                               text):
    monkeypatch.chdir(tmp_path)
    called = []
    monkeypatch.setattr("microconveyor_env.studies.sensitivity.sensitivity_rows",
                        lambda *a, **k: called.append(1) or [])
    assert main(["sensitivity", "--json", "--quick", option, value]) == 2
    out, err = capsys.readouterr()
    assert text in json.loads(out)["error"] and len(err.splitlines()) == 1
    assert not called and os.listdir(tmp_path) == []


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes anywhere")
def test_unwritable_folder_fails_before_any_work(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    assert main(["engage", "--json", "--out", str(locked / "e.csv")]) == 2
    assert "not writable" in json.loads(capsys.readouterr().out)["error"]


def test_staged_outputs_all_or_nothing(tmp_path):
    rows = [{"x_m": 1.0}]
    with pytest.raises(RuntimeError), outputs() as files:
        files.table(rows, str(tmp_path / "a.csv"))
        raise RuntimeError("interrupted before the end")
    assert os.listdir(tmp_path) == []
    with outputs() as files:
        assert files.table(rows, str(tmp_path / "a.csv")) == str(tmp_path / "a.csv")
        assert "a.csv" not in os.listdir(tmp_path)  # staged under a temporary name till the end
    assert os.listdir(tmp_path) == ["a.csv"]


class _InterruptedFinalizer:
    """An object whose ``__del__`` receives the Ctrl-C (as numba's compiler objects can)."""

    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10_000):  # bytecodes for the handler to run (and raise) in here
            pass


class _FailingFinalizer:
    def __del__(self):
        raise ValueError("a finalizer's own error")


def test_a_ctrl_c_lost_in_a_finalizer_still_discards_the_outputs(tmp_path, monkeypatch):
    """Python hands an exception raised in ``__del__`` to ``sys.unraisablehook`` (by default it
    prints "Exception ignored") and goes on. Under main()'s latch the SIGINT is remembered, the
    lost KeyboardInterrupt is kept off stderr (the command's one line reports it), other lost
    errors still reach the hook, and the staged outputs are discarded, not committed."""
    from microconveyor_env.cli import base

    lost = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: lost.append(u.exc_type))
    collector = sys.unraisablehook
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        undo = base._install_sigint_latch()               # what main() does first
        obj = _InterruptedFinalizer()
        del obj                                           # the KeyboardInterrupt is lost in __del__
        assert base._sigint_seen and lost == []
        obj = _FailingFinalizer()
        del obj
        assert lost == [ValueError]
        with pytest.raises(KeyboardInterrupt), outputs() as files:
            files.table([{"x_m": 1.0}], str(tmp_path / "a.csv"))
        assert os.listdir(tmp_path) == []
        undo()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert sys.unraisablehook is collector
    finally:
        signal.signal(signal.SIGINT, previous)
        base._sigint_seen = False


def test_main_latches_sigint_only_over_pythons_own_handler():
    """An ignored SIGINT (a background job) stays ignored; the handler is restored after."""
    from microconveyor_env.cli import base

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        undo = base._install_sigint_latch()
        assert signal.getsignal(signal.SIGINT) is base._latch_sigint
        undo()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        base._install_sigint_latch()()
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


# ----------------------------------------------------------------------------- Ctrl-C
def _sigint_default() -> None:
    """In the child before exec: SIGINT back to its default. A shell that starts a command in
    the background (``cmd &``, as CI runners and nohup'd runs may) ignores SIGINT, the child
    inherits that, and Python then installs no KeyboardInterrupt handler: the Ctrl-C test would
    measure the launcher, not the CLI."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("workers", ["0", "2"])
def test_ctrl_c_exits_130_with_one_line_and_no_output(tmp_path, workers):
    """SIGINT to the whole process group (a terminal's Ctrl-C) once the study is under way (its
    first contact table lands in the fresh cache): exit 130, one line on stderr, one JSON object
    on stdout, no output file (partial or not)."""
    out_dir, cache = tmp_path / "out", tmp_path / "cache"
    out_dir.mkdir()
    cache.mkdir()
    p = subprocess.Popen([sys.executable, "-m", "microconveyor_env.cli", "sensitivity", "--quick",
                          "--json", "--no-progress", "--workers", workers,
                          "--out", str(out_dir / "s.csv"), "--plot", str(out_dir / "s.png")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=_sigint_default,
                         env={**os.environ, "MICROCONVEYOR_CACHE_DIR": str(cache)})
    try:
        t_end = time.monotonic() + 120
        while not any(cache.glob("*.npz")) and p.poll() is None and time.monotonic() < t_end:
            time.sleep(0.02)
        assert p.poll() is None, f"ended before the interrupt: {p.communicate()}"
        os.killpg(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130, err
    assert err.splitlines() == ["microconveyor sensitivity: interrupted"]
    assert json.loads(out) == {"error": "interrupted", "error_type": "KeyboardInterrupt"}
    assert os.listdir(out_dir) == []
