"""Policy files are data: loading a policy folder runs no code from it, and a folder whose parts
disagree is refused with one error naming the file (issue 17, items 4 and 5)."""
import base64
import json
import os
import pickle
import shutil
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.evaluation.evaluate import PolicyError, load_policy  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from support.cli import run_cli  # noqa: E402


class _Payload:
    """Pickles to ``os.system("touch MARKER")``: what an attacker puts in a policy file."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _copy_shipped(tmp_path, name="ppo"):
    dst = tmp_path / name
    shutil.copytree(shipped_path(name, "MicroConveyor-v0"), dst)
    return dst


def _cli(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def _rewrite_data(zip_path, edit):
    """Rewrite the ``data`` JSON inside an SB3 zip with ``edit(dict)`` (and its recorded hash,
    as whoever crafts a folder would)."""
    with zipfile.ZipFile(zip_path) as zf:
        items = {n: zf.read(n) for n in zf.namelist()}
    data = json.loads(items["data"])
    edit(data)
    items["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as zf:
        for n, b in items.items():
            zf.writestr(n, b)
    if (zip_path.parent / "metadata.json").is_file():
        _rehash(zip_path.parent)


def _rehash(folder):
    """Record the sha256 of the policy files now in ``folder`` in its metadata (what a folder
    edited on purpose carries), so that the check under test is the one that answers."""
    from agents.rl.artefacts.checkpoint import sha256

    meta = json.loads((folder / "metadata.json").read_text())
    meta["files"] = {n: sha256(folder / n) for n in ("model.zip", "normalization.json")
                     if (folder / n).is_file()}
    (folder / "metadata.json").write_text(json.dumps(meta))


def test_shipped_folders_hold_no_pickle_and_load():
    for name in ("ppo", "ppo_randomised"):
        folder = shipped_path(name, "MicroConveyor-v0")
        assert not list(folder.glob("*.pkl"))
        pol = load_policy(folder)
        assert pol.normalizer is not None and pol.metadata["algo"] == "ppo"


def test_malicious_vecnormalize_pickle_is_never_loaded(tmp_path):
    folder = _copy_shipped(tmp_path)
    (folder / "normalization.json").unlink()
    _rehash(folder)
    marker = tmp_path / "pwned-by-pickle"
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(PolicyError, match="is a pickle.*convert-stats"):
        load_policy(folder)
    for cmd in (("evaluate", "--policy", str(folder), "--targets", "2", "--json"),
                ("demo", "--policy", str(folder), "--env", "MicroConveyor-v0", "--out",
                 str(tmp_path / "demo"), "--json")):
        r = _cli(*cmd)
        assert r.returncode == 2 and "is a pickle" in json.loads(r.stdout)["error"], r.stdout
        assert len(r.stderr.strip().splitlines()) == 1
    assert not marker.exists()


def test_malicious_entry_in_model_zip_is_never_unpickled(tmp_path):
    marker = tmp_path / "pwned-by-zip"
    evil = {":type:": "<class 'function'>",
            ":serialized:": base64.b64encode(pickle.dumps(_Payload(marker))).decode()}
    folder = _copy_shipped(tmp_path)
    _rewrite_data(folder / "model.zip", lambda d: d.update(evil_entry=evil))
    with pytest.raises(PolicyError, match="'evil_entry' holds a pickled Python object"):
        load_policy(folder)
    _rewrite_data(folder / "model.zip", lambda d: (d.pop("evil_entry"), d.update(policy_class=evil)))
    with pytest.raises(PolicyError, match=r"policy_class names \['posix.system'\]"):
        load_policy(folder)
    _rewrite_data(folder / "model.zip", lambda d: d.update(learning_rate=evil))  # a known key
    r = _cli("evaluate", "--policy", str(folder), "--targets", "2", "--json")
    assert r.returncode == 2 and "policy_class names" in r.stdout
    assert not marker.exists()


def test_known_pickled_entries_are_replaced_not_unpickled(tmp_path):
    """A payload in an entry the loader replaces (the schedule) is ignored: the policy loads,
    acts, and nothing ran."""
    marker = tmp_path / "pwned-by-schedule"
    evil = {":type:": "<class 'function'>",
            ":serialized:": base64.b64encode(pickle.dumps(_Payload(marker))).decode()}
    folder = _copy_shipped(tmp_path)
    _rewrite_data(folder / "model.zip", lambda d: d.update(learning_rate=evil, lr_schedule=evil))
    pol = load_policy(folder)
    assert pol.act(pol.normalizer.mean[None, :]).shape == (1, 3)
    assert not marker.exists()


def test_conf_file_is_parsed_as_data(tmp_path):
    from agents.rl.training import hyperparams

    marker = tmp_path / "pwned-by-yaml"
    conf = tmp_path / "ppo.yml"
    conf.write_text("MicroConveyor-v0:\n  normalize: \"dict(x=__import__('os').system('touch "
                    f"{marker}'))\"\n")
    with pytest.raises(ValueError, match="nothing in them is evaluated"):
        hyperparams.load(str(conf), "MicroConveyor-v0")
    r = _cli("train", "--env", "MicroConveyor-v0", "--conf-file", str(conf), "--out",
             str(tmp_path / "run"), "--json")
    assert r.returncode == 2 and "nothing in them is evaluated" in r.stdout
    assert not marker.exists()
    ok = hyperparams._eval_dict("dict(net_arch=dict(pi=[64]), activation_fn=nn.ReLU, x=-1e-3)")
    import torch.nn as nn

    assert ok == {"net_arch": {"pi": [64]}, "activation_fn": nn.ReLU, "x": -1e-3}


def test_a2c_zip_is_never_evaluated_as_ppo(tmp_path):
    from stable_baselines3 import A2C

    from microconveyor_env.envs import MicroConveyorEnv

    folder = _copy_shipped(tmp_path)
    A2C("MlpPolicy", MicroConveyorEnv(), n_steps=5, device="cpu").save(folder / "model.zip")
    with pytest.raises(PolicyError, match="not the file metadata.json describes"):
        load_policy(folder)                                   # the recorded hash catches it
    _rehash(folder)
    with pytest.raises(PolicyError, match="says PPO, but .* is an A2C model"):
        load_policy(folder)
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(folder / "model.zip", bare / "model.zip")
    with pytest.raises(PolicyError, match="has no metadata.json: nothing says which env"):
        load_policy(bare / "model.zip")
    with pytest.raises(PolicyError, match="has no normalization.json"):
        load_policy(bare / "model.zip", env_id="MicroConveyor-v0")
    # said to be raw-observation A2C, it is read as A2C: its pickled policy_kwargs (A2C's
    # RMSprop optimizer class) are read by name, never unpickled, and it acts as A2C's actor
    (bare / "metadata.json").write_text(json.dumps({"algo": "a2c", "env_id": "MicroConveyor-v0",
                                                    "hyperparams": {"normalize": None}}))
    _rehash(bare)
    pol = load_policy(bare / "model.zip")
    assert pol.actor.algo == "a2c" and pol.actor.activation == "Tanh"
    model = A2C.load(bare / "model.zip", device="cpu")     # the test's own file: trusted here
    obs = np.random.default_rng(0).uniform(-2, 2, (20, 6)).astype(np.float32)
    want = np.concatenate([model.predict(obs[i:i + 1], deterministic=True)[0]
                           for i in range(len(obs))])
    assert np.array_equal(pol.act(obs), want)
    # a pickled policy_kwargs naming anything but torch.nn activations and torch.optim classes
    # is refused without being unpickled
    naming_os_system = base64.b64encode(b"cos\nsystem\n.").decode()   # GLOBAL os.system
    _rewrite_data(bare / "model.zip",
                  lambda d: d["policy_kwargs"].__setitem__(":serialized:", naming_os_system))
    with pytest.raises(PolicyError, match="policy_kwargs name \\['os.system'\\]"):
        load_policy(bare / "model.zip")


@pytest.mark.parametrize("damage, message", [
    ("pickled_dict", "is not readable JSON"),
    ("wrong_shape", r"obs_rms.mean has shape \(4,\), expected \(6,\)"),
    ("nan", "obs_rms.var holds NaN or inf"),
    ("missing", "has no normalization.json"),
    ("metadata", "metadata.json' is missing or not JSON"),
])
def test_damaged_or_mismatched_folder_is_one_clear_error(tmp_path, damage, message):
    folder = _copy_shipped(tmp_path)
    stats_path = folder / "normalization.json"
    stats = json.loads(stats_path.read_text())
    if damage == "pickled_dict":
        stats_path.write_bytes(pickle.dumps({"obs_rms": 1}))
    elif damage == "wrong_shape":
        stats["obs_rms"]["mean"] = stats["obs_rms"]["mean"][:4]
        stats["obs_rms"]["var"] = stats["obs_rms"]["var"][:4]
        stats_path.write_text(json.dumps(stats))
    elif damage == "nan":
        stats["obs_rms"]["var"][0] = float("nan")
        stats_path.write_text(json.dumps(stats))
    elif damage == "missing":
        stats_path.unlink()
    _rehash(folder)
    if damage == "metadata":
        (folder / "metadata.json").write_text("{ truncated")
    with pytest.raises(PolicyError, match=message):
        load_policy(folder)


def test_changed_file_is_caught_by_the_recorded_hash(tmp_path):
    folder = _copy_shipped(tmp_path)
    stats = json.loads((folder / "normalization.json").read_text())
    stats["obs_rms"]["mean"][0] += 1.0
    (folder / "normalization.json").write_text(json.dumps(stats))
    with pytest.raises(PolicyError, match="normalization.json' is not the file metadata.json"):
        load_policy(folder)


def test_convert_stats_turns_a_trusted_pickle_into_json(tmp_path):
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.rl.artefacts.normalization import read
    from microconveyor_env.envs import MicroConveyorEnv

    vn = VecNormalize(DummyVecEnv([MicroConveyorEnv]), gamma=0.95)
    vn.reset()
    vn.obs_rms.mean[:] = 0.25
    vn.save(str(tmp_path / "vecnormalize.pkl"))
    r = _cli("convert-stats", str(tmp_path / "vecnormalize.pkl"), "--json")
    assert r.returncode == 0, r.stderr
    stats = read(tmp_path / "normalization.json", (6,))
    assert stats["gamma"] == 0.95 and stats["obs_rms"]["mean"] == [0.25] * 6
    r = _cli("convert-stats", str(tmp_path / "nope.pkl"), "--json")
    assert r.returncode == 2


def test_policy_with_observation_history_loads_and_evaluates(tmp_path):
    """A policy trained with observe_history (issue 21) is loaded in the scene of its metadata
    (its observation has the history's shape), evaluates from the CLI, and a folder whose
    metadata no longer matches the model's observation shape is refused."""
    import numpy as np

    from agents.experiments.perturb import Level, perturbation_table, policy_rollout
    from agents.rl.evaluation.evaluate import evaluate
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train
    from microconveyor_env.envs import env_config

    folder = tmp_path / "hist"
    kw = {"observe_history": 2, "action_noise": 0.003, "num_threads": 1}
    train(folder, TrainSettings(steps=512, seed=0, env_id="MicroConveyor-v1", env_kwargs=kw,
                                overrides={"n_envs": 16, "n_steps": 32, "batch_size": 256,
                                "n_epochs": 1,
                     "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}}}, checkpoint_freq=512, eval_freq=0, eval_targets=0, progress_bar=False, tensorboard=False))
    pol = load_policy(folder)
    assert pol.config.observe_history == 2 and pol.config.action_noise == 0.0  # nominal
    assert pol.actor.obs_dim == 26
    res = evaluate(pol, n_targets=3, seed=0)
    assert res["n_targets"] == 3
    rows = perturbation_table(policy_rollout(pol), pol.config, np.array([2e-3, 5e-3]),
                              [Level(0.003, 0.05)], tolerance=50e-6, repeats=1)
    assert len(rows) == 1
    r = _cli("evaluate", "--policy", str(folder), "--targets", "2", "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    out = json.loads(r.stdout)
    assert out["n_targets"] == 2 and out["env_kwargs"]["observe_history"] == 2
    with pytest.raises(PolicyError, match="observe_history: trained 2, asked 0"):
        load_policy(folder, env_config("MicroConveyor-v1"))
    r = _cli("evaluate", "--policy", str(folder), "--targets", "2", "--json",
             "--env-kwargs", "observe_history:1")
    assert r.returncode == 2 and "observe_history: trained 2, asked 1" in json.loads(
        r.stdout)["error"], r.stdout
    # metadata edited to another history length: the zip's observation shape disagrees
    meta = json.loads((folder / "metadata.json").read_text())
    meta["env_kwargs"]["observe_history"] = 1
    meta["hyperparams"]["env_kwargs"]["observe_history"] = 1
    (folder / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyError, match=r"observation"):
        load_policy(folder)


@pytest.mark.parametrize("env_id", ["MicroConveyor-v0", "MicroConveyor-v1"])
def test_a_rows_action_does_not_depend_on_its_batch(env_id):
    """Policy.act computes each row alone: on CPUs whose float32 kernels round by batch size
    (AVX-512 here: up to ~2e-7 in action units between a batch of 64 and single rows) a
    target's result would otherwise depend on how many were evaluated with it, and MPC's plan
    from the policy (one state at a time) would differ from the policy's own episode."""
    import numpy as np

    pol = load_policy(shipped_path("ppo", env_id))
    rng = np.random.default_rng(0)
    spread = 3 * np.sqrt(pol.normalizer.var)
    lo, hi = pol.normalizer.mean - spread, pol.normalizer.mean + spread
    obs = rng.uniform(lo, hi, (64, len(lo))).astype(np.float32)
    batch = pol.act(obs)
    for n in (1, 2, 7, 64):
        np.testing.assert_array_equal(pol.act(obs[:n]), batch[:n])
    assert pol.act(obs[:0]).shape == (0, 3)
    with pytest.raises(ValueError, match="batch of observations"):
        pol.act(obs[0])


def test_a_model_that_trained_past_its_budget_is_data():
    """SB3 stores 1 - steps done / steps asked as the progress left: below -1 when a run's last
    rollout overshoots a small budget (256 steps asked, 4,096 done: -15). Such a model is one
    ``train`` writes, so it loads; a value SB3 never writes (above 1, or not a number) does not."""
    from pathlib import Path

    from agents.rl.artefacts.model_zip import ModelFileError, check_data

    check_data(Path("model.zip"), {"_current_progress_remaining": 1.0 - 4096 / 256})
    for bad in (1.5, "x", float("nan")):
        with pytest.raises(ModelFileError, match="_current_progress_remaining"):
            check_data(Path("model.zip"), {"_current_progress_remaining": bad})


def test_rl_zoo3_layout_loads_after_convert_stats(tmp_path):
    """rl-zoo3 saves ``RUN/ENV.zip`` and ``RUN/ENV/vecnormalize.pkl``; ``convert-stats`` on that
    pickle writes ``RUN/ENV/normalization.json``, which is where loading the zip then finds it
    (the pickle beside it is never opened)."""
    import shutil

    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from microconveyor_env.envs import MicroConveyorEnv

    run = tmp_path / "ppo" / "MicroConveyor-v0_1"
    (run / "MicroConveyor-v0").mkdir(parents=True)
    shutil.copy(shipped_path("ppo", "MicroConveyor-v0") / "model.zip", run / "MicroConveyor-v0.zip")
    vn = VecNormalize(DummyVecEnv([MicroConveyorEnv]), gamma=0.95)
    vn.reset()
    vn.obs_rms.mean[:] = 0.25
    pkl = run / "MicroConveyor-v0" / "vecnormalize.pkl"
    vn.save(str(pkl))
    with pytest.raises(PolicyError, match="is a pickle.*convert-stats"):
        load_policy(run / "MicroConveyor-v0.zip", env_id="MicroConveyor-v0")
    r = _cli("convert-stats", str(pkl), "--json")
    assert r.returncode == 0, r.stderr
    pol = load_policy(run / "MicroConveyor-v0.zip", env_id="MicroConveyor-v0")
    assert pol.normalizer is not None
    r = _cli("evaluate", "--policy", str(run / "MicroConveyor-v0.zip"), "--env",
             "MicroConveyor-v0", "--targets", "2", "--json")
    assert r.returncode == 0, r.stderr
