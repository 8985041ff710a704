"""A policy folder received from someone else is data: loading it imports nothing it names,
allocates nothing it asks for, reads only regular files of the folder within byte limits, and
fails as one PolicyError naming the file. Each case is what an attacker would write."""
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.policy_files import PolicyError, load_policy  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from support.cli import run_cli  # noqa: E402


def _sac_folder(tmp_path, name="sac", dict_obs=False):
    """A raw-observation SAC policy folder of MicroConveyor-v1 (untrained: a crafted file's
    starting point)."""
    from stable_baselines3 import SAC

    from microconveyor_env.envs import MicroConveyorEnv, env_config

    folder = tmp_path / name
    folder.mkdir()
    SAC("MlpPolicy", MicroConveyorEnv(config=env_config("MicroConveyor-v1")), buffer_size=10,
        device="cpu").save(folder / "model.zip")
    (folder / "metadata.json").write_text(json.dumps(
        {"algo": "sac", "env_id": "MicroConveyor-v1", "hyperparams": {"normalize": None}}))
    _rehash(folder)
    return folder


def _rehash(folder):
    """Record the sha256 of the model (and statistics) now in ``folder`` in its metadata, as
    whoever crafts a folder would, so that the check under test is the one that answers."""
    from agents.rl.artefacts.checkpoint import sha256

    meta = json.loads((folder / "metadata.json").read_text())
    meta["files"] = {n: sha256(folder / n) for n in ("model.zip", "normalization.json")
                     if (folder / n).is_file()}
    (folder / "metadata.json").write_text(json.dumps(meta))


def _edit_zip(path, edit=None, add=None, replace=None):
    """Rewrite the zip at ``path``: ``edit(data dict)`` on its data JSON, ``add`` entries
    {name: bytes}, ``replace`` entries {name: bytes}."""
    with zipfile.ZipFile(path) as zf:
        items = {n: zf.read(n) for n in zf.namelist()}
    if edit is not None:
        data = json.loads(items["data"])
        edit(data)
        items["data"] = json.dumps(data).encode()
    items.update(replace or {})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for n, b in {**items, **(add or {})}.items():
            zf.writestr(n, b)
    if (path.parent / "metadata.json").is_file():
        _rehash(path.parent)


def _cli(*args, cwd=None, timeout=120):
    return subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                          capture_output=True, text=True, timeout=timeout, cwd=cwd)


def test_an_env_name_in_the_model_data_imports_nothing(tmp_path):
    """SB3 would build ``data["env"]`` with gym.make, which imports the module before the
    colon: a ``policyhook.py`` beside the policy ran on ``evaluate --policy .``."""
    folder = _sac_folder(tmp_path)
    marker = tmp_path / "hook-ran"
    (folder / "policyhook.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    _edit_zip(folder / "model.zip", edit=lambda d: d.__setitem__("env", "policyhook:X-v0"))
    r = _cli("evaluate", "--policy", ".", "--targets", "2", "--json", cwd=folder)
    assert r.returncode == 2 and not marker.exists(), r.stdout + r.stderr
    assert "'env' is not one a stable-baselines3 model of this package holds" in r.stdout
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["policy_kwargs"].update(n_critics=10**6), "'policy_kwargs'"),
    (lambda d: d["policy_kwargs"].update(net_arch=[20000, 20000]), "'policy_kwargs'"),
    (lambda d: d.update(buffer_size=10**9), "'buffer_size' = 1000000000 is invalid"),
    (lambda d: d.update(n_envs=10**9), "'n_envs' = 1000000000 is invalid"),
    (lambda d: d.update(gamma=float("nan")), "'gamma'"),
    (lambda d: d.update(verbose="loud"), "'verbose'"),
])
def test_sizes_in_the_model_data_are_bounded_before_anything_is_built(tmp_path, edit, message):
    folder = _sac_folder(tmp_path)
    _edit_zip(folder / "model.zip", edit=edit)
    t0 = time.perf_counter()
    with pytest.raises(PolicyError, match=message):
        load_policy(folder)
    assert time.perf_counter() - t0 < 30   # refused up front, not after allocating


def test_evaluation_builds_no_sb3_model_env_or_buffer(tmp_path, monkeypatch):
    """Only the actor is rebuilt, from the tensors: a plausible n_critics (or any setting SB3
    would allocate from) is never acted on."""
    from stable_baselines3.common import base_class, buffers

    folder = _sac_folder(tmp_path)
    _edit_zip(folder / "model.zip", edit=lambda d: d["policy_kwargs"].update(n_critics=32))

    def refuse(*a, **k):
        raise AssertionError("an SB3 model or buffer was built to evaluate a policy")

    monkeypatch.setattr(base_class.BaseAlgorithm, "__init__", refuse)
    monkeypatch.setattr(buffers.BaseBuffer, "__init__", refuse)
    pol = load_policy(folder)
    assert pol.act(np.zeros((2, 6), np.float32)).shape == (2, 3)


@pytest.mark.parametrize("algo", ["sac", "tqc", "td3"])
def test_rebuilt_actor_acts_exactly_as_sb3_predict(tmp_path, algo):
    """Box and Dict observations: the actor rebuilt from the tensors gives SB3's own
    deterministic actions bit for bit (the shipped PPO policies: tests/agents)."""
    import gymnasium as gym

    import microconveyor_env  # noqa: F401
    from agents.rl.artefacts.actor_net import load_actor
    from agents.rl.artefacts.sb3_files import algo_class

    cls = algo_class(algo)
    for env_id, policy in (("MicroConveyor-v1", "MlpPolicy"),
                           ("MicroConveyorGoal-v1", "MultiInputPolicy")):
        env = gym.make(env_id)
        kw = {"policy_kwargs": {"net_arch": [24, 16]}}
        if algo == "tqc":
            kw["policy_kwargs"].update(n_critics=2, n_quantiles=5)
        model = cls(policy, env, buffer_size=10, device="cpu", seed=1, **kw)
        path = tmp_path / f"{algo}-{env_id}.zip"
        model.save(path)
        actor = load_actor(path, algo, env.observation_space, env.action_space)
        for _ in range(20):
            obs = env.observation_space.sample()
            batch = ({k: v[None] for k, v in obs.items()} if isinstance(obs, dict)
                     else obs[None])
            want, _ = model.predict(batch, deterministic=True)
            assert np.array_equal(actor.predict(batch), want), (algo, env_id)


def test_special_files_are_refused_without_reading_or_blocking(tmp_path):
    for name in ("metadata.json", "normalization.json"):
        folder = tmp_path / f"zero-{name}"
        shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), folder)
        (folder / name).unlink()
        os.symlink("/dev/zero", folder / name)
        with pytest.raises(PolicyError, match="symbolic link"):
            load_policy(folder)
        fifo = tmp_path / f"fifo-{name}"
        shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), fifo)
        (fifo / name).unlink()
        os.mkfifo(fifo / name)
        t0 = time.perf_counter()
        with pytest.raises(PolicyError, match="FIFO"):
            load_policy(fifo)
        assert time.perf_counter() - t0 < 10
    folder = tmp_path / "zip-link"
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), folder)
    (folder / "model.zip").unlink()
    os.symlink("/dev/zero", folder / "model.zip")
    with pytest.raises(PolicyError):
        load_policy(folder)


def test_a_preset_path_in_the_metadata_is_read_within_limits(tmp_path):
    folder = _sac_folder(tmp_path)
    link = tmp_path / "surface.yaml"
    os.symlink("/dev/zero", link)
    meta = json.loads((folder / "metadata.json").read_text())
    meta["env_kwargs"] = {"preset": str(link)}
    (folder / "metadata.json").write_text(json.dumps(meta))
    t0 = time.perf_counter()
    with pytest.raises(PolicyError, match="character device"):
        load_policy(folder)
    assert time.perf_counter() - t0 < 10
    meta["env_kwargs"] = {"path": "/dev/zero"}    # EnvConfig.from_yaml's file argument
    (folder / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyError, match="'path'"):
        load_policy(folder)


def test_a_zip_bomb_is_refused_before_it_is_inflated(tmp_path):
    folder = _sac_folder(tmp_path)
    big = b'{"pad": "' + b" " * (64 << 20) + b'"}'      # 64 MiB of JSON, ~64 kB deflated
    _edit_zip(folder / "model.zip", replace={"data": big})
    assert (folder / "model.zip").stat().st_size < 4 << 20     # a small file on disk
    with pytest.raises(PolicyError, match="data entry would inflate to 67,108,875 bytes"):
        load_policy(folder)


def test_names_that_leave_the_folder_are_refused(tmp_path):
    import hashlib

    folder = tmp_path / "p"
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), folder)
    meta = json.loads((folder / "metadata.json").read_text())
    secret = tmp_path / "secret.txt"
    secret.write_text("x")
    for name in (str(secret), "../secret.txt", "../nothing-here"):
        bad = {**meta, "files": {**meta["files"],
                                 name: hashlib.sha256(b"x").hexdigest()}}
        (folder / "metadata.json").write_text(json.dumps(bad))
        with pytest.raises(PolicyError, match="is not a plain file name") as exc:
            load_policy(folder)
        assert "missing" not in str(exc.value)     # says nothing of what exists outside
    (folder / "metadata.json").write_text(json.dumps(meta))
    _edit_zip(folder / "model.zip", add={"../escape": b"x"})
    with pytest.raises(PolicyError, match="entry '../escape' is not a plain file name"):
        load_policy(folder)


def test_refine_reads_no_file_through_a_link(tmp_path):
    from agents.rl.refinement.writer import write_refined

    folder = tmp_path / "p"
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), folder)
    secret = tmp_path / "secret.jsonl"
    secret.write_text('{"secret": 1}\n')
    os.symlink(secret, folder / "evaluations.jsonl")
    pol = load_policy(folder)
    with pytest.raises(ValueError, match="symbolic link"):
        write_refined(pol, {"wall_time_s": 0.0}, tmp_path / "out", evaluation={"x": 1})
    assert not (tmp_path / "out").exists()


def test_a_pickle_in_policy_pth_is_one_error_without_torch_advice(tmp_path):
    import pickle

    folder = _sac_folder(tmp_path)

    class Payload:
        def __reduce__(self):
            return (os.system, ("true",))

    _edit_zip(folder / "model.zip", replace={"policy.pth": pickle.dumps(Payload())})
    with pytest.raises(PolicyError) as exc:
        load_policy(folder)
    msg = str(exc.value)
    assert "policy.pth is not a file of tensors" in msg and "weights_only" not in msg
    r = _cli("evaluate", "--policy", str(folder), "--targets", "2")
    assert r.returncode == 2 and "weights_only" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_refine_out_is_checked_before_the_refinement(tmp_path):
    """In this process (tests/cli start the console script's processes)."""
    dangling = tmp_path / "dangling"
    os.symlink(tmp_path / "nowhere", dangling)
    src = str(shipped_path("ppo", "MicroConveyor-v1"))
    t0 = time.perf_counter()
    r = run_cli("refine", src, "--out", str(dangling))
    assert r.returncode == 2 and "symbolic link" in r.stderr
    locked = tmp_path / "ro"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        if os.access(locked, os.W_OK):     # root writes anywhere: a file as the parent instead
            target = tmp_path / "a-file" / "out"
            (tmp_path / "a-file").write_text("")
        else:
            target = locked / "out"
        r = run_cli("refine", src, "--out", str(target))
        assert r.returncode == 2 and "cannot be written" in r.stderr, r.stderr
    finally:
        locked.chmod(0o700)
    assert time.perf_counter() - t0 < 60   # refused before minutes of refinement


def test_a_killed_refine_leaves_no_staging_folder_for_long(tmp_path):
    """A staging folder of a writer that died is removed by the next write into that place."""
    from agents.rl.refinement.writer import write_refined

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = tmp_path / f".out.tmp-{dead}"
    stale.mkdir()
    (stale / "model.zip").write_bytes(b"half")
    pol = load_policy(shipped_path("ppo", "MicroConveyor-v1"))
    write_refined(pol, {"wall_time_s": 0.0}, tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
