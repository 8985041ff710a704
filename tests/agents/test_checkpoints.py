"""Checkpoints survive kill -9 and a full disk; --resume refuses what it cannot honour; one
training per folder (issue 17, items 2 and 3)."""
import errno
import json
import math
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts import checkpoint as ck  # noqa: E402
from agents.rl.artefacts.checkpoint import CheckpointError  # noqa: E402
from support.cli import run_cli  # noqa: E402

SMALL = {"n_envs": 16, "n_steps": 32, "batch_size": 256, "n_epochs": 1}
SMALL_YAML = ("MicroConveyor-v0:\n  env_kwargs: {num_threads: 1}\n  n_envs: 16\n  n_steps: 32\n"
              "  batch_size: 256\n  n_epochs: 1\n  n_timesteps: 1000000\n  policy: 'MlpPolicy'\n"
              "  normalize: \"dict(norm_obs=True, norm_reward=True, gamma=0.99)\"\n"
              "  learning_rate: lin_3e-4\n  policy_kwargs: \"dict(net_arch=dict(pi=[32], vf=[32]))\"\n")


def _files(folder):
    (folder / "model.zip").write_bytes(os.urandom(1000))
    (folder / "normalization.json").write_text("{}")


# ------------------------------------------------------------------------ generations
def test_generations_are_complete_verified_and_pruned(tmp_path):
    for steps in (100, 200, 300):
        gen = ck.write_generation(tmp_path, steps, {"algo": "x"}, _files)
        assert gen.name == f"gen-{steps:012d}"
    assert [g.name for g in ck.generations(tmp_path)] == ["gen-000000000300", "gen-000000000200"]
    assert ck.latest(tmp_path).steps == 300
    (ck.generations(tmp_path)[0] / "model.zip").write_bytes(b"truncated")  # damage the newest
    latest = ck.latest(tmp_path)
    assert latest.steps == 200 and "sha256 differs" in latest.skipped[0]
    dead = tmp_path / "checkpoints" / ".tmp-000000000400-999999999"  # a killed writer's leftovers
    dead.mkdir()
    ck.prune(tmp_path)
    assert not dead.exists()


def test_a_failed_write_keeps_the_previous_generation(tmp_path):
    ck.write_generation(tmp_path, 100, {}, _files)

    def full_disk(folder):
        (folder / "model.zip").write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(CheckpointError, match="step 200 could not be written .No space left on "
                                              "device.; the checkpoint at step 100 is intact"):
        ck.write_generation(tmp_path, 200, {}, full_disk)
    assert ck.latest(tmp_path).steps == 100
    assert not list((tmp_path / "checkpoints").glob(".tmp-*"))


def test_one_training_per_folder_and_the_lock_dies_with_its_owner(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from pathlib import Path; "
         "from agents.rl.artefacts.checkpoint import folder_lock\n"
         f"with folder_lock(Path({str(tmp_path)!r})):\n print('locked', flush=True); time.sleep(120)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(CheckpointError, match=f"in use by another training .pid {holder.pid}"):
            with ck.folder_lock(tmp_path):
                pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with ck.folder_lock(tmp_path):  # kill -9 released it: no stale lock
        pass


# ------------------------------------------------------------------------ resume refusals
def test_resume_refuses_what_it_cannot_honour(tmp_path):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    kw = dict(steps=512, seed=0, overrides=SMALL, checkpoint_freq=512, eval_freq=0,
              eval_targets=0, progress_bar=False, tensorboard=False)
    with pytest.raises(CheckpointError, match="nothing to resume .* no checkpoint in it"):
        train(tmp_path / "empty", TrainSettings(resume=True, **kw))
    train(tmp_path / "a", TrainSettings(**kw))
    with pytest.raises(CheckpointError, match="already holds a training .*--resume"):
        train(tmp_path / "a", TrainSettings(**kw))
    with pytest.raises(CheckpointError, match="another config .*gamma.*--allow-config-change"):
        train(tmp_path / "a", TrainSettings(resume=True, **{**kw, "overrides": {**SMALL,
                                            "gamma": 0.9}}))
    meta = train(tmp_path / "a", TrainSettings(resume=True, allow_config_change=True, **{**kw,
                                               "steps": 1024, "overrides": {**SMALL,
                                               "gamma": 0.9}}))
    assert meta["config_changes"][0]["at_steps"] == 512 and meta["hyperparams"]["gamma"] == 0.9
    for gen in ck.generations(tmp_path / "a"):            # only damaged checkpoints left
        (gen / "normalization.json").write_text("{")
    with pytest.raises(CheckpointError, match="none of its 2 checkpoint.s. is complete"):
        train(tmp_path / "a", TrainSettings(resume=True, allow_config_change=True, **kw))
    (tmp_path / "old" / "checkpoint").mkdir(parents=True)     # an earlier version's layout
    with pytest.raises(CheckpointError, match="earlier version .*cannot be resumed safely"):
        train(tmp_path / "old", TrainSettings(resume=True, **kw))


def test_resume_continues_the_whole_runs_budgets_and_schedule(tmp_path, monkeypatch):
    """Steps, wall time and the learning-rate schedule count from the run's start: a resumed run
    picks the schedule up where it stopped (no sawtooth), and one with nothing left is refused
    with a message, not stopped after one rollout."""
    from agents.rl.training.algos import algo_class
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train
    BudgetPPO = algo_class("ppo")

    kw = dict(seed=0, overrides=SMALL, checkpoint_freq=512, eval_freq=0, eval_targets=0,
              progress_bar=False, tensorboard=False)
    train(tmp_path / "a", TrainSettings(steps=512, **kw))
    with pytest.raises(ValueError, match="already has 512 of its 512 steps"):
        train(tmp_path / "a", TrainSettings(steps=512, resume=True, **kw))
    with pytest.raises(ValueError, match="already used .* of its --max-minutes 1e-05"):
        train(tmp_path / "a", TrainSettings(steps=4096, max_minutes=1e-5, resume=True, **kw))
    seen = []
    orig = BudgetPPO._update_current_progress_remaining

    def record(self, num_timesteps, total_timesteps):
        orig(self, num_timesteps, total_timesteps)
        seen.append(self._current_progress_remaining)

    monkeypatch.setattr(BudgetPPO, "_update_current_progress_remaining", record)
    lines = []
    meta = train(tmp_path / "a", TrainSettings(steps=2048, resume=True, **kw), log=lines.append)
    assert meta["steps"] >= 2048
    # SB3 updates the progress after each 512-step rollout: the first resumed one ends at step
    # 1024 of 2048 (0.5 remaining); a schedule restarted from the resumed step would say 0.75
    assert seen[:3] == pytest.approx([0.5, 0.25, 0.0], abs=0.01)
    assert any("continuing at step 512 of 2048" in line for line in lines)


def test_resume_continues_the_runs_own_seed_and_records_it(tmp_path):
    """SB3 reseeds a loaded model from its checkpoint, so a resume trains on the run's seed
    whatever it is given: the metadata says that seed, and another one is refused instead of
    being recorded while the run goes on under its own."""
    import zipfile

    from agents.rl.training.settings import TrainSettings

    from agents.rl.training.train import train

    kw = dict(overrides=SMALL, checkpoint_freq=512, eval_freq=0, eval_targets=0,
              progress_bar=False, tensorboard=False)
    train(tmp_path / "a", TrainSettings(steps=512, seed=3, **kw))
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    with pytest.raises(ValueError, match="seed 9: this run trains with seed 3"):
        train(tmp_path / "a", TrainSettings(steps=2048, seed=9, resume=True, **kw))
    lines: list[str] = []
    # 2,048 steps: the last update of a run has a learning rate of 0, so a resume for one
    # rollout would leave any weights as they were
    meta_a = train(tmp_path / "a", TrainSettings(steps=2048, resume=True, **kw), log=lines.append)
    meta_b = train(tmp_path / "b", TrainSettings(steps=2048, seed=3, resume=True, **kw))
    assert meta_a["seed"] == meta_b["seed"] == 3
    assert any("seed 3" in line for line in lines if line.startswith("resume: from step"))

    def weights(run):
        with zipfile.ZipFile(run / "model.zip") as z:
            return z.read("policy.pth")
    assert weights(tmp_path / "a") == weights(tmp_path / "b")
    assert train(tmp_path / "c", TrainSettings(steps=512,
                                               **kw))["seed"] == 0       # a new run: seed 0


def test_a_fork_continues_a_checkpoint_under_another_seed(tmp_path):
    """--fork-seed: the same checkpoint continued under another seed trains on other samples
    (the same fork seed twice: the same weights), the metadata records the fork, and a later
    resume continues the fork's seed."""
    import zipfile

    from agents.rl.training.settings import TrainSettings

    from agents.rl.training.train import train

    kw = dict(overrides=SMALL, checkpoint_freq=512, eval_freq=0, eval_targets=0,
              progress_bar=False, tensorboard=False)
    with pytest.raises(ValueError, match="needs resume"):
        train(tmp_path / "x", TrainSettings(steps=512, fork_seed=5, **kw))
    train(tmp_path / "a", TrainSettings(steps=512, seed=3, **kw))
    for name in ("f5", "f5b", "f6"):
        shutil.copytree(tmp_path / "a", tmp_path / name)
    # 2,048 steps: two updates with a learning rate above 0 (the run's last one has 0)
    lines: list[str] = []
    metas = {name: train(tmp_path / name, TrainSettings(steps=2048, resume=True, fork_seed=fs, **kw),
                                                        log=lines.append)
             for name, fs in (("f5", 5), ("f5b", 5), ("f6", 6))}
    said = [x for x in lines if x.startswith("resume: from step 512")]
    assert len(said) == 3 and "forked to seed 6 from seed 3" in said[-1]
    plain = train(tmp_path / "a", TrainSettings(steps=2048, resume=True, **kw))

    def weights(run):
        with zipfile.ZipFile(run / "model.zip") as z:
            return z.read("policy.pth")
    assert weights(tmp_path / "f5") == weights(tmp_path / "f5b")
    assert len({weights(tmp_path / n) for n in ("f5", "f6", "a")}) == 3
    assert metas["f5"]["seed"] == 5 and plain["seed"] == 3 and "forks" not in plain
    assert metas["f6"]["forks"] == [{"at_steps": 512, "from_seed": 3, "seed": 6}]
    again = train(tmp_path / "f6", TrainSettings(steps=2560, resume=True, **kw))
    assert again["seed"] == 6 and again["forks"] == metas["f6"]["forks"]


@pytest.mark.parametrize("bad", [{"max_minutes": math.nan}, {"max_minutes": -1.0},
                                 {"max_minutes": 0}, {"steps": 0}, {"steps": 1.5},
                                 {"checkpoint_freq": 0}, {"eval_freq": -1}])
def test_invalid_budgets_are_refused(tmp_path, bad):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    with pytest.raises(ValueError, match=next(iter(bad))):
        train(tmp_path, TrainSettings(**{"steps": 512, "progress_bar": False, **bad}))
    assert not tmp_path.joinpath("checkpoints").exists()


def test_cli_refuses_bad_budgets_and_empty_resume(tmp_path):
    """In this process (the console script's exit status 2 on a refusal: the first run of
    test_write_failure_at_the_first_save_leaves_nothing_broken)."""
    for args in (["--max-minutes", "nan"], ["--max-minutes", "-1"], ["--max-minutes", "0"],
                 ["--resume"]):
        r = run_cli("train", "--env", "MicroConveyor-v0", "--out", str(tmp_path / "run"), *args,
                    "--json")
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "error" in json.loads(r.stdout)


# ------------------------------------------------------------------------ kill -9 and full disk
def _cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                          capture_output=True, text=True, timeout=600, **kw)


def _train_cmd(out, conf, *extra):
    return [sys.executable, "-m", "microconveyor_env.cli", "train", "--env", "MicroConveyor-v0",
            "--out", str(out),
            "--conf-file", str(conf), "--checkpoint-freq", "512", "--eval-freq", "0",
            "--eval-targets", "0", "--no-progress", *extra]


class _Lines:
    """Collects a child's stderr lines in a thread (so the test can wait for them)."""

    def __init__(self, proc):
        self.lines, self.proc = [], proc
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line.strip())

    def saved(self):
        return [int(x.split()[2]) for x in list(self.lines) if x.startswith("checkpoint: step")]

    def wait_for(self, pred, timeout=120):
        t0 = time.time()
        while not pred() and time.time() - t0 < timeout and self.proc.poll() is None:
            time.sleep(0.02)
        return pred()


def kill_and_resume(tmp_path, kills: int, seed: int = 0) -> list[dict]:
    """Train, kill -9 at a random moment after the first checkpoint, resume; ``kills`` times.
    After every kill the newest complete checkpoint is at least the last one the run reported
    saved (so at most one interval of training is lost) and the next run resumes from it."""
    rng = random.Random(seed)
    conf = tmp_path / "small.yml"
    conf.write_text(SMALL_YAML)
    out = tmp_path / "run"
    report = []
    for i in range(kills):
        proc = subprocess.Popen(_train_cmd(out, conf, *(["--resume"] if i else [])),
                                stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
        lines = _Lines(proc)
        start = len(lines.saved())
        assert lines.wait_for(lambda lines=lines, start=start: len(lines.saved()) > start), lines.lines
        time.sleep(rng.uniform(0.0, 1.5))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        last_saved = max(lines.saved())
        mid_write = bool(list((out / "checkpoints").glob(".tmp-*")))
        gen = ck.latest(out)
        assert gen is not None and gen.steps >= last_saved, (gen, last_saved)
        resumed = [x for x in lines.lines if x.startswith("resume: from step")]
        report.append({"kill": i, "last_saved": last_saved, "resumable_from": gen.steps,
                       "killed_mid_write": mid_write, "resumed_line": resumed[:1]})
        if i:
            assert resumed and int(resumed[0].split()[3]) == report[i - 1]["resumable_from"]
    final = _cli(*_train_cmd(out, conf, "--resume", "--steps", str(ck.latest(out).steps + 512))[3:])
    assert final.returncode == 0, final.stderr
    from agents.rl.evaluation.evaluate import evaluate, load_policy

    assert evaluate(load_policy(out), 4, seed=1)["n_targets"] == 4
    return report


@pytest.mark.slow   # the same property as test_kill_9_twenty_times (slow too), with 3 kills
def test_kill_9_at_random_moments_then_resume(tmp_path):
    report = kill_and_resume(tmp_path, kills=3)
    assert len(report) == 3


@pytest.mark.slow
def test_kill_9_twenty_times(tmp_path):
    report = kill_and_resume(tmp_path, kills=20, seed=1)
    print(json.dumps(report))
    assert len(report) == 20


def _limit_file_size(limit):
    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # the write fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return pre


def test_write_failure_at_the_first_save_leaves_nothing_broken(tmp_path):
    """A write that fails part-way (a file-size limit standing in for a full disk) at the first
    checkpoint: a clear error, no truncated checkpoint, and the folder can start again."""
    conf = tmp_path / "small.yml"
    conf.write_text(SMALL_YAML)
    out = tmp_path / "run"
    r = subprocess.run(_train_cmd(out, conf, "--steps", "2048", "--json"), capture_output=True,
                       text=True, timeout=600, preexec_fn=_limit_file_size(20_000))
    assert r.returncode == 2, r.stderr
    err = json.loads(r.stdout)["error"]
    assert "step 512 could not be written" in err and "no earlier checkpoint" in err
    assert ck.generations(out) == [] and not list((out / "checkpoints").glob(".tmp-*"))
    # the rest in this process (no file-size limit: space back)
    r = run_cli(*_train_cmd(out, conf, "--resume", "--json")[3:])
    assert r.returncode == 2 and "nothing to resume" in r.stdout
    r = run_cli(*_train_cmd(out, conf, "--steps", "1024")[3:])   # it starts afresh
    assert r.returncode == 0, r.stderr
    assert ck.latest(out).steps == 1024


def _fill(path, leave_bytes):
    """Fill the file system of ``path`` with a file until it is full, then give back
    ``leave_bytes`` (so small writes still work but a checkpoint does not fit)."""
    with open(path, "wb") as fh:
        block = b"\0" * (1 << 16)
        try:
            while True:
                fh.write(block)
                fh.flush()
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
        size = fh.tell()
    os.truncate(path, max(0, size - leave_bytes))


@pytest.mark.slow
@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("mount") is None,
                    reason="mounting a small tmpfs needs root")
def test_full_disk_mid_training_keeps_the_previous_checkpoint(tmp_path):
    """A real full disk: the run's folder is on a 64 MB tmpfs that is filled up right after the
    first checkpoint; the next checkpoint fails, the run stops with one clear line, the first
    checkpoint is intact, and --resume works once there is room again."""
    conf = tmp_path / "small.yml"
    conf.write_text(SMALL_YAML)
    mnt = tmp_path / "disk"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(mnt)]).returncode:
        pytest.skip("cannot mount tmpfs here")
    try:
        out = mnt / "run"
        proc = subprocess.Popen(_train_cmd(out, conf, "--steps", "1000000", "--json"),
                                stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        lines = _Lines(proc)
        assert lines.wait_for(lambda: len(lines.saved()) >= 1), lines.lines
        _fill(mnt / "filler", leave_bytes=8192)
        stdout = proc.stdout.read()
        assert proc.wait(timeout=300) == 2
        err = json.loads(stdout)["error"]
        assert "could not be written (No space left on device)" in err and "is intact" in err
        gen = ck.latest(out)
        assert gen is not None and gen.steps >= lines.saved()[0]
        assert not list((out / "checkpoints").glob(".tmp-*"))
        (mnt / "filler").unlink()
        r = subprocess.run(_train_cmd(out, conf, "--resume", "--steps", str(gen.steps + 512)),
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        assert f"resume: from step {gen.steps}" in r.stderr
    finally:
        subprocess.run(["umount", "-l", str(mnt)])
