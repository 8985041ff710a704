"""Policy folders are written whole or not at all, by one writer, never through a symbolic link:
the shared writer (staging beside the destination, metadata with the files' sha256 last,
verified, renamed into place, under a lock), `imitate` on it (its --out checked before any work),
`train --refine` (its refined folder held for the whole command), `train`'s final files (a kill
between them never leaves a folder that the loader loads as a wrong policy) and its run folder
(no symbolic link inside is written through)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts import checkpoint as ck  # noqa: E402
from agents.rl.artefacts.checkpoint import CheckpointError  # noqa: E402
from agents.rl.artefacts.folders import (  # noqa: E402
    NewPolicyFolder,
    write_file,
    write_policy_folder,
)

TINY = ["--rounds", "1", "--episodes", "2"]


def _two_files(folder: Path) -> dict:
    (folder / "model.zip").write_bytes(b"model")
    (folder / "normalization.json").write_text("{}")
    return {"env_id": "MicroPositioner-v0"}


# ------------------------------------------------------------------ the shared writer
def test_a_policy_folder_is_written_whole_with_its_hashes_last(tmp_path):
    out = write_policy_folder(tmp_path / "p", _two_files)
    assert sorted(p.name for p in out.iterdir()) == ["metadata.json", "model.zip",
                                                     "normalization.json"]
    meta = json.loads((out / "metadata.json").read_text())
    assert list(meta)[-1] == "files" and set(meta["files"]) == {"model.zip", "normalization.json"}
    ck.verify_files(out, meta)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p"]   # no staging, no lock left


def test_a_writer_that_fails_midway_leaves_nothing(tmp_path):
    def half(folder: Path) -> dict:
        (folder / "model.zip").write_bytes(b"model")
        raise OSError("killed between files")

    with pytest.raises(OSError, match="killed between files"):
        write_policy_folder(tmp_path / "p", half)
    assert list(tmp_path.iterdir()) == []


def test_a_killed_writer_leaves_no_folder_and_the_next_one_cleans_up(tmp_path):
    out = tmp_path / "p"
    code = ("import sys, time\nfrom pathlib import Path\n"
            "from agents.rl.artefacts.folders import write_policy_folder\n"
            "def files(folder):\n"
            "    (folder / 'model.zip').write_bytes(b'model')\n"
            "    print('written', flush=True)\n"
            "    time.sleep(120)\n"
            f"write_policy_folder(Path({str(out)!r}), files)\n")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "written"
        staging = tmp_path / f".p.tmp-{child.pid}"
        assert (staging / "model.zip").is_file()
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    assert not out.exists() and staging.exists()   # killed: no policy folder, only the staging
    write_policy_folder(out, _two_files)           # the next writer: its place is clean again
    assert not staging.exists() and (out / "metadata.json").is_file()


def test_a_second_writer_is_refused_naming_the_first(tmp_path):
    out = tmp_path / "p"
    with NewPolicyFolder(out):
        with pytest.raises(ValueError, match=rf"being written by another command \(pid "
                                             rf"{os.getpid()} on "):
            with NewPolicyFolder(out):
                pass
    with NewPolicyFolder(out) as folder:   # released: a later writer goes ahead
        folder.write(_two_files)


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_text("x"), "is a file"),
    (lambda p: (p.mkdir(), (p / "old.txt").write_text("x")), "exists and is not empty"),
    (lambda p: p.symlink_to(p.parent / "elsewhere", target_is_directory=True),
     "is a symbolic link"),
])
def test_an_occupied_destination_is_refused(tmp_path, make, words):
    out = tmp_path / "p"
    make(out)
    with pytest.raises(ValueError, match=words):
        write_policy_folder(out, _two_files)
    assert not (tmp_path / "elsewhere").exists()


def test_a_file_is_replaced_whole_and_never_through_a_link(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("keep")
    (tmp_path / "best.yml").symlink_to(victim)
    with pytest.raises(ValueError, match="not a regular file"):
        write_file(tmp_path / "best.yml", "new")
    assert victim.read_text() == "keep"
    write_file(tmp_path / "b.yml", "one")
    write_file(tmp_path / "b.yml", "two")
    assert (tmp_path / "b.yml").read_text() == "two"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.yml", "best.yml", "victim"]


# ------------------------------------------------------------------ imitate
def _imitate(out: str, *extra: str) -> int:
    from microconveyor_env.cli import main

    return main(["imitate", "--out", out, *TINY, *extra])


def _refused_at_once(capsys, status: int, words: str) -> None:
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert status == 2 and len(err) == 1 and words in err[0], cap.err
    assert "round 0" not in cap.out + cap.err   # refused before any training


def test_imitate_refuses_an_empty_out_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    _refused_at_once(capsys, _imitate(""), "names no new folder")
    assert list(tmp_path.iterdir()) == []


def test_imitate_refuses_a_file_or_a_folder_with_a_link_before_any_work(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    _refused_at_once(capsys, _imitate(str(tmp_path / "file")), "is a file")
    _refused_at_once(capsys, _imitate(str(tmp_path / "file" / "p")), "cannot be written")
    victim = tmp_path / "victim.zip"
    victim.write_bytes(b"keep")
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "model.zip").symlink_to(victim)
    _refused_at_once(capsys, _imitate(str(tmp_path / "p")), "exists and is not empty")
    assert victim.read_bytes() == b"keep"


def test_imitate_refuses_a_second_writer_of_the_same_out(tmp_path, capsys):
    with NewPolicyFolder(tmp_path / "p"):
        _refused_at_once(capsys, _imitate(str(tmp_path / "p")), "being written by another "
                                                                "command (pid ")
    assert not (tmp_path / "p").exists()


def test_imitate_killed_between_files_leaves_no_folder_that_loads(tmp_path, monkeypatch):
    """A failure after the model and statistics are written but before the metadata (here the
    hashing of the files): nothing at --out, no staging left, nothing loads there."""
    from agents.imitation.dagger import DaggerSettings, dagger
    from agents.rl.evaluation.evaluate import load_policy

    def killed(path: Path) -> str:
        raise OSError("killed between files")

    monkeypatch.setattr(ck, "sha256", killed)
    s = DaggerSettings(rounds=1, episodes=2, epochs=1, frequencies=5, strokes=2, margin=2)
    with pytest.raises(OSError, match="killed between files"):
        dagger(tmp_path / "p", s, progress=lambda line: None)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(Exception, match="no policy at"):
        load_policy(tmp_path / "p")


# ------------------------------------------------------------------ train --refine
def test_train_refine_holds_the_refined_folder_for_the_whole_command(tmp_path, monkeypatch,
                                                                      capsys):
    """`train --refine` holds OUT/refined from before the training to the end: another writer
    of it is refused during the training, and one already writing it refuses the command
    before any training."""
    import agents.rl.training.train as train_mod
    from agents.rl.artefacts.folders import NewPolicyFolder
    from microconveyor_env.cli import main

    out = tmp_path / "run"
    seen = []

    def training(folder, settings, log=None):
        try:
            with NewPolicyFolder(Path(folder) / "refined"):
                seen.append("entered")
        except ValueError as exc:
            seen.append(str(exc))
        raise ValueError("the training stops here")

    monkeypatch.setattr(train_mod, "train", training)
    assert main(["train", "--out", str(out), "--steps", "4096", "--refine"]) != 0
    assert len(seen) == 1 and "being written by another command" in seen[0]
    with NewPolicyFolder(out / "refined"):   # released when the command ends
        pass
    monkeypatch.undo()
    capsys.readouterr()
    with NewPolicyFolder(out / "refined"):   # another command writing it: refused before training
        assert main(["train", "--out", str(out), "--steps", "4096", "--refine"]) != 0
    assert "being written by another command" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == []   # nothing trained


# ------------------------------------------------------------------ train's final files
def _shipped(name: str) -> tuple[bytes, bytes]:
    """The model and statistics of the shipped MicroConveyor-v0 policy ``name``."""
    from agents.rl.artefacts.shipped import shipped_path

    folder = shipped_path(name, "MicroConveyor-v0")
    return (folder / "model.zip").read_bytes(), (folder / "normalization.json").read_bytes()


def _policy(folder: Path, model: bytes, norm: bytes | None) -> None:
    """A policy's final files as a generation holds them: a real model and its statistics
    (none: the metadata says it reads raw observations), the metadata listing them."""
    from agents.rl.artefacts.shipped import shipped_path

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.zip").write_bytes(model)
    if norm is not None:
        (folder / "normalization.json").write_bytes(norm)
    names = ["model.zip"] + (["normalization.json"] if norm is not None else [])
    meta = json.loads((shipped_path("ppo", "MicroConveyor-v0") / "metadata.json").read_text())
    if norm is None:
        meta["hyperparams"]["normalize"] = None
    meta["files"] = {n: ck.sha256(folder / n) for n in names}
    (folder / "metadata.json").write_text(json.dumps(meta))


def _loads_as(folder: Path) -> tuple[bytes, bytes | None] | None:
    """What the policy loader (:func:`agents.rl.evaluation.evaluate.load_policy`) acts with at
    ``folder``: (model bytes, statistics bytes, None where it reads raw observations), or None
    where it refuses the folder."""
    from agents.rl.artefacts.policy_files import PolicyError
    from agents.rl.evaluation.evaluate import load_policy

    try:
        pol = load_policy(folder)
    except PolicyError:
        return None
    norm = (folder / "normalization.json").read_bytes() if pol.normalizer is not None else None
    return (folder / "model.zip").read_bytes(), norm


def test_loads_as_is_the_loaders_word(tmp_path):
    """A folder "loads" only where load_policy accepts it: metadata without ``files`` (or with
    a stale hash) does not, whatever files lie there."""
    old = _shipped("ppo")
    _policy(tmp_path / "p", *old)
    assert _loads_as(tmp_path / "p") == old
    meta = json.loads((tmp_path / "p" / "metadata.json").read_text())
    (tmp_path / "p" / "metadata.json").write_text(json.dumps(
        {k: v for k, v in meta.items() if k != "files"}))
    assert _loads_as(tmp_path / "p") is None
    meta["files"]["model.zip"] = "0" * 64
    (tmp_path / "p" / "metadata.json").write_text(json.dumps(meta))
    assert _loads_as(tmp_path / "p") is None


@pytest.mark.parametrize("raw_observations", [False, True])
def test_train_final_files_killed_at_any_point_never_load_as_a_wrong_policy(tmp_path,
                                                                            monkeypatch,
                                                                            raw_observations):
    """A resumed run (allowed a config change) replacing a finished run's files: a kill before
    any rename leaves the old policy, after the last the new one, in between nothing loads;
    the old statistics never stay with a new model that has none."""
    old = _shipped("ppo")
    model, norm = _shipped("ppo_randomised")
    new = (model, None if raw_observations else norm)
    gen = tmp_path / "gen"
    _policy(gen, *new)
    assert _loads_as(gen) == new and _loads_as(gen) != old
    names = tuple(n for n in ("model.zip", "normalization.json") if (gen / n).is_file()) \
        + ("metadata.json",)
    real_replace = os.replace
    for kill_at in range(len(names) + 1):
        out = tmp_path / f"out-{kill_at}"
        _policy(out, *old)
        assert _loads_as(out) == old
        calls = []

        def replace(src, dst, calls=calls, kill_at=kill_at):
            if len(calls) == kill_at:
                raise KeyboardInterrupt("killed")
            calls.append(dst)
            real_replace(src, dst)

        monkeypatch.setattr(os, "replace", replace)
        try:
            ck.replace_files(gen, out, names)
        except KeyboardInterrupt:
            pass
        finally:
            monkeypatch.setattr(os, "replace", real_replace)
        got = _loads_as(out)
        assert got in (None, old, new), kill_at
        if kill_at == len(names):
            assert got == new


def test_train_refuses_a_symbolic_link_inside_its_folder(tmp_path):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    victim = tmp_path / "victim"
    victim.write_text("keep")
    out = tmp_path / "run"
    out.mkdir()
    (out / "evaluations.jsonl").symlink_to(victim)
    with pytest.raises(ValueError, match="holds a symbolic link 'evaluations.jsonl'"):
        train(out, TrainSettings(env_id="MicroConveyor-v0", steps=64))
    assert victim.read_text() == "keep" and not (out / "checkpoints").exists()
    (tmp_path / "link").symlink_to(out, target_is_directory=True)
    with pytest.raises(ValueError, match="is a symbolic link"):
        train(tmp_path / "link", TrainSettings(env_id="MicroConveyor-v0", steps=64))


def test_the_training_lock_is_never_taken_through_a_link(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("keep")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / ".lock").symlink_to(victim)
    t0 = time.monotonic()
    with pytest.raises(CheckpointError, match="never followed"):
        with ck.folder_lock(tmp_path / "run"):
            pass
    assert victim.read_text() == "keep" and time.monotonic() - t0 < 5
